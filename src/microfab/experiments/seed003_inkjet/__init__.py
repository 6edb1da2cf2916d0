"""Seed 003 part 1: drop-on-demand inkjetting of sodium alginate, breakup time and mode."""
