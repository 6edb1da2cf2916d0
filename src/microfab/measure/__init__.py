"""Measurements: metrics on measured data, cameras and image analysis."""
