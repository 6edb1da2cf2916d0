"""Large valid drawings: thousands of contours read, nested, summarised and drawn right.

Correctness only (no timings): counts, the nesting of known layouts, long texts equal to
their glyphs converted one by one, shifted copies of paths equal to translated ones, and
a picture made of a few collections however many contours. ``benchmarks/bench_drawings.py``
times ``path show`` on such drawings.
"""

from __future__ import annotations

from pathlib import Path as FsPath

import ezdxf
import numpy as np
import pytest
from matplotlib.font_manager import FontProperties
from matplotlib.textpath import TextPath

from microfab.geometry import text as text_module
from microfab.geometry.layer import Layer
from microfab.geometry.load import load_drawing
from microfab.geometry.path import Path
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment
from microfab.geometry.shapes import circle
from microfab.geometry.text import text_layer
from microfab.report.geometry import fig_layer


def _rings_dxf(path: FsPath, n_side: int) -> None:
    """``n_side`` x ``n_side`` targets (circles of r 1, 0.6, 0.3 mm) on a 3 mm pitch,
    inside one plate (an LWPOLYLINE), entities shuffled."""
    rng = np.random.default_rng(0)
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4  # mm
    msp = doc.modelspace()
    jobs = [
        (3.0 * i, 3.0 * j, r) for i in range(n_side) for j in range(n_side) for r in (1, 0.6, 0.3)
    ]
    for k in rng.permutation(len(jobs)):
        x, y, r = jobs[k]
        msp.add_circle((x, y), r)
    e = 3.0 * n_side
    msp.add_lwpolyline([(-2, -2), (e, -2), (e, e), (-2, e)], close=True)
    doc.saveas(path)


def test_thousands_of_nested_dxf_circles(tmp_path: FsPath) -> None:
    f = tmp_path / "rings.dxf"
    _rings_dxf(f, 25)  # 1875 circles and the plate
    layer = load_drawing(str(f))
    assert len(layer) == 3 * 25 * 25 + 1 and all(c.closed for c in layer)
    radius = {round((c.bbox[2] - c.bbox[0]) * 1e3 / 2, 6): c for c in layer if len(c) == 1}
    assert sorted(radius) == [0.3, 0.6, 1.0]
    # the plate holds everything; each ring is one deeper than the one around it
    want = {0.3: 3, 0.6: 2, 1.0: 1}
    for c, d in zip(layer, layer.depth, strict=True):
        r = round((c.bbox[2] - c.bbox[0]) * 1e3 / 2, 6)
        assert d == (want[r] if isinstance(c.segments[0], ArcSegment) and len(c) == 1 else 0)
    assert sorted(layer.depth).count(0) == 1
    ori = layer.oriented()
    assert [c.orientation for c in ori] == ["ccw" if d % 2 == 0 else "cw" for d in layer.depth]


def test_thousands_of_scattered_circles_nest_as_pairwise_testing_says() -> None:
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 0.1, (3000, 2))
    r = rng.uniform(1e-4, 1e-3, 3000)
    layer = Layer(tuple(circle(float(ri), center=tuple(p)) for p, ri in zip(xy, r, strict=True)))
    depth = np.array(layer.depth)
    assert (depth >= 0).all() and depth.max() >= 2  # random overlaps nest a few deep
    # a sample checked against every other circle, as the pairwise loop did
    for i in rng.choice(3000, 40, replace=False):
        probe = layer[i].first_midpoint
        inside = [
            j for j in range(3000) if j != i and np.hypot(*(probe - xy[j])) < r[j] * (1 - 1e-6)
        ]
        assert list(layer.containers[i]) == inside


def test_thousands_of_svg_paths(tmp_path: FsPath) -> None:
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 98, (3000, 2))
    body = "".join(f'<path d="M {x:.3f} {y:.3f} l 1 0 l 0 1 z"/>' for x, y in xy)
    body += '<path d="M -1 -1 h 101 v 101 h -101 z"/>'  # a frame around all of them
    f = tmp_path / "many.svg"
    f.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
        f'viewBox="0 0 100 100">{body}</svg>'
    )
    layer = load_drawing(str(f))
    assert len(layer) == 3001 and all(len(c) == 3 for c in layer.contours[:3000])
    assert layer.depth[-1] == 0
    # a triangle is inside the frame, plus each triangle around its probe point
    for i in rng.choice(3000, 50, replace=False):
        assert 3000 in layer.containers[i]
        assert layer.depth[i] == len(layer.containers[i]) >= 1
    assert len(layer.summary()["contours"]) == 3001


def test_mixed_dxf_lines_arcs_polylines(tmp_path: FsPath) -> None:
    rng = np.random.default_rng(2)
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    for i in range(1500):
        x, y = 4.0 * (i % 40), 4.0 * (i // 40)  # one per cell: nothing meets
        kind = i % 3
        if kind == 0:
            msp.add_line((x, y), (x + rng.uniform(0.1, 1), y + rng.uniform(0.1, 1)))
        elif kind == 1:
            msp.add_arc((x, y), rng.uniform(0.1, 1), rng.uniform(0, 90), rng.uniform(180, 300))
        else:
            msp.add_lwpolyline(
                [(x, y, 0.2), (x + 1, y, 0), (x + 1, y + 1, 0)], format="xyb", close=True
            )
    f = tmp_path / "mixed.dxf"
    doc.saveas(f)
    layer = load_drawing(str(f))
    assert len(layer) == 1500
    assert sum(c.closed for c in layer) == 500
    assert sorted(set(layer.depth)) == [-1, 0]


def _one_by_one(text: str, height: float) -> Layer:
    """The text converted occurrence by occurrence, as `text_layer` did before templates."""
    tp = TextPath((0.0, 0.0), text, size=1.0, prop=FontProperties(family="DejaVu Sans"))
    ext = tp.get_extents()
    shift = -height * np.array([ext.x0, ext.y0])
    layer = Layer(tuple(text_module._contours(tp, height, shift)))
    depth = layer.depth
    keys = [(*sorted(a, key=depth.__getitem__), i) for i, a in enumerate(layer.containers)]
    order = sorted(range(len(layer)), key=keys.__getitem__)
    return Layer(tuple(layer[i] for i in order)).oriented()


def test_long_text_equals_its_glyphs_converted_one_by_one() -> None:
    text = "Hello oB8 wave %& ÄÖé! " * 3
    h = 0.01
    fast, slow = text_layer(text, height=h), _one_by_one(text, h)
    assert len(fast) == len(slow) > 100
    assert fast.depth == slow.depth
    for a, b in zip(fast, slow, strict=True):
        assert a.orientation == b.orientation and a.closed and b.closed
        assert [type(s) for s in a.segments] == [type(s) for s in b.segments]
        starts_a = np.array([s.start for s in a.segments])
        starts_b = np.array([s.start for s in b.segments])
        np.testing.assert_allclose(starts_a, starts_b, rtol=0, atol=1e-12 * h)
        assert a.length == pytest.approx(b.length, rel=1e-12)
        np.testing.assert_allclose(a.bbox, b.bbox, rtol=0, atol=1e-12 * h)
        assert a.signed_area == pytest.approx(b.signed_area, rel=1e-11)
        assert a.flatten().shape == b.flatten().shape


def test_two_thousand_characters() -> None:
    layer = text_layer("AB" * 1000)
    # "A": an outline and its hole, "B": an outline and two holes
    assert len(layer) == 5000
    assert layer.depth.count(0) == 2000 and layer.depth.count(1) == 3000
    assert [c.orientation for c in layer] == ["ccw" if d == 0 else "cw" for d in layer.depth]
    # each outer boundary is followed by its holes
    assert layer.depth[:5] == (0, 1, 0, 1, 1)
    # the copies of a glyph are translations of the first one
    first, last = layer[0], layer[-5]
    d = last.start - first.start
    assert d[0] > 0.5  # about 6 mm per "AB"
    np.testing.assert_allclose(last.flatten(), first.flatten() + d, rtol=0, atol=1e-12)
    assert last.length == pytest.approx(first.length, rel=1e-12)


def test_shifted_path_is_the_translated_path() -> None:
    cu = CurveSegment.from_bezier([[0.0, 0.0], [0.01, 0.02], [0.02, 0.0]])
    segs = (cu, ArcSegment((0.01, 0.0), 0.01, 0.0, -np.pi), LineSegment((0.0, 0.0), (0.0, 0.0)))
    p = Path(tuple(s for s in segs if s.length > 0), closed=True)
    p.flatten()
    _ = p.bbox, p.signed_area, p.first_midpoint  # computed, so carried over
    d = np.array([0.3, -0.2])
    a, b = p._shifted(d), p.translated(d)
    assert [type(s) for s in a.segments] == [type(s) for s in b.segments]
    for sa, sb in zip(a.segments, b.segments, strict=True):
        np.testing.assert_allclose(sa.start, sb.start, rtol=0, atol=1e-15)
        np.testing.assert_allclose(sa.end, sb.end, rtol=0, atol=1e-15)
    assert a.segments[0].length_table is p.segments[0].length_table  # kept, not recomputed
    assert a.length == pytest.approx(b.length, rel=1e-14)
    np.testing.assert_allclose(a.bbox, b.bbox, rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.flatten(), b.flatten(), rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.first_midpoint, b.first_midpoint, rtol=0, atol=1e-15)
    assert a.signed_area == pytest.approx(b.signed_area, rel=1e-12)
    assert a.point([0.013]) == pytest.approx(b.point([0.013]), abs=1e-15)


def test_picture_of_thousands_of_contours_is_a_few_collections() -> None:
    rng = np.random.default_rng(4)
    dots = [circle(1e-4, center=tuple(p)) for p in rng.uniform(0, 0.05, (2000, 2))]
    layer = Layer((*dots, Path.polyline([[0.0, 0.0], [0.05, 0.05]])))
    fig = fig_layer(layer)
    (ax,) = fig.axes
    assert len(ax.collections) <= 4  # contours, open contours, arrow shafts, arrow heads
    assert len(ax.lines) <= 5  # start dots, one line per colour
    assert not ax.texts and not ax.patches
    n_arrows = sum(len(c.get_offsets()) for c in ax.collections if len(c.get_paths()) > 1)
    assert n_arrows >= len(layer)  # at least one arrow per contour
    x0, x1 = ax.get_xlim()
    assert x0 <= 0.0 and x1 >= 50.0  # mm: everything in view
