"""Seed 004: laser micromachining workstation (linear-motor XY stage, preview + DOB,
contour compensation, sliding-mode autofocus)."""
