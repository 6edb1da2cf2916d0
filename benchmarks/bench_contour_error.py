"""Contour error of a tracked trace: vectorised foot points against the scalar baseline.

For each contour (seed 004 §IV.D: a circle of 100 µm radius; a DXF-like rounded rectangle
of 400 × 200 µm with 20 µm corner arcs, lines and arcs; and, beyond the brief, a DXF-like
slot with a cubic spline, for the curve search, and a 2000-gon of 100 µm radius, for the
candidate grids) the trace is ``n`` points (default 100 000) spaced
evenly along the contour, as a constant-speed trajectory samples it, each moved by a
uniform ±1 µm in x and in y. Printed, figures only:

- ``project_points`` wall time: the first call (it builds the path's index) and the best
  of 3 later calls, without and with ``hint`` (each sample's previous foot, as a tracker
  has it), and whether the hint changed anything (it must not);
- the scalar baseline ``project_points_scalar`` (bounded Brent per point and segment
  piece) on an evenly strided subset of ``n_ref`` points (default 300; for the 2000-gon
  30, as each of its points costs a second), its time per point, and that time scaled to
  ``n`` points (the baseline is linear in the points);
- the speed ratio (scaled baseline / best vectorised; goal >= 50) and the largest
  difference of the signed distances over the subset (goal <= 1e-10 m), and of the arc
  lengths.

Run: ``python benchmarks/bench_contour_error.py [n] [n_ref]``.
"""

from __future__ import annotations

import sys

import numpy as np
from _timing import best, timed

from microfab.geometry.path import Path
from microfab.geometry.project import Projection, project_points, project_points_scalar
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment
from microfab.geometry.shapes import circle, rectangle, regular_polygon

UM = 1e-6
JITTER = 1.0 * UM  # ±, m, uniform in each axis


def slot_with_spline() -> Path:
    """A DXF-like closed contour (100 x 80 µm): lines, two bulge arcs and a cubic spline."""
    P = np.array([[0, 0], [100, 0], [100, 40], [60, 40], [0, 40]], dtype=float) * UM
    ctrl = np.array([[60, 40], [40, 80], [20, 0], [0, 40]], dtype=float) * UM
    segs = (
        LineSegment(P[0], P[1]),
        ArcSegment.from_bulge(P[1], P[2], 1.0),
        LineSegment(P[2], P[3]),
        CurveSegment.from_bezier(ctrl),
        ArcSegment.from_bulge(P[4], P[0], 0.4),
    )
    return Path(segs, closed=True)


def tracked(path: Path, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points evenly along ``path``, jittered by ±1 µm; and their arc lengths."""
    rng = np.random.default_rng(seed)
    s = np.arange(n) * path.length / n
    return path.point(s) + rng.uniform(-JITTER, JITTER, (n, 2)), s


def same(a: Projection, b: Projection) -> bool:
    """Whether two projections are identical, array by array."""
    names = ("s", "foot", "tangent", "normal", "distance", "segment")
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in names)


def run(name: str, path: Path, n: int, n_ref: int) -> None:
    n_ref = min(n_ref, max(30, 3000 // len(path.segments)))  # the baseline is O(segments)
    p, _ = tracked(path, n)
    t_first, _ = timed(lambda: project_points(path, p))
    t_vec, proj = best(lambda: project_points(path, p))
    hint = np.roll(proj.s, 1)  # the previous sample's foot
    t_hint, with_hint = best(lambda: project_points(path, p, hint=hint))
    sub = np.linspace(0, n - 1, n_ref).astype(int)
    t_ref, ref = timed(lambda: project_points_scalar(path, p[sub]))
    t_ref /= n_ref
    d_err = float(np.max(np.abs(proj.distance[sub] - ref.distance)))
    ds = np.abs(proj.s[sub] - ref.s)
    ds = np.minimum(ds, path.length - ds)  # a closed contour: s and s + length are one point
    fastest = min(t_vec, t_hint)
    print(f"{name}: {len(path.segments)} segments, {n} points, jitter ±{JITTER / UM:g} µm")
    print(
        f"  project_points  first {t_first * 1e3:8.1f} ms   best of 3 {t_vec * 1e3:8.1f} ms"
        f"   {t_vec / n * 1e9:7.0f} ns/point"
    )
    print(
        f"  with hint                        best of 3 {t_hint * 1e3:8.1f} ms"
        f"   identical to no hint: {same(proj, with_hint)}"
    )
    print(
        f"  scalar baseline on {n_ref} points: {t_ref * 1e3:.3f} ms/point, "
        f"scaled to {n} points: {t_ref * n:.1f} s"
    )
    print(f"  speed ratio (scaled baseline / best vectorised): {t_ref * n / fastest:,.0f}")
    print(
        f"  max |distance - baseline| = {d_err:.3g} m   max |s - baseline| = {ds.max():.3g} m"
        f"   contour error rms {np.sqrt(np.mean(proj.distance**2)) / UM:.3f} µm"
    )


def main(n: int = 100_000, n_ref: int = 300) -> None:
    contours = [
        ("circle r = 100 µm", circle(100 * UM)),
        (
            "rounded rectangle 400 x 200 µm, r = 20 µm",
            rectangle(400 * UM, 200 * UM, corner_radius=20 * UM),
        ),
        ("DXF-like slot: lines, bulge arcs, a cubic spline", slot_with_spline()),
        ("2000-gon r = 100 µm", regular_polygon(2000, 100 * UM)),
    ]
    for name, path in contours:
        run(name, path, n, n_ref)


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:3]]
    main(*args)
