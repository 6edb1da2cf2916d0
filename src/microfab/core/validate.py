"""Small argument checks shared by the parameter dataclasses."""

from __future__ import annotations

import math

__all__ = ["check_positive"]


def check_positive(name: str, value: float, unit: str) -> None:
    """Raise ``ValueError`` naming ``name``, ``value`` and ``unit`` unless finite and > 0.

    Examples
    --------
    >>> check_positive("dwell_s", 30e-6, "s")
    """
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be positive and finite, got {value} {unit}")
