from importlib import resources

import numpy as np
import pytest

from microfab.geometry.airfoil import airfoil_knots, airfoil_path, read_selig
from microfab.geometry.segments import CurveSegment, LineSegment


def naca00xx(t=0.12, n=40):
    """Selig-ordered points of a symmetric NACA 4-digit section (open trailing edge)."""
    beta = np.linspace(0, np.pi, n)
    x = 0.5 * (1 - np.cos(beta))  # LE -> TE
    yt = 5 * t * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1015 * x**4)
    upper = np.column_stack([x, yt])[::-1]  # TE -> LE
    lower = np.column_stack([x, -yt])[1:]  # LE (not repeated) -> TE
    return np.vstack([upper, lower])


def selig_text(P, name="TEST FOIL"):
    return name + "\n" + "\n".join(f"{x:.10f} {y:.10f}" for x, y in P) + "\n"


def junction_points(path):
    return np.array([s.start for s in path.segments])


# ------------------------------------------------------------------ reading
def e344_text():
    return resources.files("microfab.data").joinpath("airfoils", "e344.dat").read_text()


def test_builtin_e344_file():
    name, P = read_selig(e344_text())
    assert name == "EPPLER 344 AIRFOIL"
    assert P.shape == (72, 2)
    np.testing.assert_array_equal(P[0], [1.0, 0.0])
    np.testing.assert_array_equal(P[-1], [1.0, 0.0])
    assert P[:, 0].min() == pytest.approx(0.00011)


def test_read_selig_from_file(tmp_path):
    P = naca00xx()
    f = tmp_path / "n0012.dat"
    f.write_text(selig_text(P))
    for src in (f, str(f)):
        name, Q = read_selig(src)
        assert name == "TEST FOIL"
        np.testing.assert_allclose(Q, P, atol=1e-10)


def test_lednicer_is_reordered_to_selig():
    P = naca00xx(n=30)
    x_le = int(np.argmin(P[:, 0]))
    upper = P[: x_le + 1][::-1]  # LE -> TE
    lower = P[x_le:]  # LE -> TE, LE repeated
    text = (
        "NACA 0012 (LEDNICER)\n"
        f"{len(upper)}.  {len(lower)}.\n\n"
        + "\n".join(f"{x:.10f} {y:.10f}" for x, y in upper)
        + "\n\n"
        + "\n".join(f"{x:.10f} {y:.10f}" for x, y in lower)
        + "\n"
    )
    name, Q = read_selig(text)
    assert name == "NACA 0012 (LEDNICER)"
    np.testing.assert_allclose(Q, P, atol=1e-10)


@pytest.mark.parametrize(
    "text, match",
    [
        ("JUST A NAME\n", "no coordinates"),
        ("", "empty"),
        ("\n\n", "empty"),
        ("FOIL\n1.0\n0.5\n0.0\n0.5\n1.0\n", "two columns"),
        ("FOIL\n1 0 0\n0.5 0.1 0\n0 0 0\n0.5 -0.1 0\n1 0 0\n", "two columns"),
        ("FOIL\n1 0\n0.5 0.1\n0 0\n1 0\n", "at least 5"),
        ("FOIL\n1 0\n0.5 0.1\n0 0\n0.5 -0.1\n1.5 0\n", "outside"),
        ("FOIL\n1 0\n0.5 0.1\n-0.2 0\n0.5 -0.1\n1 0\n", "outside"),
        ("FOIL\n1 0\n0.5 nan\n0 0\n0.5 -0.1\n1 0\n", "finite"),
        ("FOIL\n1 0\n0.5 0.1\nzero zero\n0.5 -0.1\n1 0\n", "line 4"),
        ("FOIL\n3. 3.\n0 0\n0.5 0.1\n1 0\n0 0\n0.5 -0.1\n", "Lednicer"),
        # an infinite count line was an OverflowError (int(inf)); it is no count line
        ("FOIL\ninf 39983\n0 0\n0.5 0.1\n1 0\n0 0\n0.5 -0.1\n", "finite"),
        ("FOIL\n1e300 3\n0 0\n0.5 0.1\n1 0\n0 0\n0.5 -0.1\n", "outside"),
        # y = 1.8e308 overflowed the spline fit, with warnings
        ("FOIL\n1 0\n0.5 1.7976931348623157e308\n0 0\n0.5 -0.1\n1 0\n", r"y = .*\[-1, 1\]"),
    ],
)
def test_malformed_files_raise(text, match):
    with pytest.raises(ValueError, match=match):
        read_selig(text)


def test_missing_file_raises():
    with pytest.raises(ValueError, match="neither a file"):
        read_selig("no_such_airfoil.dat")


# ------------------------------------------------------------------ outline
@pytest.fixture(scope="module")
def e344():
    return airfoil_path("e344", chord=0.1)


def test_closed_with_chord_as_asked(e344):
    assert e344.closed
    pts = junction_points(e344)
    assert pts[:, 0].min() == pytest.approx(0.0, abs=1e-15)
    assert pts[:, 0].max() == pytest.approx(0.1, rel=1e-12)
    # the extremes of x are at junctions: no sampled point goes beyond them
    q = e344.point(np.linspace(0, e344.length, 20001))
    assert q[:, 0].min() >= -1e-9 * 0.1
    assert q[:, 0].max() <= 0.1 * (1 + 1e-9)
    # and the leading edge is a vertical tangent
    i_le = int(np.argmin(pts[:, 0]))
    t = e344.tangent([e344.breaks[i_le]])[0]
    assert abs(t[0]) < 1e-9


@pytest.mark.parametrize("chord", [0.05, 0.1, 0.37])
def test_chord_scales(chord):
    p = airfoil_path("e344", chord=chord)
    pts = junction_points(p)
    assert np.ptp(pts[:, 0]) == pytest.approx(chord, rel=1e-12)
    assert p.length == pytest.approx(airfoil_path("e344", chord=1.0).length * chord, rel=1e-12)


def test_passes_through_every_point(e344):
    knots = airfoil_knots("e344", chord=0.1)
    assert knots.shape == (72, 2)
    pts = np.vstack([junction_points(e344), e344.end])
    d = np.min(np.linalg.norm(knots[:, None, :] - pts[None, :, :], axis=2), axis=1)
    assert np.max(d) <= 1e-12 * 0.1
    # the knots are the data scaled uniformly
    _, P = read_selig(e344_text())
    k = (knots[0, 0] - knots[5, 0]) / (P[0, 0] - P[5, 0])
    np.testing.assert_allclose(np.diff(knots, axis=0), k * np.diff(P, axis=0), atol=1e-15)


def end_curvature(seg, u):
    """Signed curvature of a CurveSegment at parameter u (exact, one-sided at u = 0, 1)."""
    d1, d2, _ = seg.derivative_coefs
    x = np.array([2.0 * u - 1.0])
    v = np.polynomial.chebyshev.chebval(x, d1)
    a = np.polynomial.chebyshev.chebval(x, d2)
    v, a = v.reshape(2), a.reshape(2)
    return (v[0] * a[1] - v[1] * a[0]) / np.hypot(*v) ** 3, v / np.hypot(*v)


def test_c2_except_at_trailing_edge(e344):
    segs = e344.segments
    assert all(isinstance(s, CurveSegment) and s.degree <= 3 for s in segs)
    kl, tl = zip(*(end_curvature(s, 1.0) for s in segs[:-1]), strict=True)
    kr, tr = zip(*(end_curvature(s, 0.0) for s in segs[1:]), strict=True)
    kmax = np.max(np.abs(e344.curvature(np.linspace(0, e344.length, 4001))))
    np.testing.assert_allclose(kl, kr, rtol=1e-7, atol=1e-9 * kmax)
    np.testing.assert_allclose(tl, tr, atol=1e-12)
    # the trailing edge (end of the last piece -> start of the first) is not smooth
    _, t_end = end_curvature(segs[-1], 1.0)
    _, t_start = end_curvature(segs[0], 0.0)
    assert np.linalg.norm(t_end - t_start) > 0.1
    # the only corner is the trailing edge, at the start of the path
    np.testing.assert_array_equal(e344.corners(), [0.0])
    np.testing.assert_allclose(e344.start, [0.1, 0.0], atol=1e-15)


def test_c2_check_detects_a_curvature_jump():
    # guards the test above: two arcs of different radius joined tangentially are C¹, not C²
    from microfab.geometry.path import Path
    from microfab.geometry.segments import ArcSegment

    def bez(arc):
        return CurveSegment.from_function(
            lambda u: (
                arc.center
                + arc.radius
                * np.column_stack(
                    [np.cos(arc.theta0 + u * arc.sweep), np.sin(arc.theta0 + u * arc.sweep)]
                )
            )
        )[0]

    a = ArcSegment([0.0, 0.0], 1.0, -np.pi / 2, np.pi / 2)
    b = ArcSegment([-1.0, 0.0], 2.0, 0.0, np.pi / 3)
    p = Path((bez(a), bez(b)))
    (k0, t0), (k1, t1) = end_curvature(p.segments[0], 1.0), end_curvature(p.segments[1], 0.0)
    np.testing.assert_allclose(t0, t1, atol=1e-9)
    assert abs(k0 - k1) == pytest.approx(0.5, rel=1e-6)


def test_open_trailing_edge_closed_by_line():
    P = naca00xx()
    assert P[0, 1] > 0  # NACA 4-digit sections have a thick trailing edge
    p = airfoil_path(P, chord=0.2)
    assert p.closed
    assert isinstance(p.segments[-1], LineSegment)
    assert p.segments[-1].length == pytest.approx(2 * P[0, 1] * 0.2, rel=1e-9)
    assert p.corners().size == 2
    assert abs(p.signed_area) == pytest.approx(0.0822 * 0.2**2, rel=0.01)  # t/c 12 %: 0.685 t c²


@pytest.mark.parametrize(
    "start, direction",
    [("trailing", "ccw"), ("trailing", "cw"), ("leading", "ccw"), ("leading", "cw")],
)
def test_start_and_direction(start, direction):
    p = airfoil_path("e344", chord=0.1, start=start, direction=direction)
    assert p.orientation == direction
    if start == "trailing":
        np.testing.assert_allclose(p.start, [0.1, 0.0], atol=1e-15)
    else:
        assert p.start[0] == pytest.approx(0.0, abs=1e-15)
        # seed 002 Fig. 13: clockwise from the leading edge goes over the upper surface
        q = p.point([0.25 * p.length])[0]
        assert (q[1] > 0) == (direction == "cw")
    assert p.length == pytest.approx(airfoil_path("e344").length, rel=1e-12)


def test_n_max_subsamples():
    p = airfoil_path("e344", n_max=20)
    assert len(p.segments) <= 21
    assert junction_points(p)[:, 0].min() == pytest.approx(0.0, abs=1e-15)
    assert p.length == pytest.approx(airfoil_path("e344").length, rel=0.01)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"points_or_name": "naca9999"}, "unknown airfoil"),
        ({"chord": 0.0}, "chord"),
        ({"chord": -1.0}, "chord"),
        ({"chord": 1.7976931348623157e308}, "chord"),  # overflowed, with warnings
        ({"n_max": 4}, "n_max"),
        ({"start": "middle"}, "start"),
        ({"direction": "up"}, "direction"),
        ({"points_or_name": np.zeros((4, 2))}, "at least 5"),
        ({"points_or_name": np.ones((6, 3))}, "shape"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        airfoil_path(**kwargs)
