from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from microfab.geometry.hatch import hatch
from microfab.geometry.load import load_drawing
from microfab.process.slm.lattice import LatticeSpec, cubic_cell, lattice_layer
from microfab.process.slm.source import (
    CHORD_TOL_M,
    LATTICE_KEYS,
    parse_lattice_source,
    scan_program,
)


def test_parse_lattice_source_maps_every_key():
    z, spec = parse_lattice_source(
        "lattice:z=4e-4, radius=3e-3,strut=2e-4,fraction=0.04,hatch=8e-5,sides=16"
    )
    assert z == 4e-4
    assert spec == LatticeSpec(
        outline_radius_m=3e-3,
        strut_m=2e-4,
        volume_fraction=0.04,
        hatch_spacing_m=8e-5,
        hatch_offset_m=4e-5,  # half the spacing, as the default's 50 µm of 100 µm
        circle_sides=16,
    )
    assert set(LATTICE_KEYS) == {"z", "radius", "strut", "fraction", "hatch", "sides"}
    assert parse_lattice_source("lattice:") == (0.0, LatticeSpec())
    # seed 003 part 2 §4: strut 250 µm and 5 % give the 1.64 mm cell
    assert parse_lattice_source("LATTICE:radius=1e-3")[1].cell_m == pytest.approx(1.637e-3, 1e-3)


@pytest.mark.parametrize(
    "text, says",
    [
        ("lattice:size=1", "unknown lattice key 'size'; known: z, radius, strut, fraction"),
        ("lattice:z", "must look like key=value"),
        ("lattice:z=a", "lattice z='a' is not a number"),
        ("lattice:z=1,z=2", "given twice"),
        ("lattice:sides=16.5", "whole number"),
        ("lattice:sides=18", "multiple of 4"),
        ("lattice:fraction=0.99", "volume_fraction"),
        ("lattice:radius=-1", "outline_radius_m"),
        ("lattice:z=nan", "lattice z"),
        ("circle:radius=1", "starts with 'lattice:'"),
    ],
)
def test_parse_lattice_source_refusals(text: str, says: str):
    with pytest.raises(ValueError, match=None) as e:
        parse_lattice_source(text)
    assert says in str(e.value)


def test_lattice_program_is_the_lattice_layer():
    src = "lattice:z=4e-4,radius=3e-3"
    got = scan_program(src)
    want = lattice_layer(4e-4, LatticeSpec(outline_radius_m=3e-3))
    np.testing.assert_array_equal(got.points, want.points)
    np.testing.assert_array_equal(got.is_mark, want.is_mark)
    assert got.n_marks > 0 and got.n_jumps > 0
    # z_m sets the height of a source without z; a different z twice is refused
    other = scan_program("lattice:radius=3e-3", z_m=cubic_cell())  # a node plane: struts
    assert other.n_marks != got.n_marks
    assert scan_program(src, z_m=4e-4).summary() == got.summary()
    with pytest.raises(ValueError, match="height is given twice"):
        scan_program(src, z_m=1e-3)


def test_lattice_hatch_spacing_and_angle_reach_the_spec():
    coarse = scan_program("lattice:z=4e-4,radius=3e-3", hatch_spacing_m=200e-6)
    want = lattice_layer(
        4e-4, LatticeSpec(outline_radius_m=3e-3, hatch_spacing_m=200e-6, hatch_offset_m=100e-6)
    )
    np.testing.assert_array_equal(coarse.points, want.points)
    # the source's hatch key wins over the keyword
    keyed = scan_program("lattice:z=4e-4,radius=3e-3,hatch=2e-4", hatch_spacing_m=50e-6)
    np.testing.assert_array_equal(keyed.points, want.points)
    turned = scan_program("lattice:z=4e-4,radius=3e-3", hatch_angle_deg=90.0)
    marks = np.diff(turned.points, axis=0)[turned.is_mark]
    # the longest marks are hatch lines; at 90 degrees they run along y
    longest = marks[np.argmax(np.hypot(*marks.T))]
    assert abs(longest[0]) < 1e-12 < abs(longest[1])


def test_drawing_program_contours_then_hatch():
    r, h = 2e-3, 100e-6
    p = scan_program("circle:radius=2e-3", hatch_spacing_m=h, start=(-5e-3, 0.0))
    assert tuple(p.points[0]) == (-5e-3, 0.0) and not p.is_mark[0]
    # the contour: one closed polyline of marks on the circle, within the chord tolerance
    n_ring = int(np.argmin(p.is_mark[1:]))  # marks until the first jump after them
    ring = p.points[1 : n_ring + 2]
    assert np.allclose(ring[0], ring[-1])
    rad = np.hypot(*ring.T)
    assert np.all(np.abs(rad - r) < 1e-12)  # vertices on the circle
    chord = np.hypot(*np.diff(ring, axis=0).T)
    sagitta = r - np.sqrt(r * r - (chord / 2) ** 2)
    assert sagitta.max() <= CHORD_TOL_M * (1 + 1e-9)
    # then the hatch, as geometry.hatch gives it from the ring's end
    sv = hatch(load_drawing("circle:radius=2e-3"), spacing=h, start=ring[-1])
    vec, is_mark = sv.vectors()
    np.testing.assert_allclose(p.points[n_ring + 2 :], vec[:, 1], atol=0)
    np.testing.assert_array_equal(p.is_mark[n_ring + 1 :], is_mark)
    assert p.n_marks == n_ring + len(sv)
    lengths = p.lengths[p.is_mark][n_ring:]
    assert lengths.sum() == pytest.approx(sv.total_mark_length)
    # about the disc's area over the spacing
    assert lengths.sum() == pytest.approx(math.pi * r * r / h, rel=0.02)


def test_drawing_program_without_contours_and_angle(tmp_path: Path):
    p = scan_program("rectangle:width=2e-3,height=1e-3", contours=False, hatch_angle_deg=90.0)
    marks = np.diff(p.points, axis=0)[p.is_mark]
    assert np.allclose(marks[:, 0], 0.0) and np.all(np.abs(marks[:, 1]) > 0)
    assert len(p) == 2 * int(p.n_marks) and p.n_marks == pytest.approx(2e-3 / 100e-6, abs=1)
    # a part between two hatch lines without contours: no vectors at all
    svg = tmp_path / "sliver.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" height="10mm" '
        'viewBox="0 0 10 10"><rect x="1" y="1.02" width="3" height="0.03"/></svg>'
    )
    empty = scan_program(str(svg), contours=False, start=(1e-3, 2e-3))
    assert len(empty) == 0 and tuple(empty.points[0]) == (1e-3, 2e-3)
    ring = scan_program(str(svg))  # with its contour: a jump, then its four sides
    assert ring.is_mark.tolist() == [False, True, True, True, True]


def test_drawing_file_with_an_open_contour_is_refused_naming_it(tmp_path: Path):
    svg = tmp_path / "part.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="10mm" height="10mm" '
        'viewBox="0 0 10 10">'
        '<rect x="1" y="1" width="3" height="3"/>'
        '<path d="M 5 5 L 9 5 L 9 9"/></svg>'
    )
    with pytest.raises(ValueError, match=r"1 of its 2 contours are open: #1 \(ends") as e:
        scan_program(str(svg))
    assert "part.svg" in str(e.value)
    with pytest.raises(ValueError, match="contours are open: #0"):
        scan_program("spiral")
    with pytest.raises(FileNotFoundError):
        scan_program(str(tmp_path / "missing.dxf"))


@pytest.mark.parametrize(
    "kw, says",
    [
        ({"hatch_spacing_m": 0.0}, "hatch spacing"),
        ({"hatch_angle_deg": math.inf}, "hatch angle"),
        ({"start": (0.0, math.nan)}, "start"),
    ],
)
def test_scan_program_refuses_bad_numbers(kw: dict, says: str):
    with pytest.raises(ValueError, match=says):
        scan_program("circle:radius=1e-3", **kw)
