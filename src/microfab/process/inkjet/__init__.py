"""Piezo drop-on-demand inkjet: waveform, printhead acoustics, fluid, jet breakup, images.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al.): droplet
formation of sodium alginate solutions from a MicroFab 120 µm dispenser.
"""
