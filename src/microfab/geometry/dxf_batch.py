"""Segments of a DXF drawing held as numbers while it is read, and made in one go.

A large drawing is mostly LINEs and polyline edges, and making each segment as its entity
is read costs as much as reading the entity. :class:`SegmentBatch` keeps instead their end
points (and a polyline edge's bulge) as plain numbers, in drawing order, and
:meth:`SegmentBatch.finish` makes all the segments at the end with array operations: the
same operations, element by element, as the one-at-a-time constructors, hence the same
segments to the bit (:meth:`~microfab.geometry.segments.LineSegment.many`,
:func:`~microfab.geometry.segments.bulge_arc_numbers`).

Whether a bulged polyline lies within the drawing bounds is only known with its arcs, at
the end: until then it is *pending*. A pending polyline whose arcs turn out invalid or too
far is made again one segment at a time, as the reader makes the other entities, and
refused with the reason the reader would give, its skip record put where the reader would
have put it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from microfab.geometry.chain import segment_endpoints
from microfab.geometry.layer import MAX_COORDINATE_M, Skipped
from microfab.geometry.segments import (
    ArcSegment,
    CurveSegment,
    LineSegment,
    Segment,
    bulge_arc_numbers,
    segment_reach,
)

__all__ = ["ARC", "LINE_BULGE", "SegmentBatch", "beyond_reason", "extent"]


class _ArcSlot:
    """The place of a bulged polyline edge's arc in `SegmentBatch.slots`."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "ARC"


#: Placeholder in `SegmentBatch.slots` for an arc held as numbers (a line's is None).
ARC = _ArcSlot()

#: A polyline edge whose |bulge| is at most this is straight: its sagitta is below 1e-12 of
#: its chord (assumed: far below a drawing's precision).
LINE_BULGE = 1e-12


def beyond_reason(reach: float) -> str:
    """Why an entity whose segments reach ``reach`` (m) beyond `MAX_COORDINATE_M` is skipped."""
    what = f"{reach:.3g} m" if math.isfinite(reach) else "non-finite coordinates"
    return (
        f"invalid geometry: reaches {what}, beyond ±{MAX_COORDINATE_M:g} m "
        "(a corrupt value, or the wrong units?)"
    )


@dataclass(frozen=True, kw_only=True)
class _Pending:
    """A bulged polyline waiting for its arcs: its skip record's place, its slots and rows."""

    skip_at: int  # where its skip record goes in the reader's list
    kind: str
    ref: str
    slots: tuple[int, int]  # its placeholders in `SegmentBatch.slots`
    lines: tuple[int, int]  # its rows of `SegmentBatch.lines` (4 numbers each)
    arcs: tuple[int, int]  # its rows of `SegmentBatch.arcs` (5 numbers each)


class SegmentBatch:
    """A drawing's segments in drawing order, the lines and bulged edges as numbers.

    Attributes
    ----------
    slots : list
        The segments; None where a line is held in `lines`, `ARC` where an arc is held
        in `arcs` (both in the order of their slots).
    lines : list of float
        ``x0, y0, x1, y1`` (m) of each line, finite and within ``±MAX_COORDINATE_M``.
    arcs : list of float
        ``x0, y0, x1, y1`` (m, finite and within ``±MAX_COORDINATE_M``) and the bulge of
        each bulged edge.
    """

    def __init__(self) -> None:
        self.slots: list[Segment | _ArcSlot | None] = []
        self.lines: list[float] = []
        self.arcs: list[float] = []
        self._pending: list[_Pending] = []

    def mark(self) -> tuple[int, int, int]:
        """Numbers of slots, lines and arcs so far: where the next entity's start."""
        return len(self.slots), len(self.lines) // 4, len(self.arcs) // 5

    def wait(self, mark: tuple[int, int, int], skip_at: int, kind: str, ref: str) -> None:
        """Hold the entity added since `mark` until `finish` knows its arcs.

        ``skip_at`` is where its skip record goes in the reader's list if it is refused.
        """
        s0, l0, a0 = mark
        s1, l1, a1 = self.mark()
        self._pending.append(
            _Pending(
                skip_at=skip_at, kind=kind, ref=ref, slots=(s0, s1), lines=(l0, l1), arcs=(a0, a1)
            )
        )

    def add_polyline(
        self, xy: Sequence[tuple[float, float]], bulges: Sequence[float], closed: bool, k: float
    ) -> bool | None:
        """Hold a polyline's edges: lines, and arcs where ``|bulge| > LINE_BULGE``.

        Parameters
        ----------
        xy : sequence of (float, float)
            The vertices, drawing units; edges between coinciding vertices are dropped.
        bulges : sequence of float
            Each vertex's bulge (of the edge it starts).
        closed : bool
            Whether an edge joins the last vertex to the first.
        k : float
            Metres per drawing unit.

        Returns
        -------
        bool or None
            Whether arcs are held (the polyline must then `wait`); None when nothing is
            held: a vertex is not finite or lies beyond ``±MAX_COORDINATE_M``, or there
            is no edge (the caller makes the segments, to be refused).
        """
        limit, n = MAX_COORDINATE_M, len(xy)
        pts = [(x * k, y * k) for x, y in xy]
        if not all(abs(x) <= limit and abs(y) <= limit for x, y in pts):  # or not finite
            return None
        slots, lines, arcs = self.slots, self.lines, self.arcs
        n_slots = len(slots)
        with_arcs = False
        for i in range(n if closed else n - 1):
            j = i + 1 if i + 1 < n else 0
            (x0, y0), (x1, y1) = xy[i], xy[j]
            if x0 == x1 and y0 == y1:
                continue
            b = bulges[i]
            if abs(b) <= LINE_BULGE:
                lines += (*pts[i], *pts[j])
                slots.append(None)
            else:
                arcs += (*pts[i], *pts[j], b)
                slots.append(ARC)
                with_arcs = True
        return with_arcs if len(slots) > n_slots else None

    def finish(
        self, skipped: list[Skipped]
    ) -> tuple[list[Segment], np.ndarray, np.ndarray, list[Segment]]:
        """Make the segments, and settle the pending entities.

        Parameters
        ----------
        skipped : list of Skipped
            The reader's skip records; those of refused pending entities are inserted.

        Returns
        -------
        segments : list of Segment
            In drawing order.
        starts, ends : numpy.ndarray
            Their end points (those of `segment_endpoints`), shape (n, 2), m.
        others : list of Segment
            The segments that are not lines held as numbers (arcs, curves, ...).
        """
        lines = np.array(self.lines, dtype=float).reshape(-1, 4)
        rows = np.array(self.arcs, dtype=float).reshape(-1, 5)
        center, radius, theta0, sweep, ok = bulge_arc_numbers(rows[:, :2], rows[:, 2:4], rows[:, 4])
        with np.errstate(over="ignore", invalid="ignore"):
            # each arc's reach, as `segment_reach` gives it wherever it is within the bounds
            reach = np.maximum(np.abs(center[:, 0]), np.abs(center[:, 1])) + radius
        good = ok & (reach <= MAX_COORDINATE_M)
        slots = self.slots
        if not good.all():
            keep_lines = np.ones(lines.shape[0], dtype=bool)
            keep_arcs = np.ones(rows.shape[0], dtype=bool)
            first = np.array([p.arcs[0] for p in self._pending], dtype=np.int64)
            redo = np.unique(np.searchsorted(first, np.flatnonzero(~good), side="right") - 1)
            refused: list[tuple[int, Skipped]] = []
            slots = list(slots)
            for k in redo[::-1].tolist():  # from the last: earlier slots keep their places
                p = self._pending[int(k)]
                made = self._remake(p, lines, rows)
                keep_lines[p.lines[0] : p.lines[1]] = False
                keep_arcs[p.arcs[0] : p.arcs[1]] = False
                if isinstance(made, str):
                    del slots[p.slots[0] : p.slots[1]]
                    refused.append((p.skip_at, Skipped(p.kind, made, p.ref)))
                else:  # valid after all: its segments as made one by one
                    slots[p.slots[0] : p.slots[1]] = made
            for at, record in refused:  # from the last, so earlier places stay valid
                skipped.insert(at, record)
            lines, rows = lines[keep_lines], rows[keep_arcs]
            center, radius = center[keep_arcs], radius[keep_arcs]
            theta0, sweep = theta0[keep_arcs], sweep[keep_arcs]
        made_lines = iter(LineSegment.many(lines))
        made_arcs = iter(ArcSegment._many_checked(center, radius, theta0, sweep))
        is_line = np.array([s is None for s in slots], dtype=bool)
        segs: list[Segment] = [
            next(made_lines) if s is None else next(made_arcs) if s is ARC else s  # type: ignore[misc]
            for s in slots
        ]
        starts, ends = np.empty((len(segs), 2)), np.empty((len(segs), 2))
        starts[is_line], ends[is_line] = lines[:, :2], lines[:, 2:]
        where = np.flatnonzero(~is_line).tolist()
        others = [segs[i] for i in where]
        if others:
            starts[where], ends[where] = segment_endpoints(others)
        return segs, starts, ends, others

    def _remake(self, p: _Pending, lines: np.ndarray, rows: np.ndarray) -> list[Segment] | str:
        """A pending entity's segments made one by one as the reader makes them, or why not.

        The reader makes a polyline's edges in order, and refuses it at the first arc that
        raises, or when a segment reaches beyond `MAX_COORDINATE_M`.
        """
        line_rows = iter(lines[p.lines[0] : p.lines[1]].tolist())
        arc_rows = iter(rows[p.arcs[0] : p.arcs[1]].tolist())
        segs: list[Segment] = []
        for slot in self.slots[p.slots[0] : p.slots[1]]:
            if slot is None:
                x0, y0, x1, y1 = next(line_rows)
                segs.append(LineSegment((x0, y0), (x1, y1)))
                continue
            x0, y0, x1, y1, bulge = next(arc_rows)
            try:
                segs.append(ArcSegment._from_bulge(x0, y0, x1, y1, bulge))
            except (ValueError, ArithmeticError) as exc:  # as the reader reports them
                return f"invalid geometry: {exc}"
        reach = max(map(segment_reach, segs), default=0.0)
        if not reach <= MAX_COORDINATE_M:
            return beyond_reason(reach)
        return segs


def extent(others: Sequence[Segment], starts: np.ndarray, ends: np.ndarray) -> float:
    """Largest side of a box around the segments' end points and arcs' circles, m.

    Parameters
    ----------
    others : sequence of Segment
        The segments other than lines (a line adds no more than its ends).
    starts, ends : numpy.ndarray
        All the segments' end points, shape (n, 2), m.
    """
    pts = [starts, ends]
    arcs = [s for s in others if isinstance(s, ArcSegment)]
    if arcs:
        c = np.array([s.center for s in arcs])
        r = np.array([s.radius for s in arcs])[:, None]
        pts += [c - r, c + r]
    curves = [s for s in others if isinstance(s, CurveSegment)]
    if curves:
        pts.append(np.array([s.point(np.array([0.5]))[0] for s in curves]))
    allp = np.vstack(pts)
    return float(np.max(np.ptp(allp, axis=0)))
