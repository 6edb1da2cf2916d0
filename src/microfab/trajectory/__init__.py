"""microfab.trajectory."""
