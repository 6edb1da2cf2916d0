"""Seed 002 part 1: the black-box XY stage, its linear model and per-axis ANNs."""
