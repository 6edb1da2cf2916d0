"""Figures of an optimised reference: the signed deviation they plot."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.geometry.path import Path
from microfab.report.reference import signed_deviation


def test_signed_deviation_on_a_line_is_the_offset_with_its_side():
    line = Path.polyline([(0.0, 0.0), (1e-2, 0.0)])
    pts = np.array([[2e-3, 5e-6], [6e-3, -3e-6]])
    s, d = signed_deviation(line, pts)
    assert s == pytest.approx([2e-3, 6e-3], abs=1e-12)
    assert abs(d) == pytest.approx([5e-6, 3e-6], abs=1e-12)
    assert d[0] * d[1] < 0  # opposite sides of the contour
