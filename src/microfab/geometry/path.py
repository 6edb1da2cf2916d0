"""`Path`: an arc-length-parameterised planar contour made of exact segments.

A path is a chain of :mod:`~microfab.geometry.segments` joined end to start, open or
closed. Everything is a function of the arc length ``s ∈ [0, length]`` (m): position,
unit tangent, left normal, signed curvature, and the derivatives ``d^k q / ds^k`` up to
the third, evaluated for many ``s`` at once. Segments of one kind are packed into arrays
so that evaluation is vectorised however many segments a drawing has.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.polynomial import chebyshev as cheb

from microfab.core.validate import check_positive
from microfab.geometry.path_curves import _clenshaw as _clenshaw
from microfab.geometry.path_curves import _CurveGroup, _shifted_segment
from microfab.geometry.segments import (
    GL_W,
    GL_X,
    N_PANELS,
    ArcSegment,
    CurveSegment,
    LineSegment,
    Segment,
    cheb_fit2,
    segment_bbox,
)

__all__ = ["MAX_FLATTEN", "Path"]

#: Most vertices `Path.flatten` gives one segment.
MAX_FLATTEN = 4096

_LINE, _ARC, _CURVE = 0, 1, 2
_CHUNK = 8192


@dataclass(frozen=True, eq=False)
class Path:
    """A planar contour: segments joined end to start, parameterised by arc length.

    Parameters
    ----------
    segments : sequence of Segment
        Consecutive segments; each must start where the previous one ends (within
        ``gap_tol``). Zero-length segments are dropped.
    closed : bool
        Whether the contour is closed; the last segment must then end at the first one's
        start (within ``gap_tol``).
    gap_tol : float
        Largest allowed gap between consecutive segments, m; ``None`` uses 1e-9 of the
        path's size (plus 1e-12 m).

    Raises
    ------
    ValueError
        If the path is empty, has a gap, or is closed but does not close.
    """

    segments: tuple[Segment, ...]
    closed: bool = False
    gap_tol: float | None = None

    def __post_init__(self) -> None:
        segs = tuple(s for s in self.segments if s.length > 0)
        if not segs:
            raise ValueError("a path needs at least one segment of nonzero length")
        for s in segs:
            if not isinstance(s, LineSegment | ArcSegment | CurveSegment):
                raise TypeError(f"not a segment: {s!r}")
        starts = np.array([s.start for s in segs])
        ends = np.array([s.end for s in segs])
        pts = np.vstack([starts, ends])
        size = float(np.max(np.ptp(pts, axis=0)))
        tol = self.gap_tol if self.gap_tol is not None else 1e-9 * size + 1e-12
        gaps = np.hypot(*(starts[1:] - ends[:-1]).T) if len(segs) > 1 else np.zeros(0)
        if gaps.size and gaps.max() > tol:
            i = int(np.argmax(gaps > tol))
            raise ValueError(
                f"segment {i + 1} starts {gaps[i]:.3g} m away from the end of segment {i} "
                f"(tolerance {tol:.3g} m); chain the segments first"
            )
        if self.closed:
            gap = float(np.hypot(*(starts[0] - ends[-1])))
            if gap > tol:
                raise ValueError(
                    f"closed path does not close: the end is {gap:.3g} m from the start "
                    f"(tolerance {tol:.3g} m)"
                )
        object.__setattr__(self, "segments", segs)
        object.__setattr__(self, "gap_tol", tol)

    # ----------------------------------------------------------------- construction
    @classmethod
    def _checked(
        cls,
        segments: tuple[Segment, ...],
        closed: bool,
        gap_tol: float,
        breaks: np.ndarray | None = None,
    ) -> Path:
        """The path `Path(segments, closed, gap_tol)` makes, for a caller that has checked it.

        For builders of many paths (:func:`~microfab.geometry.chain.chain_segments`) that
        check all their chains at once: every segment is a `LineSegment`, `ArcSegment`
        or `CurveSegment` of nonzero length, and the gaps are within ``gap_tol``. The
        caller may pass the `breaks` too, read-only, as `breaks` computes them (to the
        bit: 0, then the running sum of the segments' lengths in order).
        """
        path = object.__new__(cls)
        attrs = path.__dict__  # frozen: set the fields as __init__ would
        attrs["segments"] = segments
        attrs["closed"] = closed
        attrs["gap_tol"] = gap_tol
        if breaks is not None:
            attrs["breaks"] = breaks  # the cached property's value
        return path

    @classmethod
    def polyline(cls, points: object, closed: bool = False) -> Path:
        """Straight segments through ``points`` (n, 2), m; repeated points are skipped."""
        P = np.asarray(points, dtype=float)
        if P.ndim != 2 or P.shape[1] != 2 or P.shape[0] < 2 or not np.all(np.isfinite(P)):
            raise ValueError(f"points must be a finite (n >= 2, 2) array, got shape {P.shape}")
        if closed and np.allclose(P[0], P[-1], rtol=0, atol=0):
            P = P[:-1]
        Q = np.vstack([P, P[:1]]) if closed else P
        segs = [LineSegment(a, b) for a, b in itertools.pairwise(Q) if np.any(a != b)]
        return cls(tuple(segs), closed=closed)

    # ----------------------------------------------------------------- basic facts
    @cached_property
    def breaks(self) -> np.ndarray:
        """Arc length at the start of each segment and at the end, shape (n_seg + 1,), m."""
        b = np.concatenate([[0.0], np.cumsum([s.length for s in self.segments])])
        b.setflags(write=False)
        return b

    @property
    def length(self) -> float:
        """Total arc length, m."""
        return float(self.breaks[-1])

    @property
    def start(self) -> np.ndarray:
        """Start point, m."""
        return self.segments[0].start

    @property
    def end(self) -> np.ndarray:
        """End point, m."""
        return self.segments[-1].end

    def __len__(self) -> int:
        return len(self.segments)

    # ----------------------------------------------------------------- evaluation
    @cached_property
    def _packed(self) -> dict[str, object]:
        kinds = np.empty(len(self.segments), dtype=np.int8)
        local = np.empty(len(self.segments), dtype=np.int64)
        lines: list[LineSegment] = []
        arcs: list[ArcSegment] = []
        by_deg: dict[int, list[int]] = {}
        curves: list[CurveSegment] = []
        for i, s in enumerate(self.segments):
            if isinstance(s, LineSegment):
                kinds[i], local[i] = _LINE, len(lines)
                lines.append(s)
            elif isinstance(s, ArcSegment):
                kinds[i], local[i] = _ARC, len(arcs)
                arcs.append(s)
            else:
                kinds[i], local[i] = _CURVE, len(curves)
                curves.append(s)
                by_deg.setdefault(s.degree, []).append(len(curves) - 1)
        packed: dict[str, object] = {"kinds": kinds, "local": local}
        if lines:
            p0 = np.array([s.p0 for s in lines])
            p1 = np.array([s.p1 for s in lines])
            L = np.array([s.length for s in lines])
            packed["line"] = (p0, (p1 - p0) / L[:, None])
        if arcs:
            packed["arc"] = (
                np.array([s.center for s in arcs]),
                np.array([s.radius for s in arcs]),
                np.array([s.theta0 for s in arcs]),
                np.sign([s.sweep for s in arcs]),
            )
        if curves:
            group_of = np.empty(len(curves), dtype=np.int64)
            row_of = np.empty(len(curves), dtype=np.int64)
            groups = []
            for g, (_, idx) in enumerate(sorted(by_deg.items())):
                groups.append(_CurveGroup([curves[i] for i in idx]))
                group_of[idx] = g
                row_of[idx] = np.arange(len(idx))
            packed["curve"] = (groups, group_of, row_of)
        return packed

    def _eval_local(self, seg: np.ndarray, sigma: np.ndarray, order: int) -> list[np.ndarray]:
        n = seg.size
        out = [np.zeros((n, 2)) for _ in range(order + 1)]
        pk = self._packed
        kinds = pk["kinds"][seg]  # type: ignore[index]
        loc = pk["local"][seg]  # type: ignore[index]
        m = kinds == _LINE
        if np.any(m):
            p0, t = pk["line"]  # type: ignore[misc]
            i = loc[m]
            out[0][m] = p0[i] + sigma[m, None] * t[i]
            if order >= 1:
                out[1][m] = t[i]
        m = kinds == _ARC
        if np.any(m):
            c, r, th0, sg = pk["arc"]  # type: ignore[misc]
            i = loc[m]
            th = th0[i] + sg[i] * sigma[m] / r[i]
            cs = np.column_stack([np.cos(th), np.sin(th)])
            perp = np.column_stack([-np.sin(th), np.cos(th)])
            out[0][m] = c[i] + r[i, None] * cs
            if order >= 1:
                out[1][m] = sg[i, None] * perp
            if order >= 2:
                out[2][m] = -cs / r[i, None]
            if order >= 3:
                out[3][m] = -(sg[i] / r[i] ** 2)[:, None] * perp
        m = kinds == _CURVE
        if np.any(m):
            groups, group_of, row_of = pk["curve"]  # type: ignore[misc]
            where = np.nonzero(m)[0]
            g_of_q = group_of[loc[m]]
            for g, grp in enumerate(groups):
                sel = where[g_of_q == g]
                for lo in range(0, sel.size, _CHUNK):
                    q = sel[lo : lo + _CHUNK]
                    res = grp.derivs(row_of[loc[q]], sigma[q], order)
                    for k in range(order + 1):
                        out[k][q] = res[k]
        return out

    def locate(self, s: object) -> tuple[np.ndarray, np.ndarray]:
        """Segment index and local arc length for each ``s`` (wrapped if closed, else clipped)."""
        sv = np.asarray(s, dtype=float).reshape(-1)
        if not np.all(np.isfinite(sv)):
            raise ValueError("arc length s must be finite")
        L = self.length
        sv = np.mod(sv, L) if self.closed else np.clip(sv, 0.0, L)
        seg = np.clip(np.searchsorted(self.breaks, sv, side="right") - 1, 0, len(self.segments) - 1)
        sigma = np.clip(sv - self.breaks[seg], 0.0, None)
        return seg, sigma

    def evaluate(self, s: object, order: int = 0) -> list[np.ndarray]:
        """Position and arc-length derivatives at ``s``.

        Parameters
        ----------
        s : array_like
            Arc lengths, m. Wrapped into ``[0, length)`` for a closed path, clipped to
            ``[0, length]`` for an open one. At a segment junction the later segment is
            used.
        order : int
            Highest derivative, 0 to 3.

        Returns
        -------
        list of numpy.ndarray
            ``[q, dq/ds, d²q/ds², d³q/ds³][: order + 1]``, each shape (n, 2): m, 1, 1/m,
            1/m².
        """
        if order not in (0, 1, 2, 3):
            raise ValueError(f"order must be 0, 1, 2 or 3, got {order}")
        seg, sigma = self.locate(s)
        return self._eval_local(seg, sigma, order)

    def point(self, s: object) -> np.ndarray:
        """Positions at ``s``, shape (n, 2), m."""
        return self.evaluate(s, 0)[0]

    def tangent(self, s: object) -> np.ndarray:
        """Unit tangents at ``s``, shape (n, 2)."""
        return self.evaluate(s, 1)[1]

    def normal(self, s: object) -> np.ndarray:
        """Unit left normals (tangent turned +90°) at ``s``, shape (n, 2)."""
        t = self.tangent(s)
        return np.column_stack([-t[:, 1], t[:, 0]])

    def curvature(self, s: object) -> np.ndarray:
        """Signed curvature at ``s`` (positive turning left), 1/m."""
        _, d1, d2 = self.evaluate(s, 2)
        return d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]

    # ----------------------------------------------------------------- structure
    def _end_tangents(self) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.segments)
        idx = np.arange(n)
        t_start = self._eval_local(idx, np.zeros(n), 1)[1]
        t_end = self._eval_local(idx, np.array([s.length for s in self.segments]), 1)[1]
        return t_start, t_end

    def junctions(self) -> np.ndarray:
        """Arc length of every segment junction inside the path, m (curvature may jump)."""
        out = self.breaks[1:-1]
        if self.closed and len(self.segments) > 1:
            out = np.concatenate([[0.0], out])
        return np.array(out)

    def corners(self, angle_tol: float = 1e-3) -> np.ndarray:
        """Arc length of the junctions where the tangent turns by more than ``angle_tol`` rad.

        For a closed path, ``s = 0`` is included when the closing junction is a corner.
        """
        t_start, t_end = self._end_tangents()
        n = len(self.segments)
        a = np.arange(n - 1 + int(self.closed))
        b = (a + 1) % n  # the closing junction pairs the last segment with the first
        cosang = np.clip(np.einsum("ij,ij->i", t_end[a], t_start[b]), -1.0, 1.0)
        turned = b[np.arccos(cosang) > angle_tol]
        return np.sort(np.where(turned == 0, 0.0, self.breaks[turned]))

    # ----------------------------------------------------------------- sampling
    def resample(self, n: int | None = None, ds: float | None = None) -> np.ndarray:
        """Points equally spaced in arc length, shape (n, 2), m.

        Give either ``n`` (number of points, ends included for an open path; for a
        closed path the start is not repeated) or ``ds`` (spacing, m).
        """
        if (n is None) == (ds is None):
            raise ValueError("give exactly one of n or ds")
        if ds is not None:
            check_positive("ds", ds, "m")
            n = max(int(np.ceil(self.length / ds)) + (0 if self.closed else 1), 2)
        assert n is not None
        if n < 2:
            raise ValueError(f"n must be at least 2, got {n}")
        s = np.arange(n) * self.length / n if self.closed else np.linspace(0.0, self.length, n)
        return self.point(s)

    def flatten(self, tol: float | None = None) -> np.ndarray:
        """A polyline within ``tol`` (m) of the path, with every segment end as a vertex.

        Parameters
        ----------
        tol : float, optional
            Largest chord deviation, m; 1e-4 of the path's size by default.

        Returns
        -------
        numpy.ndarray
            Vertices, shape (n, 2); for a closed path the first vertex is repeated last.

        Notes
        -----
        Lines and arcs are sampled evenly in arc length; polynomial curves evenly in their
        own parameter, with a step from the largest ``|f''(u)|``, so a cusp (a Bézier
        curve that stops and turns back) needs no special case. A segment gets at most
        `MAX_FLATTEN` vertices; a curve that would need more deviates by more than ``tol``.
        """
        if tol is None:
            return self._flat.copy()
        return self._flatten(tol)

    @cached_property
    def _flat(self) -> np.ndarray:
        """`flatten` at its default tolerance, computed once (read-only)."""
        tol = 1e-4 * max(float(np.max(np.ptp(self._coarse, axis=0))), 1e-12)
        flat = self._flatten(tol)
        flat.setflags(write=False)
        return flat

    def _flatten(self, tol: float) -> np.ndarray:
        """`flatten` at tolerance ``tol``, m."""
        check_positive("tol", tol, "m")
        counts = np.ones(len(self.segments), dtype=np.int64)
        for i, seg in enumerate(self.segments):
            if isinstance(seg, ArcSegment):
                step = 2.0 * np.sqrt(max(2.0 * tol * seg.radius - tol * tol, 1e-300))
                n_arc = np.ceil(seg.length / min(step, 2 * seg.radius))
                counts[i] = max(int(min(n_arc, MAX_FLATTEN)), 2)
            elif isinstance(seg, CurveSegment):
                # sampled evenly in the curve's own parameter u: a chord of Δu deviates
                # by at most max|f''(u)| Δu² / 8 (no arc-length inversion needed)
                d2 = seg.derivative_coefs[1]
                with np.errstate(over="ignore", invalid="ignore"):
                    x = np.linspace(-1.0, 1.0, 33)
                    probe = np.hypot(cheb.chebval(x, d2[:, 0]), cheb.chebval(x, d2[:, 1]))
                    kmax = float(np.max(probe))
                du = np.sqrt(8.0 * tol / kmax) if kmax > 0 else 1.0
                n = np.ceil(1.25 / du) if np.isfinite(du) and du > 0 else MAX_FLATTEN
                counts[i] = max(int(min(n, MAX_FLATTEN)), 2)
        seg_idx = np.repeat(np.arange(len(self.segments)), counts)
        frac = np.concatenate([np.arange(c) / c for c in counts])
        lengths = np.array([s.length for s in self.segments])
        is_curve = np.array([isinstance(s, CurveSegment) for s in self.segments])
        rows = ~is_curve[seg_idx]
        pts = np.empty((seg_idx.size, 2))
        if np.any(rows):
            pts[rows] = self._eval_local(seg_idx[rows], frac[rows] * lengths[seg_idx[rows]], 0)[0]
        start = np.concatenate([[0], np.cumsum(counts)])
        for i in np.flatnonzero(is_curve):
            seg = self.segments[i]
            assert isinstance(seg, CurveSegment)
            pts[start[i] : start[i + 1]] = seg.point(frac[start[i] : start[i + 1]])
        return np.vstack([pts, self.end[None, :] if not self.closed else pts[:1]])

    @cached_property
    def first_midpoint(self) -> np.ndarray:
        """The point half-way along the first segment, shape (2,), m (read-only).

        Away from the vertices that contours may share: :attr:`Layer.containers
        <microfab.geometry.layer.Layer.containers>` asks which contours contain it.
        """
        p = self.point([0.5 * self.segments[0].length])[0]
        p.setflags(write=False)
        return p

    @cached_property
    def _coarse(self) -> np.ndarray:
        pts = [s.start for s in self.segments] + [self.end]
        return np.vstack([np.array(pts), self.resample(n=min(64 * len(self.segments), 4096))])

    @cached_property
    def bbox(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)``, m: exact, from each segment's extremes."""
        b = np.array([segment_bbox(seg) for seg in self.segments])
        return (
            float(b[:, 0].min()),
            float(b[:, 1].min()),
            float(b[:, 2].max()),
            float(b[:, 3].max()),
        )

    @cached_property
    def signed_area(self) -> float:
        """Signed enclosed area (positive counter-clockwise), m²; 0 for an open path.

        Green's theorem ``½∮(x dy − y dx)`` by Gauss–Legendre quadrature per segment.
        """
        if not self.closed:
            return 0.0
        n = len(self.segments)
        lengths = np.array([s.length for s in self.segments])
        # 16 panels x 10 Gauss nodes per segment, as for the curves' length tables
        panels = N_PANELS
        frac = (np.arange(panels)[:, None] + (GL_X[None, :] + 1.0) / 2.0).ravel() / panels
        w = np.tile(GL_W, panels) / (2.0 * panels)
        seg = np.repeat(np.arange(n), frac.size)
        sig = np.tile(frac, n) * lengths[seg]
        q, d1 = self._eval_local(seg, sig, 1)
        integrand = q[:, 0] * d1[:, 1] - q[:, 1] * d1[:, 0]
        return float(0.5 * np.sum(integrand * np.tile(w, n) * lengths[seg]))

    @property
    def orientation(self) -> str:
        """``"ccw"``, ``"cw"`` (closed paths) or ``"open"``."""
        if not self.closed:
            return "open"
        return "ccw" if self.signed_area > 0 else "cw"

    # ----------------------------------------------------------------- transforms
    def reversed(self) -> Path:
        """The same contour traversed backwards."""
        return Path(
            tuple(s.reversed() for s in reversed(self.segments)),
            closed=self.closed,
            gap_tol=self.gap_tol,
        )

    def _shifted(self, d: np.ndarray) -> Path:
        """The path moved by ``d`` (m), keeping what it has computed, for many copies.

        For builders that place one contour many times (the glyphs of a text): the
        segments move as :meth:`translated` moves them (end points, centre or constant
        coefficient plus ``d``), without the checks; a curve keeps its derivative and
        arc-length tables, which a translation leaves unchanged to the bit. Of the path's
        own cached results, the box, the default polyline (`flatten`) and the sample
        points it is sized from, and `first_midpoint` are moved by ``d``, and the signed
        area is kept: the same as recomputing them, up to rounding, for none of the work.

        Parameters
        ----------
        d : numpy.ndarray
            Shift, shape (2,), m, finite.
        """
        shift = np.asarray(d, dtype=float).reshape(2)
        path = Path._checked(
            tuple(_shifted_segment(s, shift) for s in self.segments), self.closed, self.gap_tol
        )
        have, attrs = self.__dict__, path.__dict__
        for name in ("_coarse", "_flat", "first_midpoint"):
            if name in have:
                moved = have[name] + shift
                moved.setflags(write=False)
                attrs[name] = moved
        if "bbox" in have:
            x0, y0, x1, y1 = have["bbox"]
            dx, dy = float(shift[0]), float(shift[1])
            attrs["bbox"] = (x0 + dx, y0 + dy, x1 + dx, y1 + dy)
        if "signed_area" in have:
            attrs["signed_area"] = have["signed_area"]
        return path

    def transformed(self, A: object, b: object = (0.0, 0.0)) -> Path:
        """Image under ``p -> A p + b`` (A shape (2, 2), b in m)."""
        segs: list[Segment] = []
        for s in self.segments:
            if isinstance(s, ArcSegment):
                segs.extend(s.transformed_pieces(A, b))
            else:
                segs.append(s.transformed(A, b))
        # gaps scale with the transform: allow its largest stretch
        stretch = float(np.linalg.norm(np.asarray(A, dtype=float).reshape(2, 2), 2))
        tol = None if self.gap_tol is None else self.gap_tol * max(stretch, 1.0)
        return Path(tuple(segs), closed=self.closed, gap_tol=tol)

    def scaled(self, k: float, origin: object = (0.0, 0.0)) -> Path:
        """Uniformly scaled by ``k`` about ``origin``."""
        o = np.asarray(origin, dtype=float)
        return self.transformed(k * np.eye(2), o - k * o)

    def translated(self, d: object) -> Path:
        """Shifted by ``d`` (m)."""
        return self.transformed(np.eye(2), d)

    def rotated(self, angle: float, origin: object = (0.0, 0.0)) -> Path:
        """Rotated by ``angle`` rad counter-clockwise about ``origin``."""
        c, s = np.cos(angle), np.sin(angle)
        R = np.array([[c, -s], [s, c]])
        o = np.asarray(origin, dtype=float)
        return self.transformed(R, o - R @ o)

    def with_start(self, s0: float) -> Path:
        """A closed path re-started at arc length ``s0`` (the segment there is split)."""
        if not self.closed:
            raise ValueError("only a closed path can be re-started")
        seg, sigma = self.locate([s0])
        i, sg = int(seg[0]), float(sigma[0])
        head, tail = _split(self.segments[i], sg)
        segs = [*([tail] if tail else []), *self.segments[i + 1 :], *self.segments[:i]]
        segs += [head] if head else []
        return Path(tuple(segs), closed=True, gap_tol=self.gap_tol)

    def summary(self) -> dict[str, object]:
        """Length, bbox, closure and point count, for printing or JSON."""
        return {
            "closed": self.closed,
            "length_m": self.length,
            "bbox_m": list(self.bbox),
            "n_points": int(self.flatten().shape[0]),
            "n_segments": len(self.segments),
        }


def _split(seg: Segment, sigma: float) -> tuple[Segment | None, Segment | None]:
    """Split a segment at local arc length sigma into (head, tail); None where empty."""
    L = seg.length
    if sigma <= 1e-15 * L:
        return None, seg
    if sigma >= L * (1 - 1e-15):
        return seg, None
    if isinstance(seg, LineSegment):
        m = seg.p0 + (seg.p1 - seg.p0) * (sigma / L)
        return LineSegment(seg.p0, m), LineSegment(m, seg.p1)
    if isinstance(seg, ArcSegment):
        a = np.sign(seg.sweep) * sigma / seg.radius
        return (
            ArcSegment(seg.center, seg.radius, seg.theta0, a),
            ArcSegment(seg.center, seg.radius, seg.theta0 + a, seg.sweep - a),
        )
    tmp = Path((seg,))
    u = tmp._packed["curve"][0][0].u_of_sigma(np.array([0]), np.array([sigma]))[0]  # type: ignore[index]

    def piece(a: float, b: float) -> CurveSegment:
        n = seg.degree
        x = np.cos(np.pi * (np.arange(n + 1) + 0.5) / (n + 1))
        vals = seg.point(a + (b - a) * (x + 1) / 2)
        return CurveSegment(cheb_fit2(x, vals, n))

    return piece(0.0, float(u)), piece(float(u), 1.0)


def concatenate(paths: Iterable[Path], closed: bool = False) -> Path:
    """Join paths end to start into one path."""
    segs: list[Segment] = []
    tols: list[float] = []
    for p in paths:
        segs.extend(p.segments)
        tols.append(p.gap_tol or 0.0)
    return Path(tuple(segs), closed=closed, gap_tol=max(tols) or None)
