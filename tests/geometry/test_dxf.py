import logging
import math

import ezdxf
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import ellipe

from microfab.geometry.dxf import read_dxf
from microfab.geometry.segments import ArcSegment, CurveSegment

MM = 1e-3


def new_doc(insunits=4):
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = insunits
    return doc, doc.modelspace()


def save(doc, tmp_path, name="d.dxf"):
    p = tmp_path / name
    doc.saveas(p)
    return p


def add_square(layout, x0=0.0, y0=0.0, a=1.0):
    c = [(x0, y0), (x0 + a, y0), (x0 + a, y0 + a), (x0, y0 + a)]
    # out of order and mixed directions
    layout.add_line(c[1], c[2])
    layout.add_line(c[0], c[1])
    layout.add_line(c[0], c[3])
    layout.add_line(c[3], c[2])


def midpoint(path):
    return path.point([0.5 * path.length])[0]


# ---------------------------------------------------------------------------- lines, units
def test_lines_chain_into_closed_square_in_metres(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp, 1, 2, 10)
    layer = read_dxf(save(doc, tmp_path, "sq.dxf"))
    assert layer.source == "sq.dxf"
    assert len(layer) == 1 and layer[0].closed
    assert layer[0].length == pytest.approx(40 * MM, rel=1e-14)
    assert layer.bbox == pytest.approx((1 * MM, 2 * MM, 11 * MM, 12 * MM), rel=1e-9)
    assert layer.skipped == ()


def test_mm_and_inch_headers_differ_by_25_4(tmp_path):
    lengths = {}
    for code in (4, 1, 13, 6):
        doc, msp = new_doc(code)
        add_square(msp, 0, 0, 3)
        msp.add_circle((10, 0), 1)
        layer = read_dxf(save(doc, tmp_path, f"u{code}.dxf"))
        lengths[code] = sum(p.length for p in layer)
    assert lengths[1] / lengths[4] == pytest.approx(25.4, rel=1e-14)
    assert lengths[6] / lengths[4] == pytest.approx(1000.0, rel=1e-14)
    assert lengths[13] / lengths[4] == pytest.approx(1e-3, rel=1e-14)


def test_unitless_raises_and_override_works(tmp_path):
    doc, msp = new_doc(0)
    add_square(msp, 0, 0, 2)
    p = save(doc, tmp_path, "nounits.dxf")
    with pytest.raises(ValueError, match=r"nounits\.dxf.*units=.*--units mm"):
        read_dxf(p)
    assert read_dxf(p, units="mm")[0].length == pytest.approx(8 * MM)
    assert read_dxf(p, units="in")[0].length == pytest.approx(8 * 0.0254)
    assert read_dxf(p, units="inch")[0].length == pytest.approx(8 * 0.0254)
    assert read_dxf(p, units="um")[0].length == pytest.approx(8e-6)
    assert read_dxf(p, units="cm")[0].length == pytest.approx(8e-2)
    assert read_dxf(p, units="m")[0].length == pytest.approx(8.0)


def test_units_that_contradict_the_header_are_refused(tmp_path):
    """Issue 32: units= used to override a header that gives other units, rescaling the
    drawing silently (x 25.4 for inch on mm); the units apply where the header has none."""
    doc, msp = new_doc(1)  # $INSUNITS 1: inches
    add_square(msp)
    p = save(doc, tmp_path)
    with pytest.raises(ValueError, match=r"\$INSUNITS = 1, 0\.0254 m\); units 'mm'"):
        read_dxf(p, units="mm")
    assert read_dxf(p, units="inch")[0].length == read_dxf(p)[0].length  # the same: accepted


def test_unknown_units_code_and_name(tmp_path):
    doc, msp = new_doc(99)
    add_square(msp)
    p = save(doc, tmp_path)
    with pytest.raises(ValueError, match=r"\$INSUNITS = 99.*units="):
        read_dxf(p)
    with pytest.raises(ValueError, match=r"unknown units 'parsec'.*'mm'.*'inch'"):
        read_dxf(p, units="parsec")


# ---------------------------------------------------------------------------- arcs, circles
def test_arc_ccw(tmp_path):
    doc, msp = new_doc(4)
    arc = msp.add_arc((3, 4), 2, 30, 120)
    (path,) = read_dxf(save(doc, tmp_path))
    assert not path.closed
    assert path.length == pytest.approx(2 * math.radians(90) * MM, rel=1e-14)
    assert np.allclose(path.start, np.array(arc.start_point)[:2] * MM, atol=1e-15)
    assert np.allclose(path.end, np.array(arc.end_point)[:2] * MM, atol=1e-15)
    mid = next(iter(arc.vertices([75.0])))
    assert np.allclose(midpoint(path), np.array(mid)[:2] * MM, atol=1e-15)


def test_arc_negative_extrusion_runs_clockwise(tmp_path):
    doc, msp = new_doc(4)
    arc = msp.add_arc((2, 1), 1, 0, 90, dxfattribs={"extrusion": (0, 0, -1)})
    # close it with a chord so the traversal direction shows in the signed area
    s, e = arc.start_point, arc.end_point
    msp.add_line(e, s)
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.closed
    segs = [seg for seg in path.segments if isinstance(seg, ArcSegment)]
    assert len(segs) == 1
    arc_seg = segs[0]
    # WCS: the OCS centre (2, 1) is mirrored to (-2, 1); from (-3, 1) clockwise to (-2, 2)
    assert np.allclose(arc_seg.center, [-2 * MM, 1 * MM], atol=1e-15)
    assert np.allclose(np.array(s)[:2], [-3, 1]) and np.allclose(np.array(e)[:2], [-2, 2])
    assert arc_seg.sweep == pytest.approx(-math.pi / 2)
    assert np.allclose(arc_seg.start, [-3 * MM, 1 * MM], atol=1e-15)
    assert np.allclose(arc_seg.end, [-2 * MM, 2 * MM], atol=1e-15)
    mid = next(iter(arc.vertices([45.0])))
    q = arc_seg.center + arc_seg.radius * np.array(
        [math.cos(arc_seg.theta0 + arc_seg.sweep / 2), math.sin(arc_seg.theta0 + arc_seg.sweep / 2)]
    )
    assert np.allclose(q, np.array(mid)[:2] * MM, atol=1e-15)
    assert path.orientation == "cw"
    assert path.signed_area == pytest.approx(-(math.pi / 4 - 0.5) * MM**2, rel=1e-12)


def test_circle_full_and_mirrored(tmp_path):
    doc, msp = new_doc(4)
    msp.add_circle((5, 5), 2)
    msp.add_circle((5, 5), 1, dxfattribs={"extrusion": (0, 0, -1)})
    a, b = read_dxf(save(doc, tmp_path))
    assert a.closed and len(a) == 1 and a.orientation == "ccw"
    assert a.length == pytest.approx(4 * math.pi * MM, rel=1e-14)
    assert b.closed and b.orientation == "cw"
    assert np.allclose(b.segments[0].center, [-5 * MM, 5 * MM])
    assert b.signed_area == pytest.approx(-math.pi * MM**2, rel=1e-12)


def test_tilted_circle_and_3d_line_are_skipped(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    c = msp.add_circle((0, 0), 1, dxfattribs={"extrusion": (0, 1, 1)})
    ln = msp.add_line((0, 0, 0), (1, 1, 1))
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 1
    skipped = {s.ref: s for s in layer.skipped}
    assert skipped[c.dxf.handle].kind == "CIRCLE"
    assert "XY" in skipped[c.dxf.handle].reason
    assert skipped[ln.dxf.handle].kind == "LINE"
    assert "XY" in skipped[ln.dxf.handle].reason


def test_geometry_at_constant_elevation_is_taken(tmp_path):
    doc, msp = new_doc(4)
    msp.add_line((0, 0, 5), (1, 0, 5))
    layer = read_dxf(save(doc, tmp_path))
    assert layer[0].length == pytest.approx(1 * MM)


# ---------------------------------------------------------------------------- polylines
def test_lwpolyline_closed_with_bulges_exact_length(tmp_path):
    doc, msp = new_doc(4)
    b1, b2 = 1.0, -0.4  # semicircle outwards, shallow arc inwards
    pts = [(0, 0, 0), (4, 0, b1), (4, 3, 0), (0, 3, b2)]
    msp.add_lwpolyline(pts, format="xyb", close=True)
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.closed and len(path) == 4

    def arc_len(chord, bulge):
        sweep = 4 * math.atan(abs(bulge))
        return chord / (2 * math.sin(sweep / 2)) * sweep

    expected = 4 + 4 + arc_len(3, b1) + arc_len(3, b2)
    assert path.length == pytest.approx(expected * MM, rel=1e-9)
    assert path.orientation == "ccw"
    area = 12 + math.pi * 1.5**2 / 2
    r2 = 3 / (2 * math.sin(2 * math.atan(0.4)))
    seg2 = r2**2 / 2 * (4 * math.atan(0.4) - math.sin(4 * math.atan(0.4)))
    assert path.signed_area == pytest.approx((area - seg2) * MM**2, rel=1e-12)


def test_lwpolyline_negative_extrusion_and_elevation(tmp_path):
    doc, msp = new_doc(4)
    msp.add_lwpolyline(
        [(0, 0, 0), (2, 0, 1), (2, 2, 0), (0, 2, 0)],
        format="xyb",
        close=True,
        dxfattribs={"extrusion": (0, 0, -1), "elevation": 7.0},
    )
    (path,) = read_dxf(save(doc, tmp_path))
    # mirrored in x: the D shape lies in x ∈ [-3, 0] and runs clockwise
    xmin, _, xmax, _ = path.bbox
    assert xmin == pytest.approx(-3 * MM, rel=1e-6) and xmax == pytest.approx(0, abs=1e-12)
    assert path.orientation == "cw"
    assert path.signed_area == pytest.approx(-(4 + math.pi / 2) * MM**2, rel=1e-12)


def test_open_lwpolyline_stays_open(tmp_path):
    doc, msp = new_doc(4)
    msp.add_lwpolyline([(0, 0), (1, 0), (1, 1)])
    layer = read_dxf(save(doc, tmp_path))
    assert not layer[0].closed
    assert layer[0].length == pytest.approx(2 * MM)
    with pytest.raises(ValueError, match="open"):
        layer.require_closed()


def test_polyline2d_with_bulge(tmp_path):
    doc, msp = new_doc(4)
    pl = msp.add_polyline2d([(0, 0), (2, 0), (2, 2)], close=True)
    pl.vertices[1].dxf.bulge = 0.5
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.closed
    sweep = 4 * math.atan(0.5)
    expected = 2 + 2 * math.sqrt(2) + 2 / (2 * math.sin(sweep / 2)) * sweep
    assert path.length == pytest.approx(expected * MM, rel=1e-12)
    assert sum(isinstance(s, ArcSegment) for s in path.segments) == 1


def test_polyline3d_planar_taken_nonplanar_skipped(tmp_path):
    doc, msp = new_doc(4)
    msp.add_polyline3d([(0, 0, 2), (3, 0, 2), (3, 4, 2)], close=True)
    bad = msp.add_polyline3d([(10, 0, 0), (11, 0, 1), (12, 1, 0)])
    face = msp.add_polyface()
    face.append_face([(0, 0, 0), (1, 0, 0), (1, 1, 0)])
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 1 and layer[0].closed
    assert layer[0].length == pytest.approx(12 * MM)
    refs = {s.ref: s for s in layer.skipped}
    assert refs[bad.dxf.handle].kind == "POLYLINE"
    assert "mesh" in refs[face.dxf.handle].reason


# ---------------------------------------------------------------------------- splines
def test_nonrational_spline_matches_ezdxf(tmp_path):
    doc, msp = new_doc(4)
    cps = [(0, 0), (1, 3), (3, -1), (4, 2), (6, 0), (7, 1)]
    knots = [0, 0, 0, 0, 1, 2, 3, 3, 3, 3]
    spline = msp.add_open_spline(cps, degree=3, knots=knots)
    (path,) = read_dxf(save(doc, tmp_path))
    bs = spline.construction_tool()
    assert len(path) == 3 and all(isinstance(s, CurveSegment) for s in path.segments)
    assert all(s.degree <= 3 for s in path.segments)  # exact Bézier pieces, not a fit
    u = np.linspace(0, 1, 41)
    for j, seg in enumerate(path.segments):
        ref = np.array(list(bs.points((j + u).tolist())))[:, :2] * MM
        assert np.max(np.abs(seg.point(u) - ref)) <= 1e-9 * 7 * MM


def test_unclamped_spline_matches_ezdxf(tmp_path):
    doc, msp = new_doc(4)
    cps = [(0, 0), (1, 3), (3, -1), (4, 2), (6, 0), (7, 1)]
    spline = msp.add_open_spline(cps, degree=3, knots=list(range(10)))
    (path,) = read_dxf(save(doc, tmp_path))
    bs = spline.construction_tool()
    assert not bs.is_clamped
    # valid parameter range [3, 6]: three knot spans
    assert len(path) == 3
    u = np.linspace(0, 1, 41)
    for j, seg in enumerate(path.segments):
        ref = np.array(list(bs.points((3 + j + u).tolist())))[:, :2] * MM
        assert np.max(np.abs(seg.point(u) - ref)) <= 1e-9 * 7 * MM


def test_fit_point_spline(tmp_path):
    doc, msp = new_doc(4)
    fit = [(0, 0), (2, 1), (4, -1), (6, 0)]
    msp.add_spline(fit)
    (path,) = read_dxf(save(doc, tmp_path))
    assert np.allclose(path.start, [0, 0], atol=1e-15)
    assert np.allclose(path.end, [6 * MM, 0], atol=1e-15)
    # the curve passes through the fit points
    pts = path.flatten(1e-9 * MM)
    for f in fit:
        assert np.min(np.hypot(*(pts - np.array(f) * MM).T)) < 1e-8 * MM


def test_rational_spline_quarter_circle(tmp_path):
    doc, msp = new_doc(4)
    r = 5.0
    w = math.sqrt(0.5)
    msp.add_rational_spline([(r, 0), (r, r), (0, r)], [1, w, 1], degree=2, knots=[0, 0, 0, 1, 1, 1])
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.length == pytest.approx(math.pi * r / 2 * MM, rel=1e-8)
    p = path.resample(n=101)
    assert np.max(np.abs(np.hypot(*p.T) - r * MM)) < 1e-12 * MM


def test_rational_spline_full_circle_closes(tmp_path):
    doc, msp = new_doc(4)
    r = 2.0
    cps = [(r, 0), (r, r), (0, r), (-r, r), (-r, 0), (-r, -r), (0, -r), (r, -r), (r, 0)]
    w = math.sqrt(0.5)
    weights = [1, w, 1, w, 1, w, 1, w, 1]
    knots = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
    msp.add_rational_spline(cps, weights, degree=2, knots=knots)
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.closed
    assert len(path) == 4  # one piece per knot span
    assert path.length == pytest.approx(2 * math.pi * r * MM, rel=1e-8)
    assert path.signed_area == pytest.approx(math.pi * r**2 * MM**2, rel=1e-8)


# ---------------------------------------------------------------------------- ellipses
def test_full_ellipse_length(tmp_path):
    doc, msp = new_doc(4)
    a, ratio = 10.0, 0.4
    msp.add_ellipse((1, 2), major_axis=(a * math.cos(0.3), a * math.sin(0.3), 0), ratio=ratio)
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.closed and path.orientation == "ccw"
    expected = 4 * a * ellipe(1 - ratio**2)
    assert path.length == pytest.approx(expected * MM, rel=1e-9)
    assert path.signed_area == pytest.approx(math.pi * a * a * ratio * MM**2, rel=1e-9)


@pytest.mark.parametrize(("t0", "t1"), [(0.3, 2.0), (5.0, 1.0)])
def test_elliptic_arc(tmp_path, t0, t1):
    doc, msp = new_doc(4)
    a, b = 6.0, 2.0
    el = msp.add_ellipse((0, 0), major_axis=(a, 0, 0), ratio=b / a, start_param=t0, end_param=t1)
    (path,) = read_dxf(save(doc, tmp_path))
    assert not path.closed
    assert np.allclose(path.start, np.array(el.start_point)[:2] * MM, atol=1e-15)
    assert np.allclose(path.end, np.array(el.end_point)[:2] * MM, atol=1e-15)
    span = (t1 - t0) % (2 * math.pi)
    expected, _ = quad(
        lambda t: math.hypot(a * math.sin(t), b * math.cos(t)), t0, t0 + span, epsabs=1e-14
    )
    assert path.length == pytest.approx(expected * MM, rel=1e-9)


# ---------------------------------------------------------------------------- blocks
def block_doc():
    doc, msp = new_doc(4)
    blk = doc.blocks.new("PART")
    add_square(blk, 0, 0, 1)
    blk.add_circle((0.5, 0.5), 0.25)
    return doc, msp


def test_insert_scaled_rotated(tmp_path):
    doc, msp = block_doc()
    ins = msp.add_blockref("PART", (10, 5), dxfattribs={"xscale": 2, "yscale": 2, "rotation": 30})
    layer = read_dxf(save(doc, tmp_path))
    lengths = sorted(p.length for p in layer)
    assert lengths == pytest.approx([2 * math.pi * 0.5 * MM, 8 * MM], rel=1e-12)
    circle = next(p for p in layer if len(p) == 1)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    centre = np.array([10, 5]) + 2 * np.array([c * 0.5 - s * 0.5, s * 0.5 + c * 0.5])
    assert np.allclose(circle.segments[0].center, centre * MM, atol=1e-15)
    assert ins.dxf.handle  # the INSERT itself is not reported as skipped
    assert layer.skipped == ()


def test_insert_nonuniform_scale_turns_arcs_into_ellipses(tmp_path):
    doc, msp = new_doc(4)
    blk = doc.blocks.new("ROUND")
    blk.add_circle((0, 0), 1)
    blk.add_arc((5, 0), 1, 0, 90)
    msp.add_blockref("ROUND", (0, 0), dxfattribs={"xscale": 2, "yscale": 1})
    circle, arc = read_dxf(save(doc, tmp_path))
    m = 1 - (1 / 2) ** 2
    assert circle.closed
    assert circle.length == pytest.approx(4 * 2 * ellipe(m) * MM, rel=1e-9)
    assert not arc.closed
    assert arc.length == pytest.approx(2 * ellipe(m) * MM, rel=1e-9)
    assert np.allclose(arc.start, [12 * MM, 0], atol=1e-15)
    assert np.allclose(arc.end, [10 * MM, 1 * MM], atol=1e-15)


def test_insert_mirrored(tmp_path):
    doc, msp = new_doc(4)
    blk = doc.blocks.new("D")
    blk.add_lwpolyline([(0, 0, 0), (2, 0, 1), (2, 2, 0), (0, 2, 0)], format="xyb", close=True)
    blk.add_arc((5, 0), 1, 0, 90)
    msp.add_blockref("D", (0, 0), dxfattribs={"xscale": -1, "yscale": 1})
    d, arc = read_dxf(save(doc, tmp_path))
    assert d.orientation == "cw"
    assert d.signed_area == pytest.approx(-(4 + math.pi / 2) * MM**2, rel=1e-12)
    assert d.bbox[0] == pytest.approx(-3 * MM, rel=1e-6)
    assert np.allclose(arc.start, [-6 * MM, 0], atol=1e-15)
    assert np.allclose(arc.end, [-5 * MM, 1 * MM], atol=1e-15)
    assert arc.segments[0].sweep == pytest.approx(-math.pi / 2)
    mid = midpoint(arc)
    assert np.allclose(mid, [(-5 - math.sqrt(0.5)) * MM, math.sqrt(0.5) * MM], atol=1e-15)


def test_nested_blocks(tmp_path):
    doc, msp = new_doc(4)
    inner = doc.blocks.new("INNER")
    inner.add_circle((1, 0), 1)
    inner.add_text("label")
    outer = doc.blocks.new("OUTER")
    outer.add_blockref("INNER", (0, 2), dxfattribs={"xscale": 3, "yscale": 3})
    ins = msp.add_blockref("OUTER", (10, 0), dxfattribs={"xscale": 2, "yscale": 2, "rotation": 90})
    layer = read_dxf(save(doc, tmp_path))
    (circle,) = layer
    seg = circle.segments[0]
    assert seg.radius == pytest.approx(6 * MM, rel=1e-14)
    assert np.allclose(seg.center, [6 * MM, 6 * MM], atol=1e-15)
    (text,) = layer.skipped
    assert text.kind == "TEXT"
    assert text.ref.startswith(ins.dxf.handle) and "INNER" in text.ref


def test_minsert_grid(tmp_path):
    doc, msp = block_doc()
    msp.add_blockref("PART", (0, 0)).grid(size=(2, 3), spacing=(5, 5))
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 12
    assert sum(p.length for p in layer) == pytest.approx(6 * (4 + math.pi * 0.5) * MM)


def test_flatten_blocks_false_reports_insert(tmp_path):
    doc, msp = block_doc()
    add_square(msp, 20, 0, 1)
    ins = msp.add_blockref("PART", (0, 0))
    layer = read_dxf(save(doc, tmp_path), flatten_blocks=False)
    assert len(layer) == 1
    assert [(s.kind, s.ref) for s in layer.skipped] == [("INSERT", ins.dxf.handle)]


# ---------------------------------------------------------------------------- skipped, errors
def test_text_and_point_reported(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    t = msp.add_text("hello")
    pt = msp.add_point((3, 3))
    h = msp.add_mtext("more")
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 1
    got = {(s.kind, s.ref) for s in layer.skipped}
    assert got == {("TEXT", t.dxf.handle), ("POINT", pt.dxf.handle), ("MTEXT", h.dxf.handle)}
    assert all(s.reason for s in layer.skipped)
    assert layer.summary()["skipped"][0]["kind"] in {"TEXT", "POINT", "MTEXT"}


def test_only_unsupported_raises(tmp_path):
    doc, msp = new_doc(4)
    msp.add_text("a")
    msp.add_point((0, 0))
    with pytest.raises(ValueError, match=r"no importable geometry; skipped: 1 POINT, 1 TEXT"):
        read_dxf(save(doc, tmp_path))


def test_empty_drawing_raises(tmp_path):
    doc, _ = new_doc(4)
    with pytest.raises(ValueError, match=r"empty\.dxf: no importable geometry"):
        read_dxf(save(doc, tmp_path, "empty.dxf"))


def test_garbage_and_truncated_files_raise(tmp_path):
    g = tmp_path / "garbage.dxf"
    g.write_bytes(bytes(range(256)) * 20)
    with pytest.raises(ValueError, match=r"garbage\.dxf"):
        read_dxf(g)
    doc, msp = new_doc(4)
    add_square(msp)
    full = save(doc, tmp_path, "full.dxf").read_text()
    t = tmp_path / "truncated.dxf"
    t.write_text(full[: len(full) // 2])
    with pytest.raises(ValueError, match=r"truncated\.dxf"):
        read_dxf(t)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nope\.dxf"):
        read_dxf(tmp_path / "nope.dxf")


def test_chaining_tolerance(tmp_path):
    doc, msp = new_doc(4)
    msp.add_line((0, 0), (10, 1e-4))  # misses the next corner by 0.1 µm
    msp.add_line((10, 0), (10, 10))
    msp.add_line((10, 10), (0, 10))
    msp.add_line((0, 10), (0, 0))
    p = save(doc, tmp_path)
    with pytest.raises(ValueError, match="open"):
        read_dxf(p).require_closed()  # default tol: 1e-6 of 10 mm = 10 nm < 100 nm
    layer = read_dxf(p, tol=1e-6)
    assert layer.require_closed() is layer
    with pytest.raises(ValueError, match="tol"):
        read_dxf(p, tol=0.0)


def test_zero_length_line_reported(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    z = msp.add_line((5, 5), (5, 5))
    layer = read_dxf(save(doc, tmp_path))
    assert [(s.kind, s.ref) for s in layer.skipped] == [("LINE", z.dxf.handle)]


def test_polyline2d_negative_extrusion_runs_clockwise(tmp_path):
    doc, msp = new_doc(4)
    pl = msp.add_polyline2d(
        [(0, 0), (2, 0), (2, 2), (0, 2)], close=True, dxfattribs={"extrusion": (0, 0, -1)}
    )
    pl.vertices[1].dxf.bulge = 1.0  # semicircle on the edge (2, 0) -> (2, 2)
    (path,) = read_dxf(save(doc, tmp_path))
    assert path.orientation == "cw"
    assert path.signed_area == pytest.approx(-(4 + math.pi / 2) * MM**2, rel=1e-12)
    assert path.bbox[0] == pytest.approx(-3 * MM, rel=1e-6)


def test_out_of_plane_spline_and_ellipse_skipped(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    sp = msp.add_open_spline([(0, 0, 0), (1, 1, 1), (2, 0, 0), (3, 1, 0)])
    el = msp.add_ellipse((0, 0, 0), major_axis=(2, 0, 1), ratio=0.5)
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 1
    assert {(s.kind, s.ref) for s in layer.skipped} == {
        ("SPLINE", sp.dxf.handle),
        ("ELLIPSE", el.dxf.handle),
    }


def test_invalid_values_are_reported(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    bad = msp.add_circle((0, 0), 1)
    bad.dxf.radius = -2.0
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 1
    assert [(s.kind, s.ref) for s in layer.skipped] == [("CIRCLE", bad.dxf.handle)]
    assert "radius" in layer.skipped[0].reason


# ---------------------------------------------------------------------------- damaged files
def _square_text(tmp_path):
    doc, msp = new_doc(4)
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 10), (0, 10)], close=True)
    return save(doc, tmp_path, "full.dxf").read_bytes()


@pytest.mark.parametrize("extra", range(0, 15))
def test_cut_right_after_insunits_is_refused_not_stopiteration(tmp_path, extra):
    # issue 13: cut right after its $INSUNITS header value -> StopIteration from ezdxf
    data = _square_text(tmp_path)
    cut = tmp_path / "trunc.dxf"
    cut.write_bytes(data[: data.index(b"$INSUNITS") + extra])
    with pytest.raises(ValueError, match=r"^trunc\.dxf: not a readable DXF file \(") as err:
        read_dxf(cut)
    assert "\n" not in str(err.value)


def test_cut_binary_dxf_is_refused(tmp_path):
    doc, msp = new_doc(4)
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 10)], close=True)
    p = tmp_path / "bin.dxf"
    doc.saveas(p, fmt="bin")
    data = p.read_bytes()
    for k in (40, len(data) // 3, len(data) - 7):  # IndexError / struct.error in ezdxf
        p.write_bytes(data[:k])
        with pytest.raises(ValueError, match=r"^bin\.dxf: not a readable DXF file"):
            read_dxf(p)


def test_invalid_group_code_message_is_one_line(tmp_path):
    # ezdxf's 'Invalid group code "x\n"' spans two lines
    data = _square_text(tmp_path).replace(b"$INSUNITS", b"$INSUNITS\nx", 1)
    p = tmp_path / "junk.dxf"
    p.write_bytes(data)
    with pytest.raises(ValueError, match="not a readable DXF file") as err:
        read_dxf(p)
    assert "\n" not in str(err.value)


def test_ezdxf_repair_messages_are_not_printed(tmp_path, capfd, monkeypatch):
    # as on the command line: no logging handler anywhere, so Python would print warnings
    monkeypatch.setattr(logging.getLogger(), "handlers", [])
    text = (
        "0\nSECTION\n2\nHEADER\n9\n$ACADVER\n1\nAC1015\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n"
        "0\nSECTION\n2\nENTITIES\n"
        "0\nLINE\n5\nAB\n100\nAcDbEntity\n8\n0\n100\nAcDbLine\n10\n0\n20\n0\n11\n1\n21\n0\n"
        "0\nLINE\n5\nAB\n100\nAcDbEntity\n8\n0\n100\nAcDbLine\n10\n1\n20\n0\n11\n1\n21\n1\n"
        "0\nENDSEC\n0\nEOF\n"
    )  # two entities with the same handle: ezdxf logs a warning and repairs it
    p = tmp_path / "dup.dxf"
    p.write_text(text)
    layer = read_dxf(p)
    assert len(layer) == 1
    assert capfd.readouterr().err == ""


def test_absurd_bulge_arc_is_skipped_and_tiny_bulge_is_a_line(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    huge = msp.add_lwpolyline([(0, 20, 0), (5, 20, 1e308), (5, 25, 0)], format="xyb")
    tiny = msp.add_lwpolyline([(0, 40, 1e-320), (5, 40, 0)], format="xyb")
    layer = read_dxf(save(doc, tmp_path))
    assert [(s.kind, s.ref) for s in layer.skipped] == [("LWPOLYLINE", huge.dxf.handle)]
    assert "beyond ±1000 m" in layer.skipped[0].reason
    assert len(layer) == 2  # the square, and the tiny bulge read as a straight line
    assert tiny.dxf.handle not in {s.ref for s in layer.skipped}
    (line,) = (c for c in layer if not c.closed)
    assert line.length == pytest.approx(5 * MM, rel=1e-12)


def test_contours_shorter_than_a_nanometre_are_skipped(tmp_path):
    doc, msp = new_doc(4)
    add_square(msp)
    msp.add_line((100, 100), (100 + 1e-8, 100))  # 1e-11 m
    layer = read_dxf(save(doc, tmp_path))
    assert len(layer) == 1
    assert [s.kind for s in layer.skipped] == ["contour"]
    assert "shorter than 1e-09 m" in layer.skipped[0].reason


def test_a_contour_moved_beyond_a_kilometre_by_snapping_is_refused(tmp_path):
    # a half circle touching x = 1000 m whose end is snapped 1.4e-4 m out to a short arc:
    # its refitted circle reaches past 1000 m (each entity alone lies within)
    doc, msp = new_doc(6)
    msp.add_arc((999.5, 0.0), 0.5, 270, 90)
    msp.add_arc((999.5001 - 0.1, 0.5001), 0.1, 0, 30)
    p = save(doc, tmp_path, "edge.dxf")
    assert len(read_dxf(p)) == 2  # not joined at the default tolerance (1e-6 of the size)
    with pytest.raises(ValueError, match=r"^edge\.dxf: contour #0 has coordinates up to 1e\+03 m"):
        read_dxf(p, tol=1e-3)
