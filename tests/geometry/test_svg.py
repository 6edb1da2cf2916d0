import math

import numpy as np
import pytest
import svgpathtools

from microfab.geometry.path import MAX_FLATTEN
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment
from microfab.geometry.svg import PX, parse_svg_path, read_svg

MM = 1e-3


def mapped(z, scale=MM, flip=True):
    """svgpathtools complex point(s) -> our coordinates."""
    z = np.atleast_1d(np.asarray(z, dtype=complex))
    return np.column_stack([z.real * scale, (-z.imag if flip else z.imag) * scale])


def dist_to_polyline(pts, poly):
    a, b = poly[:-1], poly[1:]
    ab = b - a
    out = []
    for p in pts:
        t = np.clip(((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300), 0, 1)
        out.append(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))
    return np.array(out)


# ------------------------------------------------------------------ path data
def test_square_closed_area_and_flip():
    layer = parse_svg_path("M0 0 H10 V10 H0 Z")
    assert len(layer) == 1
    (c,) = layer
    assert c.closed
    assert all(isinstance(s, LineSegment) for s in c.segments)
    assert c.signed_area == pytest.approx(-100 * MM**2, rel=1e-12)  # clockwise on screen
    assert c.orientation == "cw"
    assert c.bbox == pytest.approx((0, -10 * MM, 10 * MM, 0), abs=1e-12)
    unflipped = parse_svg_path("M0 0 H10 V10 H0 Z", flip_y=False)[0]
    assert unflipped.orientation == "ccw"
    assert parse_svg_path("M0 0 H10 V10 H0 Z", scale=2.0)[0].length == pytest.approx(80.0)


def test_relative_equals_absolute():
    a = parse_svg_path("M 1 2 L 5 2 C 6 3 7 3 8 2 Q 9 0 10 2 A 3 3 0 0 1 16 2 V 8 H 1 Z")
    b = parse_svg_path("m 1 2 l 4 0 c 1 1 2 1 3 0 q 1 -2 2 0 a 3 3 0 0 1 6 0 v 6 h -15 z")
    pa, pb = a[0], b[0]
    assert pa.length == pytest.approx(pb.length, rel=1e-14)
    s = np.linspace(0, pa.length, 57)
    np.testing.assert_allclose(pa.point(s), pb.point(s), atol=1e-15)
    assert [type(x) for x in pa.segments] == [type(x) for x in pb.segments]


@pytest.mark.parametrize("large", [0, 1])
@pytest.mark.parametrize("sweep", [0, 1])
@pytest.mark.parametrize("flip", [True, False])
def test_circular_arc_is_exact_and_follows_svg(large, sweep, flip):
    d = f"M 10 20 A 7 7 0 {large} {sweep} 20 25"
    layer = parse_svg_path(d, flip_y=flip)
    (c,) = layer
    (seg,) = c.segments
    assert isinstance(seg, ArcSegment)
    assert seg.radius == pytest.approx(7 * MM, rel=1e-14)
    ref = svgpathtools.parse_path(d)[0]
    t = np.linspace(0, 1, 41)
    # a circular arc is traversed at constant speed: s = t L
    want = mapped([ref.point(x) for x in t], flip=flip)
    np.testing.assert_allclose(c.point(t * c.length), want, atol=1e-15)
    assert c.length == pytest.approx(ref.length() * MM, rel=1e-9)


def test_arc_with_rotation_on_circle_stays_circle():
    d = "M 0 0 A 5 5 33 0 1 6 4"
    (seg,) = parse_svg_path(d)[0].segments
    assert isinstance(seg, ArcSegment)
    ref = svgpathtools.parse_path(d)[0]
    np.testing.assert_allclose(seg.end, mapped(ref.end)[0], atol=1e-15)


def test_elliptical_arc_lies_on_its_ellipse():
    d = "M 0 0 A 8 3 30 1 0 6 4"
    c = parse_svg_path(d)[0]
    assert all(isinstance(s, CurveSegment) for s in c.segments)
    ref = svgpathtools.parse_path(d)[0]
    np.testing.assert_allclose(c.start, [0, 0], atol=1e-15)
    np.testing.assert_allclose(c.end, mapped(ref.end)[0], atol=1e-14)
    assert c.length == pytest.approx(ref.length(error=1e-12) * MM, rel=1e-8)
    # back to SVG units, into the ellipse's frame: (x/rx)^2 + (y/ry)^2 = 1
    p = c.point(np.linspace(0, c.length, 101)) / MM
    z = p[:, 0] - 1j * p[:, 1] - ref.center
    w = z * np.exp(-1j * math.radians(ref.rotation))
    r = (w.real / ref.radius.real) ** 2 + (w.imag / ref.radius.imag) ** 2
    np.testing.assert_allclose(r, 1.0, atol=1e-11)


def test_smooth_curves_s_and_t_reflect_controls():
    d = "M0 0 C 1 2 3 2 4 0 S 7 -2 8 0 Q 9 2 10 0 T 12 0 T 14 0"
    c = parse_svg_path(d)[0]
    assert not c.closed
    assert len(c.segments) == 5
    assert all(isinstance(s, CurveSegment) for s in c.segments)
    # S and T make the joins tangent-continuous: no corners at all
    assert c.corners().size == 0
    ref = svgpathtools.parse_path(d)
    for ours, theirs in zip(c.segments, ref, strict=True):
        t = np.linspace(0, 1, 9)
        np.testing.assert_allclose(ours.point(t), mapped([theirs.point(x) for x in t]), atol=1e-15)
    # a plain corner is detected
    assert parse_svg_path("M0 0 C 1 2 3 2 4 0 C 5 2 6 2 7 0")[0].corners().size == 1


def test_subpaths_are_contours_and_relative_moveto_after_close():
    layer = parse_svg_path("M0 0 h4 v4 h-4 z m 1 1 h2 v2 h-2 z M 10 10 l 1 0 l 0 1")
    assert len(layer) == 3
    assert [c.closed for c in layer] == [True, True, False]
    # "m 1 1" after z is relative to the first subpath's start (0, 0)
    np.testing.assert_allclose(layer[1].start, [1 * MM, -1 * MM], atol=1e-15)
    assert layer.depth[:2] == (0, 1)


def test_drawing_after_close_starts_new_subpath_at_its_start():
    layer = parse_svg_path("M 2 3 L 10 3 L 10 10 Z L 2 20 L 5 20")
    assert len(layer) == 2
    assert layer[0].closed and not layer[1].closed
    np.testing.assert_allclose(layer[1].start, [2 * MM, -3 * MM], atol=1e-15)


def test_open_subpath_ending_at_start_is_closed_and_other_open():
    assert parse_svg_path("M0 0 L 5 0 L 5 5 L 0 0")[0].closed
    assert not parse_svg_path("M0 0 L 5 0 L 5 5 L 0 0.5")[0].closed


def test_degenerate_subpaths():
    layer = parse_svg_path("M 1 1 M 0 0 L 3 0 L 3 3 Z M 5 5 L 5 5")
    assert len(layer) == 1
    assert len(layer.skipped) == 1 and "zero length" in layer.skipped[0].reason
    assert len(parse_svg_path("")) == 0


def test_zero_radius_arc_is_a_line():
    (seg,) = parse_svg_path("M 0 0 A 0 5 0 0 1 3 4")[0].segments
    assert isinstance(seg, LineSegment)
    assert seg.length == pytest.approx(5 * MM)


@pytest.mark.parametrize(
    "d, match",
    [
        ("M 0 0 L 10", "malformed"),
        ("L 0 0 L 1 1", "moveto"),
        ("10 10 L 1 1", "moveto"),
        ("M 0 0 X 1 1", "unexpected character 'X'"),
        ("M 0 0 L 1 1 foo", "unexpected character"),
        ("M 0 0 Z 3", "closepath takes no numbers"),
        ("M 0 0 A 5 5 0 0 1 0 0", "coincide"),
    ],
)
def test_malformed_path_data_raises(d, match):
    with pytest.raises(ValueError, match=match):
        parse_svg_path(d)


def test_bad_scale_raises():
    with pytest.raises(ValueError, match="scale"):
        parse_svg_path("M0 0 L1 1", scale=0.0)


# ------------------------------------------------------------------ documents
SVG_HEAD = '<svg xmlns="http://www.w3.org/2000/svg" {attrs}>'


def write(tmp_path, body, attrs='width="20mm" height="10mm" viewBox="0 0 200 100"'):
    f = tmp_path / "d.svg"
    f.write_text(SVG_HEAD.format(attrs=attrs) + body + "</svg>")
    return f


def test_units_from_width_and_viewbox_and_flip_about_bottom(tmp_path):
    f = write(tmp_path, '<rect id="r" x="10" y="20" width="30" height="40"/>')
    layer = read_svg(f)
    assert layer.source == "d.svg"
    (c,) = layer
    # 20 mm / 200 user units = 0.1 mm per unit; y' = (100 - y) * 0.1 mm
    assert abs(c.signed_area) == pytest.approx(3 * 4 * MM**2, rel=1e-12)
    assert c.bbox == pytest.approx((1 * MM, 4 * MM, 4 * MM, 8 * MM), abs=1e-12)
    assert read_svg(f, scale=1.0)[0].bbox == pytest.approx((10, 40, 40, 80), abs=1e-9)


@pytest.mark.parametrize(
    "width, expected",
    [("2in", 0.0508), ("5cm", 0.05), ("96px", 0.0254), ("72pt", 0.0254), ("1", PX)],
)
def test_width_units(tmp_path, width, expected):
    # the line spans the whole viewBox width, so its length is the document width
    f = write(
        tmp_path, '<line x1="0" y1="0" x2="100" y2="0"/>', f'width="{width}" viewBox="0 0 100 50"'
    )
    (c,) = read_svg(f)
    assert c.length == pytest.approx(expected, rel=1e-12)


def test_no_units_means_css_px(tmp_path):
    f = write(tmp_path, '<line x1="0" y1="0" x2="96" y2="0"/>', "")
    assert read_svg(f)[0].length == pytest.approx(0.0254, rel=1e-12)
    f = write(tmp_path, '<line x1="0" y1="0" x2="96" y2="0"/>', 'width="100%" viewBox="0 0 10 10"')
    assert read_svg(f)[0].length == pytest.approx(0.0254, rel=1e-12)


def test_basic_shapes_and_skipped(tmp_path):
    body = """
      <circle cx="50" cy="50" r="10"/>
      <ellipse cx="100" cy="50" rx="20" ry="10"/>
      <rect x="0" y="0" width="40" height="20" rx="5"/>
      <polygon points="0,0 10,0 10,10"/>
      <polyline points="0,0 10,0 10,10"/>
      <line x1="0" y1="0" x2="0" y2="10"/>
      <text x="0" y="0">hi</text>
      <rect width="0" height="3"/>
      <defs><rect width="5" height="5"/></defs>
    """
    layer = read_svg(write(tmp_path, body))
    kinds = [c.closed for c in layer]
    assert kinds == [True, True, True, True, False, False]
    circle, ellipse, rect, tri = layer.contours[:4]
    assert all(isinstance(s, ArcSegment) for s in circle.segments)
    assert abs(circle.signed_area) == pytest.approx(math.pi * 1 * MM**2, rel=1e-12)
    assert abs(ellipse.signed_area) == pytest.approx(math.pi * 2 * 1 * MM**2, rel=1e-10)
    assert abs(rect.signed_area) == pytest.approx((8 - (4 - math.pi) * 0.25) * MM**2, rel=1e-12)
    assert sum(isinstance(s, ArcSegment) for s in rect.segments) == 4
    assert abs(tri.signed_area) == pytest.approx(0.5 * MM**2, rel=1e-12)
    assert sorted(s.kind for s in layer.skipped) == ["rect", "text"]


def test_group_transforms_compose(tmp_path):
    body = """
      <g transform="translate(10,0)">
        <g transform="scale(2)"><rect x="0" y="0" width="1" height="1"/></g>
        <path transform="rotate(90)" d="M 0 0 L 5 0"/>
      </g>
    """
    layer = read_svg(write(tmp_path, body), scale=1.0)  # user units as metres, y' = 100 - y
    rect, line = layer
    assert rect.bbox == pytest.approx((10, 98, 12, 100), abs=1e-9)
    np.testing.assert_allclose(line.end, [10, 95], atol=1e-12)


@pytest.mark.parametrize("tf", ["matrix(0,1,1,0,0,0)", "scale(-1,1)", "rotate(40) scale(1.5)"])
def test_arcs_under_similarities_stay_exact_arcs(tmp_path, tf):
    d = "M 10 20 A 7 7 0 0 1 20 25"
    layer = read_svg(write(tmp_path, f'<path transform="{tf}" d="{d}"/>'), scale=1.0)
    (seg,) = layer[0].segments
    assert isinstance(seg, ArcSegment)
    # independent reference: svgpathtools' own arc points, mapped by the transform and flip
    M = svgpathtools.parser.parse_transform(tf)
    ref = svgpathtools.parse_path(d)[0]
    t = np.linspace(0, 1, 21)
    z = np.array([ref.point(x) for x in t])
    xy = (M[:2, :2] @ np.vstack([z.real, z.imag])).T + M[:2, 2]
    want = np.column_stack([xy[:, 0], 100 - xy[:, 1]])
    c = layer[0]
    np.testing.assert_allclose(c.point(t * c.length), want, atol=1e-12)


def test_circle_under_unequal_scale_becomes_ellipse(tmp_path):
    f = write(tmp_path, '<circle transform="scale(2,1)" cx="0" cy="0" r="1"/>')
    (c,) = read_svg(f, scale=1.0)
    assert all(isinstance(s, CurveSegment) for s in c.segments)
    assert abs(c.signed_area) == pytest.approx(2 * math.pi, rel=1e-11)


def test_document_errors(tmp_path):
    with pytest.raises(ValueError, match="id='bad'"):
        read_svg(write(tmp_path, '<path id="bad" d="M 0 0 L 3"/>'))
    with pytest.raises(ValueError, match="transform"):
        read_svg(write(tmp_path, '<path transform="wobble(3)" d="M 0 0 L 3 3"/>'))
    with pytest.raises(ValueError, match="viewBox"):
        read_svg(write(tmp_path, "", 'viewBox="0 0 -1 3"'))
    f = tmp_path / "x.svg"
    f.write_text("<svg><path d='M0 0 L1 1'></svg>")
    with pytest.raises(ValueError, match="well-formed"):
        read_svg(f)
    f.write_text("<html/>")
    with pytest.raises(ValueError, match="not <svg>"):
        read_svg(f)


def test_elements_without_namespace_are_read(tmp_path):
    f = tmp_path / "n.svg"
    f.write_text('<svg><g><path d="M0 0 L 10 0 L 10 10 Z"/></g></svg>')
    (c,) = read_svg(f)
    assert c.closed
    assert abs(c.signed_area) == pytest.approx(50 * PX**2, rel=1e-12)


# ------------------------------------------------------------------ absurd and empty drawings
def test_scale_1e308_is_refused_with_the_element(tmp_path):
    # issue 13: transform="scale(1e308)" gave coordinates of 2.6e304 m, accepted
    f = tmp_path / "d.svg"
    f.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg"><g transform="scale(1e308)">'
        '<path d="M 0 0 L 100 0 L 100 100 Z"/></g></svg>'
    )
    with pytest.raises(
        ValueError, match=r"d\.svg: .*<path> #2: subpath 0 reaches .* beyond ±1000 m"
    ):
        read_svg(f)


def test_a_large_but_finite_scale_beyond_the_limit_is_refused(tmp_path):
    f = write(tmp_path, '<g transform="scale(1e7)"><rect x="0" y="0" width="10" height="5"/></g>')
    with pytest.raises(ValueError, match=r"reaches .* m, beyond ±1000 m"):
        read_svg(f)


def test_overflowing_transforms_are_refused(tmp_path):
    body = (
        '<polyline transform="scale(1.9,-362881) scale(1.7976931348623157e+308)" points="1 0 5 5"/>'
    )
    with pytest.raises(ValueError, match="overflows"):
        read_svg(write(tmp_path, body))


@pytest.mark.parametrize(
    "body",
    ["", "<text>only text</text>", '<path d=""/>', '<circle cx="1" cy="1"/>'],
)
def test_a_drawing_with_nothing_to_import_is_refused(tmp_path, body):
    # issue 13: an empty SVG gave an empty picture and exit 0
    with pytest.raises(ValueError, match=r"^d\.svg: no importable geometry; skipped: "):
        read_svg(write(tmp_path, body))


def test_arc_with_non_finite_radius_is_refused(tmp_path):
    with pytest.raises(ValueError, match="non-finite"):
        read_svg(write(tmp_path, '<path d="M 0 0 A 1e308 1e308 0 0 1 1e308 1"/>'))


def test_cusp_is_flattened_with_bounded_vertices(tmp_path):
    # a quadratic that runs out and back to its start: unbounded curvature at the tip
    f = write(tmp_path, '<path d="M -24 0 T 66 68 q -12.7 71.4 3.7e-117 -4.1e-154"/>')
    layer = read_svg(f)
    pts = layer[0].flatten()
    assert len(pts) <= MAX_FLATTEN * len(layer[0].segments) + 1
    assert np.all(np.isfinite(pts))


def test_subpaths_shorter_than_a_nanometre_are_skipped(tmp_path):
    f = write(tmp_path, '<path d="M 0 0 L 10 0 L 10 10 Z M 50 50 l 1e-9 0"/>')
    layer = read_svg(f)
    assert len(layer) == 1
    assert [s.kind for s in layer.skipped] == ["subpath"]
    assert "shorter than 1e-09 m" in layer.skipped[0].reason


@pytest.mark.parametrize(
    ("width", "says"),
    [("nanmm", "is not a length"), ("wide", "is not a length"), ("1e999mm", "finite length")],
)
def test_a_width_that_is_no_length_is_refused_not_read_as_pixels(tmp_path, width, says):
    """Issue 32: width="nanmm" was read silently, as CSS pixels."""
    f = write(
        tmp_path, '<line x1="0" y1="0" x2="100" y2="0"/>', f'width="{width}" viewBox="0 0 100 50"'
    )
    with pytest.raises(ValueError, match=says):
        read_svg(f)
