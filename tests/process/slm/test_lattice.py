"""Tests of the cubic strut lattice of seed 003 part 2 §4 (250 µm struts, 5 %)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from microfab.process.slm.lattice import (
    LatticeSpec,
    cubic_cell,
    cubic_volume_fraction,
    lattice_layer,
    lattice_section,
)

STRUT, PHI = 250e-6, 0.05  # seed 003 part 2 §4


def test_the_cell_of_the_seeds_lattice_is_about_1_64_mm():
    a = cubic_cell(PHI, STRUT)
    assert cubic_volume_fraction(a, STRUT) == pytest.approx(PHI, rel=1e-12)
    assert a == pytest.approx(1.64e-3, abs=5e-6)  # seed: "cell ≈ 1.64 mm" (1.6356 mm)
    # without the node overlap (3 struts of length a): a = sqrt(3 π r² / φ) = 1.716 mm
    assert math.sqrt(3 * math.pi * (STRUT / 2) ** 2 / PHI) == pytest.approx(1.716e-3, abs=1e-6)


def test_the_volume_fraction_formula_against_sampled_points():
    a, r = cubic_cell(), STRUT / 2
    rng = np.random.default_rng(5)
    n = 400_000
    x, y, z = (rng.uniform(-a / 2, a / 2, n) for _ in range(3))  # a cell around a node
    inside = (y * y + z * z < r * r) | (x * x + z * z < r * r) | (x * x + y * y < r * r)
    sigma = math.sqrt(PHI * (1 - PHI) / n)  # 3.4e-4
    assert inside.mean() == pytest.approx(PHI, abs=4 * sigma)


def test_a_section_between_node_planes_is_the_vertical_struts():
    spec = LatticeSpec(outline_radius_m=5e-3)
    a, r = spec.cell_m, STRUT / 2
    geom = lattice_section(0.5 * a, spec)
    parts = shapely.get_parts(geom)
    ij = np.arange(-4, 5) * a
    nodes = np.array([(x, y) for x in ij for y in ij if math.hypot(x, y) < 5e-3 - r])
    whole = [p for p in parts if math.isclose(p.area, 16 * r * r * math.sin(2 * math.pi / 32))]
    assert len(whole) == len(nodes)  # every strut fully inside the disc is a whole 32-gon
    assert max(math.hypot(p.centroid.x, p.centroid.y) for p in parts) < 5e-3


def test_a_node_plane_section_is_one_grid():
    spec = LatticeSpec(outline_radius_m=5e-3)
    geom = lattice_section(0.0, spec)
    assert shapely.get_num_geometries(geom) == 1  # the strips join every node
    assert geom.area > lattice_section(0.5 * spec.cell_m, spec).area * 3


@pytest.mark.parametrize("z_cells", [0.5, 0.03])
def test_layer_vectors_mark_the_material_and_nothing_else(z_cells):
    spec = LatticeSpec(outline_radius_m=4e-3)
    z = z_cells * spec.cell_m
    geom = lattice_section(z, spec)
    path = lattice_layer(z, spec, start=(-6e-3, 0.0))
    np.testing.assert_array_equal(path.points[0], [-6e-3, 0.0])
    seg = np.stack([path.points[:-1], path.points[1:]], axis=1)
    mid = shapely.points(seg[path.is_mark].mean(axis=1))
    assert np.all(shapely.dwithin(geom, mid, 1e-9))  # every mark lies on material
    mk = path.is_mark
    alone = mk & ~np.concatenate([[False], mk[:-1]]) & ~np.concatenate([mk[1:], [False]])
    hatch_marks = seg[alone]  # hatch marks stand alone; contours are polylines
    np.testing.assert_allclose(hatch_marks[:, 0, 1], hatch_marks[:, 1, 1], atol=1e-15)
    # hatch lines on the 100 µm grid offset by 50 µm, ending on the section's boundary (the
    # bands they were hatched in cut nothing short)
    k = (hatch_marks[:, 0, 1] - 50e-6) / 100e-6
    np.testing.assert_allclose(k, np.round(k), atol=1e-6)
    ends = shapely.points(hatch_marks.reshape(-1, 2))
    assert np.all(shapely.dwithin(geom.boundary, ends, 1e-9))
    # hatch length equals the section's chords: lines through the material at those heights
    ys = np.unique(np.round(hatch_marks[:, 0, 1], 12))
    lines = shapely.linestrings([[[-5e-3, y], [5e-3, y]] for y in ys])
    chords = shapely.length(shapely.intersection(lines, geom)).sum()
    total = np.abs(hatch_marks[:, 1, 0] - hatch_marks[:, 0, 0]).sum()
    assert total == pytest.approx(chords, rel=1e-9)


def test_contours_close_on_themselves():
    spec = LatticeSpec(outline_radius_m=3e-3)
    path = lattice_layer(0.5 * spec.cell_m, spec)
    n_rings = len(shapely.get_parts(lattice_section(0.5 * spec.cell_m, spec)))
    mk = path.is_mark
    starts = np.flatnonzero(mk & ~np.concatenate([[False], mk[:-1]]))
    ends = np.flatnonzero(mk & ~np.concatenate([mk[1:], [False]]))
    runs = ends - starts + 1
    rings = runs > 1  # contours are polylines; hatch marks are single vectors
    assert rings.sum() == n_rings
    np.testing.assert_allclose(path.points[starts[rings]], path.points[ends[rings] + 1], atol=0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"volume_fraction": 0.97}, "volume_fraction must lie in"),
        ({"circle_sides": 30}, "multiple of 4"),
        ({"hatch_spacing_m": 0.0}, "hatch_spacing_m must be positive"),
    ],
)
def test_bad_specs_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LatticeSpec(**kwargs)


def test_the_cell_scales_with_the_strut_and_a_huge_strut_is_refused():
    # fuzz: a 1e308 m strut raised OverflowError (r**3) instead of a ValueError
    a = cubic_cell(PHI, STRUT)
    assert cubic_cell(PHI, 1e-300) / 1e-300 == pytest.approx(a / STRUT, rel=1e-12)
    assert cubic_volume_fraction(1e300, 1e299) == pytest.approx(
        cubic_volume_fraction(10 * STRUT, STRUT), rel=1e-12
    )
    with pytest.raises(ValueError, match="strut_m = 1e\\+308 m is too large"):
        cubic_cell(PHI, 1e308)
