"""`Layer`: the contours of one drawing or slice, with outer boundaries and holes."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from microfab.geometry import nesting
from microfab.geometry.path import Path
from microfab.geometry.segments import LineSegment, Segment, segment_reach

__all__ = ["MAX_COORDINATE_M", "MIN_LENGTH_M", "Layer", "Skipped"]

#: Largest distance from the origin a drawing may reach, m. Micro-fabrication parts are
#: millimetres to decimetres; a drawing reaching beyond a kilometre is in the wrong units,
#: holds a corrupt value or an absurd transform (an SVG ``scale(1e308)``), and its
#: coordinates would overflow the sampling and planning that follow.
MAX_COORDINATE_M = 1e3
#: Shortest contour a drawing may hold, m: shorter is below any fabrication scale (a
#: drawing in the wrong units), and its derivatives underflow.
MIN_LENGTH_M = 1e-9


@dataclass(frozen=True)
class Skipped:
    """Something in a drawing that was not imported, and why."""

    kind: str
    reason: str
    ref: str = ""

    def to_dict(self) -> dict[str, str]:
        """As a JSON-ready dict."""
        return {"kind": self.kind, "ref": self.ref, "reason": self.reason}


@dataclass(frozen=True, eq=False)
class Layer:
    """Contours of one layer: closed outer boundaries, the holes inside them, open paths.

    Parameters
    ----------
    contours : sequence of Path
        The contours, in drawing order.
    skipped : sequence of Skipped
        What the importer could not take, reported rather than dropped silently.
    source : str
        Where the contours came from (file name or shape), for reports.
    """

    contours: tuple[Path, ...]
    skipped: tuple[Skipped, ...] = field(default=())
    source: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "contours", tuple(self.contours))
        object.__setattr__(self, "skipped", tuple(self.skipped))
        for c in self.contours:
            if not isinstance(c, Path):
                raise TypeError(f"a layer holds Path contours, got {type(c).__name__}")

    def __iter__(self) -> Iterator[Path]:
        return iter(self.contours)

    def __len__(self) -> int:
        return len(self.contours)

    def __getitem__(self, i: int) -> Path:
        return self.contours[i]

    @property
    def closed(self) -> tuple[Path, ...]:
        """The closed contours."""
        return tuple(c for c in self.contours if c.closed)

    @property
    def open(self) -> tuple[Path, ...]:
        """The open contours."""
        return tuple(c for c in self.contours if not c.closed)

    @cached_property
    def containers(self) -> tuple[tuple[int, ...], ...]:
        """The closed contours containing each contour, ascending indices; ``()`` if open.

        Contour ``j`` contains closed contour ``i`` when the polygon of ``j``
        (:meth:`Path.flatten <microfab.geometry.path.Path.flatten>`) contains a point of
        ``i`` just inside its first segment (the midpoint, away from shared vertices).
        Found through a grid of the polygons' boxes
        (:func:`~microfab.geometry.nesting.containers`), not by testing every pair.
        """
        closed_idx = np.array([i for i, c in enumerate(self.contours) if c.closed], dtype=int)
        out: list[tuple[int, ...]] = [()] * len(self.contours)
        if closed_idx.size == 0:
            return tuple(out)
        closed = [self.contours[i] for i in closed_idx]
        probes = np.array([c.first_midpoint for c in closed])
        ptr, idx = nesting.containers(
            [c.flatten() for c in closed], probes, own=np.arange(closed_idx.size)
        )
        found = closed_idx[idx].tolist()
        for k, i in enumerate(closed_idx.tolist()):
            out[i] = tuple(found[ptr[k] : ptr[k + 1]])
        return tuple(out)

    @cached_property
    def depth(self) -> tuple[int, ...]:
        """Nesting depth of each contour: 0 outer, 1 hole, 2 island in a hole, …; -1 open.

        A closed contour's depth is the number of other closed contours containing a
        point of it (:attr:`containers`; the even–odd rule decides what is material).
        """
        return tuple(
            len(k) if c.closed else -1 for c, k in zip(self.contours, self.containers, strict=True)
        )

    def oriented(self) -> Layer:
        """Outer contours counter-clockwise, holes clockwise.

        Closed contours at even depth turn counter-clockwise (material on the left), at
        odd depth clockwise; open contours are unchanged.
        """
        out = []
        for c, d in zip(self.contours, self.depth, strict=True):
            if d < 0:
                out.append(c)
            else:
                want = "ccw" if d % 2 == 0 else "cw"
                out.append(c if c.orientation == want else c.reversed())
        return Layer(tuple(out), self.skipped, self.source)

    def require_closed(self) -> Layer:
        """Return the layer if every contour is closed, else raise a ValueError naming them."""
        bad = [
            (i, float(np.hypot(*(c.end - c.start))))
            for i, c in enumerate(self.contours)
            if not c.closed
        ]
        if bad:
            desc = ", ".join(f"#{i} (gap {g:.3g} m)" for i, g in bad[:10])
            raise ValueError(
                f"{len(bad)} contour(s) are open and cannot be closed: {desc}; "
                "fix the drawing or raise the chaining tolerance"
            )
        if not self.contours:
            raise ValueError("the layer has no contours")
        return self

    def require_extent(
        self, limit_m: float = MAX_COORDINATE_M, *, only: Iterable[int] | None = None
    ) -> Layer:
        """Return the layer if it has contours, all within ``±limit_m`` and not too short.

        Parameters
        ----------
        limit_m : float
            Largest coordinate allowed, m (default `MAX_COORDINATE_M`).
        only : iterable of int, optional
            Indices of the contours to check, for a reader that has checked the others
            (every one of their segments within ``limit_m``, their lengths at least
            `MIN_LENGTH_M`); all of them by default.

        Raises
        ------
        ValueError
            No contours, a contour with a non-finite coordinate or one beyond ``limit_m``,
            or one shorter than `MIN_LENGTH_M`; the message names the source, the contour
            and how far it reaches or how long it is.
        """
        src = self.source or "the drawing"
        if not self.contours:
            skipped = f" (skipped: {len(self.skipped)} item(s))" if self.skipped else ""
            raise ValueError(f"{src}: no contours to draw{skipped}")
        for i in range(len(self.contours)) if only is None else sorted(only):
            c = self.contours[i]
            reach = max(segment_reach(s) for s in c.segments)
            if not reach <= limit_m:
                what = f"coordinates up to {reach:.3g} m"
                if not np.isfinite(reach):
                    what = "non-finite coordinates"
                raise ValueError(
                    f"{src}: contour #{i} has {what}; a drawing must lie within "
                    f"±{limit_m:g} m of the origin (wrong units, a corrupt value or an "
                    "absurd scale?)"
                )
            if not c.length >= MIN_LENGTH_M:
                raise ValueError(
                    f"{src}: contour #{i} is {c.length:.3g} m long, shorter than "
                    f"{MIN_LENGTH_M:g} m (wrong units or an absurd scale?)"
                )
        return self

    def transformed(self, A: object, b: object = (0.0, 0.0)) -> Layer:
        """Every contour mapped by ``p -> A p + b``."""
        return Layer(tuple(c.transformed(A, b) for c in self.contours), self.skipped, self.source)

    def scaled(self, k: float) -> Layer:
        """Every contour scaled by ``k`` about the origin."""
        return self.transformed(k * np.eye(2))

    def translated(self, d: Sequence[float]) -> Layer:
        """Every contour shifted by ``d`` (m)."""
        return self.transformed(np.eye(2), d)

    @property
    def bbox(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` over all contours, m."""
        if not self.contours:
            raise ValueError("the layer has no contours")
        b = np.array([c.bbox for c in self.contours])
        lo, hi = b[:, :2].min(axis=0), b[:, 2:].max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))

    def tour(self) -> tuple[Path, tuple[tuple[float, float], ...]]:
        """All contours as one open path, joined by straight jumps, and where to mark.

        The contours are visited in order; a straight :class:`LineSegment` jumps from the
        end of one to the start of the next (the laser is off there). A trajectory planned
        along the tour stops at every corner, including both ends of each jump.

        Returns
        -------
        path : Path
            The open tour.
        marks : tuple of (float, float)
            Arc-length intervals ``(s_start, s_end)`` of the contours themselves, m.
        """
        if not self.contours:
            raise ValueError("the layer has no contours")
        segs: list[Segment] = []
        marks: list[tuple[float, float]] = []
        s = 0.0
        for c in self.contours:
            if segs:
                gap = c.start - segs[-1].end
                if np.hypot(*gap) > 0:
                    jump = LineSegment(segs[-1].end, c.start)
                    segs.append(jump)
                    s += jump.length
            segs.extend(c.segments)
            marks.append((s, s + c.length))
            s += c.length
        return Path(tuple(segs), closed=False), tuple(marks)

    def summary(self) -> dict[str, object]:
        """The JSON summary printed by ``microfab path show --json``."""
        return {
            "contours": [c.summary() for c in self.contours],
            "skipped": [s.to_dict() for s in self.skipped],
        }
