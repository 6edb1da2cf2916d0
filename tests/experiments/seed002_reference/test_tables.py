"""Table III's agreement count (`tables.table_iii_agreement`, issue 46)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from microfab.experiments.seed002_reference import tables
from microfab.experiments.seed002_reference.paper import TABLE_III


def _study(offset: dict[tuple[str, float], float], failed=()) -> SimpleNamespace:
    """A study whose improvements are the seed's plus ``offset`` points per cell."""
    points = {}
    for case, rows in TABLE_III.items():
        for a, row in rows.items():
            if (case, a) in failed:
                points[(case, a)] = {"error": "stage 2 failed"}
                continue
            d = offset.get((case, a), 0.0)
            imp = {k: getattr(row, k) + d for k in ("l1", "l2", "linf")}
            points[(case, a)] = {"improvement": {"twin": imp, "ann": imp}}
    points[("o", 1.0)] = {"improvement": {"twin": {"l1": 0, "l2": 0, "linf": 0}}}  # not in III
    return SimpleNamespace(points=points, settings=SimpleNamespace(a_max=(1.0, 3.0)))


def test_cells_within_the_band_and_the_mean_difference():
    agree = tables.table_iii_agreement(_study({("u", 1.0): 15.0, ("r", 3.0): -15.5}))
    assert agree["cells"] == 30  # 5 shapes x 2 a_max x 3 norms
    assert agree["within"] == 27  # r at 3 m/s²: 15.5 points out; u at 1: 15 is in
    assert agree["mean_abs_diff_points"] == pytest.approx((3 * 15.0 + 3 * 15.5) / 30)


def test_failed_points_are_not_counted_and_none_gives_nan():
    agree = tables.table_iii_agreement(_study({}, failed={("h", 1.0), ("h", 3.0)}))
    assert (agree["cells"], agree["within"]) == (24, 24)
    assert agree["mean_abs_diff_points"] == 0.0
    none = tables.table_iii_agreement(_study({}, failed=set(
        (c, a) for c, rows in TABLE_III.items() for a in rows)))  # fmt: skip
    assert none["cells"] == 0 and none["mean_abs_diff_points"] is None  # JSON has no NaN
