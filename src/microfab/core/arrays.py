"""Small array helpers shared across the package."""

from __future__ import annotations

import numpy as np
from numpy.typing import DTypeLike

__all__ = ["readonly"]


def readonly(a: object, dtype: DTypeLike = float) -> np.ndarray:
    """A read-only copy of ``a`` (as ``dtype``; ``None`` keeps the input's type)."""
    arr = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr
