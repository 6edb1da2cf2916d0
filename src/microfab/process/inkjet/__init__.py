"""Piezo drop-on-demand inkjet physics: fluid, dimensionless groups, jet breakup, droplet.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al.): droplet
formation of sodium alginate solutions from a MicroFab 120 µm dispenser. The drive
waveform is in :mod:`microfab.trajectory.waveform`, the printhead acoustics in
:mod:`microfab.plants.printhead`, the camera and image analysis in
:mod:`microfab.measure`, the printhead as a machine (a drive and a fluid in, the droplet
out; the sweep, the calibration and the sensitivity study) in
:mod:`microfab.machines.printhead`, and the seed's numbers and Fig. 4 comparison in
:mod:`microfab.experiments.seed003_inkjet`.
"""
