"""microfab.process."""
