"""microfab.sim."""
