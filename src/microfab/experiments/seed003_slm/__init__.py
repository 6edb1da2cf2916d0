"""Seed 003 part 2: SLM galvo scanner (Buls et al.).

Chirp identification of a HurryScan25 axis, the model-inverse input shaper, classic
shapers and the scan time of a lattice part with and without the shaper.
"""
