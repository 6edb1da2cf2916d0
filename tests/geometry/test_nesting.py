"""nesting.containers: the same answers as testing every point against every polygon."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from microfab.geometry import nesting
from microfab.geometry.layer import Layer
from microfab.geometry.nesting import containers
from microfab.geometry.shapes import circle, square


def _pairwise(polygons: list[np.ndarray], probes: np.ndarray, own: np.ndarray) -> list[list[int]]:
    """The quadratic reference: every probe against every polygon (what Layer.depth did)."""
    polys = [MplPath(p) for p in polygons]
    return [
        [j for j, poly in enumerate(polys) if j != own[i] and poly.contains_point(tuple(p))]
        for i, p in enumerate(probes)
    ]


def _as_lists(ptr: np.ndarray, idx: np.ndarray) -> list[list[int]]:
    return [idx[ptr[i] : ptr[i + 1]].tolist() for i in range(ptr.size - 1)]


def _regular(n: int, cx: float, cy: float, r: float, phase: float = 0.0) -> np.ndarray:
    t = phase + 2 * np.pi * np.arange(n + 1) / n
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


@pytest.mark.parametrize("seed", range(4))
def test_random_polygons_match_the_pairwise_test(seed: int) -> None:
    rng = np.random.default_rng(seed)
    polygons = []
    for _ in range(300):
        cx, cy = rng.uniform(-1, 1, 2)
        r = 10 ** rng.uniform(-2.5, 0.3)  # some cover most of the field: wide boxes
        if rng.random() < 0.3:  # concentric and shared centres: nesting, touching edges
            cx, cy = round(cx, 1), round(cy, 1)
        polygons.append(_regular(int(rng.integers(3, 40)), cx, cy, r, rng.uniform(0, 1)))
    # a probe of each polygon on its own boundary (as Layer.depth asks), plus loose points
    probes = np.vstack([0.5 * (p[0] + p[1]) for p in polygons] + [rng.uniform(-2, 2, (100, 2))])
    own = np.r_[np.arange(len(polygons)), np.full(100, -1)]
    got = _as_lists(*containers(polygons, probes, own=own))
    assert got == _pairwise(polygons, probes, own)
    assert sum(map(len, got)) > 100  # the case nests a lot


def test_clustered_polygons_in_small_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    """A dense cluster and a far outlier: quantile cells, pairs made a few at a time."""
    monkeypatch.setattr(nesting, "_CHUNK", 7)
    rng = np.random.default_rng(9)
    polygons = [_regular(5, *rng.uniform(0, 0.01, 2), 2e-3) for _ in range(400)]
    polygons += [_regular(4, 100.0, 100.0, 1.0), _regular(4, 0.005, 0.005, 50.0)]
    probes = np.vstack([0.5 * (p[0] + p[1]) for p in polygons] + [rng.uniform(0, 0.01, (50, 2))])
    own = np.r_[np.arange(len(polygons)), np.full(50, -1)]
    got = _as_lists(*containers(polygons, probes, own=own))
    assert got == _pairwise(polygons, probes, own)


def test_probes_on_edges_and_vertices_match_the_pairwise_test() -> None:
    # a grid of unit squares sharing edges, probed at their corners and edge midpoints
    polygons = [
        np.array([[x, y], [x + 1, y], [x + 1, y + 1], [x, y + 1]], dtype=float)
        for x in range(6)
        for y in range(6)
    ]
    g = np.arange(0, 6.5, 0.5)
    probes = np.array([[x, y] for x in g for y in g])
    own = np.full(len(probes), -1)
    assert _as_lists(*containers(polygons, probes, own=own)) == _pairwise(polygons, probes, own)


def test_degenerate_inputs() -> None:
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    nan_poly = np.array([[0.0, 0.0], [np.nan, 0.0], [1.0, 1.0]])
    empty = np.zeros((0, 2))
    probes = np.array([[0.5, 0.5], [np.nan, 0.5], [5.0, 5.0]])
    polygons = [sq, nan_poly, empty, sq + 4.5]
    ptr, idx = containers(polygons, probes)
    expected = _pairwise([sq, nan_poly, sq + 4.5], probes, np.full(3, -1))
    # the empty polygon (index 2) contains nothing; the others are renumbered for it
    assert _as_lists(ptr, idx) == [[j if j < 2 else j + 1 for j in e] for e in expected]
    assert _as_lists(*containers([], probes)) == [[], [], []]
    ptr, idx = containers(polygons, np.zeros((0, 2)))
    assert ptr.tolist() == [0] and idx.size == 0
    with pytest.raises(ValueError, match="own"):
        containers(polygons, probes, own=np.zeros(2))


def test_one_plate_around_many_holes() -> None:
    """A box over every grid cell (a plate) is tested directly against every probe."""
    holes = [_regular(12, x, y, 0.3) for x in range(30) for y in range(30)]
    plate = np.array([[-1.0, -1.0], [30.0, -1.0], [30.0, 30.0], [-1.0, 30.0]])
    polygons = [plate, *holes]
    probes = np.array([0.5 * (p[0] + p[1]) for p in polygons])
    ptr, idx = containers(polygons, probes, own=np.arange(len(polygons)))
    assert _as_lists(ptr, idx) == [[]] + [[0]] * len(holes)


def test_layer_containers_and_depth() -> None:
    outer = square(0.04)
    hole = circle(0.01)
    island = square(0.004)
    side = circle(0.002, center=(0.05, 0.0))
    layer = Layer((hole, outer, island, side))
    assert layer.containers == ((1,), (), (0, 1), ())
    assert layer.depth == (1, 0, 2, 0)
