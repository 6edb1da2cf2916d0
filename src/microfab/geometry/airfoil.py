"""Airfoil outlines: coordinate files and a C² interpolating spline as exact segments.

The airfoil test case of seed 002 §II-C is the high-lift Eppler e344 airfoil (seed 002
ref. [30]: R. Eppler, "Airfoil data", in *Airfoil Design and Data*, Springer, 1990,
pp. 163–512). Its coordinates ship with this package as ``data/airfoils/e344.dat``, an
unmodified copy of ``e344.dat`` from the UIUC Airfoil Coordinates Database (M. Selig,
University of Illinois at Urbana-Champaign), in Selig format. The seed's part also has a
cut-out at the leading edge for a spar; that is not modelled here.

Coordinate formats
------------------
*Selig*: a name line, then ``x y`` rows (chord fractions) from the trailing edge over the
upper surface to the leading edge and back along the lower surface to the trailing edge.
*Lednicer*: a name line, a line with the point counts of the upper and lower surfaces
(e.g. ``61. 61.``), then the upper surface from the leading to the trailing edge and the
lower surface likewise; :func:`read_selig` detects it and reorders it to Selig order.

The outline
-----------
:func:`airfoil_path` interpolates the points with one cubic spline
(:class:`scipy.interpolate.CubicSpline`, not-a-knot ends) parameterised by cumulative chord
length, from the upper trailing edge through the leading edge to the lower trailing edge,
so the outline is C² everywhere (leading edge included) except at the trailing edge,
which is a corner, closed by a straight segment when the trailing edge has a thickness.
Each spline piece is a cubic, converted exactly to a
:class:`~microfab.geometry.segments.CurveSegment` through its Bézier control points.
"""

from __future__ import annotations

import functools
import os
import re
from importlib import resources

import numpy as np
from scipy.interpolate import CubicSpline

from microfab.core.validate import check_in_range
from microfab.geometry.layer import MAX_COORDINATE_M
from microfab.geometry.path import Path
from microfab.geometry.segments import CurveSegment, LineSegment, Segment

__all__ = ["BUILTIN_AIRFOILS", "X_TOL", "airfoil_knots", "airfoil_path", "read_selig"]

BUILTIN_AIRFOILS = ("e344",)
"""Airfoils shipped with the package (``data/airfoils/<name>.dat``)."""

X_TOL = 0.01
"""How far outside ``[0, 1]`` an x coordinate may lie, in chord fractions."""

_MIN_POINTS = 5
_SPLIT = re.compile(r"[\s,;]+")


def _row(line: str) -> list[float] | None:
    """The numbers of a line, or None if it is not all numbers."""
    toks = [t for t in _SPLIT.split(line.strip()) if t]
    try:
        return [float(t) for t in toks]
    except ValueError:
        return None


def _text_of(source: str | os.PathLike[str]) -> tuple[str, str]:
    """(text, where) of a file name or of coordinate text itself."""
    if isinstance(source, os.PathLike) or (
        isinstance(source, str) and "\n" not in source and os.path.isfile(source)
    ):
        fname = os.fspath(source)
        with open(fname, encoding="utf-8", errors="replace") as fh:
            return fh.read(), fname
    if isinstance(source, str):
        if "\n" not in source and source.strip():
            raise ValueError(
                f"airfoil coordinates: {source!r} is neither a file nor coordinate text "
                "(a name line followed by 'x y' rows)"
            )
        return source, "airfoil text"
    raise TypeError(f"expected a file name or coordinate text, got {type(source).__name__}")


def _check_points(P: np.ndarray, where: str) -> np.ndarray:
    if P.ndim != 2 or P.shape[1] != 2:
        raise ValueError(f"{where}: points must be an (n, 2) array of x, y, got shape {P.shape}")
    if P.shape[0] < _MIN_POINTS:
        raise ValueError(
            f"{where}: an airfoil needs at least {_MIN_POINTS} points, got {P.shape[0]}"
        )
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{where}: coordinates must be finite")
    x = P[:, 0]
    bad = np.nonzero((x < -X_TOL) | (x > 1.0 + X_TOL))[0]
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{where}: x = {x[i]:g} (point {i}) lies outside [0, 1] (chord fractions, "
            f"tolerance {X_TOL}); coordinates must be normalised by the chord"
        )
    y = P[:, 1]
    bad = np.nonzero(np.abs(y) > 1.0)[0]
    if bad.size:  # thicker than the chord is long: not an airfoil, or not normalised
        i = int(bad[0])
        raise ValueError(
            f"{where}: y = {y[i]:g} (point {i}) lies outside [-1, 1] (chord fractions); "
            "coordinates must be normalised by the chord"
        )
    return P


def read_selig(path_or_text: str | os.PathLike[str]) -> tuple[str, np.ndarray]:
    """Read airfoil coordinates in Selig or Lednicer format.

    Parameters
    ----------
    path_or_text : str or os.PathLike
        A file name, or the file's text itself (anything with a line break).

    Returns
    -------
    name : str
        The first line (empty if the file starts with numbers).
    points : numpy.ndarray
        Shape (n, 2), chord fractions, in Selig order: trailing edge → upper surface →
        leading edge → lower surface → trailing edge. A Lednicer file is reordered, and
        its leading-edge point, listed twice, is kept once.

    Raises
    ------
    ValueError
        If there are no coordinates, a row does not have exactly two numbers, a Lednicer
        count line does not match the rows, fewer than 5 points remain, a coordinate is
        not finite, an x lies outside ``[0, 1]`` by more than :data:`X_TOL`, or a y
        outside ``[-1, 1]``.
    """
    text, where = _text_of(path_or_text)
    lines = [(i + 1, ln.strip()) for i, ln in enumerate(text.splitlines()) if ln.strip()]
    if not lines:
        raise ValueError(f"{where}: empty; expected a name line and 'x y' rows")
    name = ""
    if _row(lines[0][1]) is None:
        name = lines[0][1]
        lines = lines[1:]
    if not lines:
        raise ValueError(f"{where}: no coordinates after the name line {name!r}")
    rows: list[list[float]] = []
    for lineno, ln in lines:
        r = _row(ln)
        if r is None:
            raise ValueError(f"{where}, line {lineno}: not numbers: {ln[:60]!r}")
        if len(r) != 2:
            raise ValueError(
                f"{where}, line {lineno}: expected two columns 'x y', got {len(r)}: {ln[:60]!r}"
            )
        rows.append(r)
    P = np.array(rows, dtype=float)
    first = P[0]
    if np.all(first > 1.0 + X_TOL) and np.all(first == np.round(first)) and first.max() < 1e9:
        nu, nl = int(first[0]), int(first[1])
        body = P[1:]
        if nu + nl != body.shape[0]:
            raise ValueError(
                f"{where}: Lednicer count line says {nu} upper + {nl} lower points, but "
                f"{body.shape[0]} rows follow"
            )
        upper, lower = body[:nu], body[nu:]
        if nu < 2 or nl < 2:
            raise ValueError(f"{where}: Lednicer surfaces need 2 points each, got {nu}, {nl}")
        if np.array_equal(upper[0], lower[0]):
            lower = lower[1:]
        P = np.vstack([upper[::-1], lower])
    return name, _check_points(P, where)


def _builtin(name: str) -> np.ndarray:
    return _builtin_read(name).copy()


@functools.lru_cache(maxsize=16)
def _builtin_read(name: str) -> np.ndarray:
    """A packaged airfoil's points, read once per process (`_builtin` hands out copies)."""
    res = resources.files("microfab.data").joinpath("airfoils", f"{name}.dat")
    return read_selig(res.read_text(encoding="utf-8"))[1]


def _points(points_or_name: str | np.ndarray, n_max: int | None) -> np.ndarray:
    if isinstance(points_or_name, str):
        key = points_or_name.strip().lower()
        if key in BUILTIN_AIRFOILS:
            P = _builtin(key)
        elif os.path.isfile(points_or_name):
            P = read_selig(points_or_name)[1]
        else:
            raise ValueError(
                f"unknown airfoil {points_or_name!r}: give one of {BUILTIN_AIRFOILS}, a "
                "coordinate file, or an (n, 2) array"
            )
    else:
        P = _check_points(np.array(points_or_name, dtype=float), "airfoil points")
    # drop repeated consecutive points (the spline parameter must increase)
    keep = np.concatenate([[True], np.any(np.diff(P, axis=0) != 0.0, axis=1)])
    P = P[keep]
    if n_max is not None:
        n_max = int(n_max)
        if n_max < _MIN_POINTS:
            raise ValueError(f"n_max must be at least {_MIN_POINTS} points, got {n_max}")
        if P.shape[0] > n_max:
            le = int(np.argmin(P[:, 0]))
            idx = np.round(np.linspace(0, P.shape[0] - 1, n_max - 1)).astype(int)
            P = P[np.unique(np.append(idx, le))]
    return _check_points(P, "airfoil points")


def _bezier_pieces(P: np.ndarray) -> np.ndarray:
    """Control points (n - 1, 4, 2) of the chord-length cubic spline through ``P``."""
    t = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(P, axis=0).T))])
    cs = CubicSpline(t, P, axis=0, bc_type="not-a-knot")
    h = np.diff(t)[:, None]
    # piece i: p(u) = a0 + a1 u + a2 u² + a3 u³, u = (t − t_i) / h_i ∈ [0, 1]
    a2, a1 = cs.c[1] * h**2, cs.c[2] * h
    a0 = P[:-1]
    # Bézier control points of a cubic in the power basis: b0 = a0, b1 = a0 + a1/3,
    # b2 = a0 + (2 a1 + a2)/3, b3 = a0 + a1 + a2 + a3, and b3 is the next data point
    # (exactly, rather than up to rounding), so the outline passes through every point
    return np.stack([a0, a0 + a1 / 3.0, a0 + (2.0 * a1 + a2) / 3.0, P[1:]], axis=1)


def _power(ctrl: np.ndarray) -> np.ndarray:
    """Power-basis coefficients (4, ...) of cubic Bézier control points (4, ...)."""
    b0, b1, b2, b3 = ctrl
    return np.stack([b0, 3 * (b1 - b0), 3 * (b2 - 2 * b1 + b0), b3 - 3 * b2 + 3 * b1 - b0])


def _extrema_x(ctrl: np.ndarray) -> tuple[tuple[float, int, float], tuple[float, int, float]]:
    """Exact (x, piece, u) of the smallest and the largest x of the spline."""
    best_lo = (np.inf, 0, 0.0)
    best_hi = (-np.inf, 0, 0.0)
    for i, c in enumerate(ctrl):
        a = _power(c[:, 0])
        cands = [0.0, 1.0]
        # x'(u) = a1 + 2 a2 u + 3 a3 u²
        for r in np.roots([3 * a[3], 2 * a[2], a[1]]) if np.any(a[1:] != 0) else []:
            if abs(r.imag) <= 1e-12 and 0.0 < r.real < 1.0:
                cands.append(float(r.real))
        for u in cands:
            x = float(((a[3] * u + a[2]) * u + a[1]) * u + a[0])
            if x < best_lo[0]:
                best_lo = (x, i, u)
            if x > best_hi[0]:
                best_hi = (x, i, u)
    return best_lo, best_hi


def _split_bezier(c: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
    """De Casteljau split of a cubic Bézier (4, 2) at ``u``: exact up to rounding."""
    p01, p12, p23 = (1 - u) * c[0] + u * c[1], (1 - u) * c[1] + u * c[2], (1 - u) * c[2] + u * c[3]
    p012, p123 = (1 - u) * p01 + u * p12, (1 - u) * p12 + u * p23
    m = (1 - u) * p012 + u * p123
    return np.array([c[0], p01, p012, m]), np.array([m, p123, p23, c[3]])


def _layout(
    points_or_name: str | np.ndarray, chord: float, n_max: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Scaled knots, scaled Bézier controls (split at the leading edge), transform, LE index.

    Returns ``(knots, ctrl, (k, x_le), i_le)`` where a data point ``p`` maps to
    ``k (p − (x_le, 0))`` and piece ``i_le`` of ``ctrl`` starts at the leading edge.
    """
    c = check_in_range("chord", chord, 0.0, MAX_COORDINATE_M, "m", low_closed=False)
    P = _points(points_or_name, n_max)
    ctrl = _bezier_pieces(P)
    (x_lo, i_lo, u_lo), (x_hi, _, _) = _extrema_x(ctrl)
    if not x_hi > x_lo:
        raise ValueError("airfoil points have no extent in x")
    k = c / (x_hi - x_lo)
    shift = np.array([x_lo, 0.0])
    pieces = list(ctrl)
    if 1e-9 < u_lo < 1.0 - 1e-9:
        left, right = _split_bezier(ctrl[i_lo], u_lo)
        pieces[i_lo : i_lo + 1] = [left, right]
        i_le = i_lo + 1
    else:
        i_le = i_lo + (1 if u_lo >= 0.5 else 0)
    scaled = k * (np.array(pieces) - shift)
    return k * (P - shift), scaled, np.array([k, x_lo]), i_le


def airfoil_knots(
    points_or_name: str | np.ndarray = "e344", *, chord: float = 0.1, n_max: int | None = None
) -> np.ndarray:
    """The points :func:`airfoil_path` interpolates, in metres, Selig order, shape (n, 2)."""
    return _layout(points_or_name, chord, n_max)[0]


def airfoil_path(
    points_or_name: str | np.ndarray = "e344",
    *,
    chord: float = 0.1,
    n_max: int | None = None,
    start: str = "trailing",
    direction: str = "ccw",
) -> Path:
    """Closed outline of an airfoil as exact cubic segments.

    Parameters
    ----------
    points_or_name : str or numpy.ndarray
        A built-in airfoil (:data:`BUILTIN_AIRFOILS`: ``"e344"``, seed 002 §II-C), a
        coordinate file (see :func:`read_selig`), or points (n, 2) in chord fractions in
        Selig order.
    chord : float
        Chord, m: the x extent of the outline, from the leading edge (the spline's point
        of smallest x) to the trailing edge (its largest x), computed exactly from the
        cubic pieces; at most `~microfab.geometry.layer.MAX_COORDINATE_M`.
    n_max : int, optional
        Use at most this many of the points (evenly by index, keeping both trailing-edge
        points and the point of smallest x); all by default.
    start : {"trailing", "leading"}
        Where the path starts: at the trailing edge (the end of the surface traversed
        first), or at the leading edge.
    direction : {"ccw", "cw"}
        Traversal direction. ``"ccw"`` runs from the trailing edge over the upper surface
        to the leading edge (Selig order). Seed 002 (Fig. 13) traverses its airfoil
        clockwise from the leading edge: ``start="leading", direction="cw"``.

    Returns
    -------
    Path
        Closed path. The leading edge is at x = 0, the trailing edge at x = ``chord``, y
        scaled with x (the chord line of a normalised file stays y = 0). The spline
        pieces are joined C² (the leading edge is a segment junction too); the trailing
        edge is a corner; a trailing edge of nonzero thickness is closed by a straight
        segment.

    Raises
    ------
    ValueError
        For an unknown name, bad points (see :func:`read_selig`), a chord not in
        ``(0, MAX_COORDINATE_M]``, ``n_max < 5``, or an unknown ``start`` / ``direction``.
    """
    if start not in ("trailing", "leading"):
        raise ValueError(f"start must be 'trailing' or 'leading', got {start!r}")
    if direction not in ("ccw", "cw"):
        raise ValueError(f"direction must be 'ccw' or 'cw', got {direction!r}")
    knots, ctrl, _, i_le = _layout(points_or_name, chord, n_max)
    chain: list[Segment] = [CurveSegment.from_bezier(c) for c in ctrl]
    # orientation: the sign of the knot polygon's area (shoelace) is that of the outline
    x, y = knots[:, 0], knots[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if (area > 0) != (direction == "ccw"):
        chain = [s.reversed() for s in reversed(chain)]
        i_le = len(chain) - i_le
    segs: list[Segment] = list(chain)
    gap = float(np.hypot(*(chain[-1].end - chain[0].start)))
    if gap > 1e-12 * float(chord):
        segs.append(LineSegment(chain[-1].end, chain[0].start))
    if start == "leading":
        segs = segs[i_le:] + segs[:i_le]
    return Path(tuple(segs), closed=True)
