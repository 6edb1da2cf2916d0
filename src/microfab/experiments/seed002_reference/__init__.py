"""Seed 002 part 2: two-stage reference optimisation on the black-box XY stage (§IV-V)."""
