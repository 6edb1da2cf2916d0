"""Package data (calibrations, default jobs)."""
