"""Machines: the `Machine` protocol, digital twins and file-based hardware access."""
