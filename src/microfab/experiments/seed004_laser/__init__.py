"""Seed 004: laser micromachining workstation.

Linear-motor XY stage, preview control with disturbance observer, contour compensation,
sliding-mode autofocus.
"""
