"""microfab.report."""
