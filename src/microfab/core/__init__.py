"""Foundations shared by every layer: argument checks, arrays, declared limits, signals."""
