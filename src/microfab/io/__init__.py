"""microfab.io."""
