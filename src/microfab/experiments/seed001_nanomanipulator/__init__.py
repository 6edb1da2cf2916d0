"""Seed 001: flexure XY nanomanipulator for MSL (RBF adaptive control, plug-in RC, gated laser)."""
