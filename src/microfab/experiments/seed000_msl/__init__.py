"""Seed 000: galvo-scanner MSL, lead-lag feedback and frequency-domain ILC."""
