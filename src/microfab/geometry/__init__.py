"""Geometry: exact segments, arc-length parameterised paths, layers and their sources."""
