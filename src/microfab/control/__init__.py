"""microfab.control."""
