"""microfab.plants."""
