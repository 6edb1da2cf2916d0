"""microfab.experiments."""
