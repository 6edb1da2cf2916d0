"""The entity reader of `microfab.geometry.dxf.read_dxf`: DXF entities to exact segments.

`_Reader` turns each modelspace entity, and the entities of block references (INSERT,
MINSERT, expanded recursively with ezdxf's virtual entities up to `_MAX_DEPTH` levels),
into segments in metres (LINE, ARC, CIRCLE, LWPOLYLINE, POLYLINE, SPLINE, ELLIPSE; the
table of :mod:`.dxf`) held in its `microfab.geometry.dxf_batch.SegmentBatch`, or into a
skip record (`microfab.geometry.layer.Skipped`) with the reason (`_SKIP_REASONS`, a
tilted or non-planar entity, invalid geometry, beyond the drawing bounds). Apart from
the file's reading, units and chaining (:mod:`.dxf`), which re-exports these names.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence

import numpy as np

from microfab.geometry.dxf_batch import LINE_BULGE, SegmentBatch, beyond_reason
from microfab.geometry.layer import MAX_COORDINATE_M, Skipped
from microfab.geometry.segments import (
    ArcSegment,
    CurveSegment,
    LineSegment,
    Segment,
    segment_reach,
)

__all__: list[str] = []

_MAX_DEPTH = 32  # block nesting depth; deeper means a recursive block definition
_FLAT_RTOL = 1e-9  # relative tolerance on z and on the extrusion's tilt
_TWO_PI = 2.0 * math.pi

_SKIP_REASONS: dict[str, str] = {
    **dict.fromkeys(
        ("TEXT", "MTEXT", "ATTRIB", "ATTDEF"),
        "text is not imported; convert it to outlines (explode) in the CAD program",
    ),
    **dict.fromkeys(
        ("HATCH", "MPOLYGON", "SOLID", "TRACE", "WIPEOUT"),
        "filled areas are not imported; draw the boundary as a polyline",
    ),
    **dict.fromkeys(
        ("DIMENSION", "ARC_DIMENSION", "LARGE_RADIAL_DIMENSION", "LEADER", "MLEADER",
         "MULTILEADER", "TOLERANCE"),
        "annotations are not imported",
    ),
    "POINT": "a point has no length",
    **dict.fromkeys(
        ("3DFACE", "3DSOLID", "MESH", "REGION", "BODY", "SURFACE", "EXTRUDEDSURFACE",
         "LOFTEDSURFACE", "REVOLVEDSURFACE", "SWEPTSURFACE", "PLANESURFACE"),
        "surface and solid geometry is not imported",
    ),
    **dict.fromkeys(
        ("IMAGE", "UNDERLAY", "PDFUNDERLAY", "DWFUNDERLAY", "DGNUNDERLAY", "OLE2FRAME"),
        "images and underlays are not imported",
    ),
    **dict.fromkeys(("RAY", "XLINE"), "infinite lines are not imported"),
}  # fmt: skip


#: What a handler returns when it has put the entity in the batch: accepted (a LINE, a
#: polyline without bulges) or, with arcs, pending until `SegmentBatch.finish`
_STORED: list[None] = [None]
_PENDING: list[None] = [None]


class _SkipEntityError(Exception):
    """Raised by an entity handler: the entity is skipped for the given reason."""


def _plane_sign(entity: object) -> float:
    """+1 or -1: the sign of an entity's extrusion z; raise _SkipEntityError if it is tilted."""
    ex, ey, ez = (float(v) for v in entity.dxf.extrusion)  # type: ignore[attr-defined]
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    if not norm > 0 or math.hypot(ex, ey) > _FLAT_RTOL * norm:
        raise _SkipEntityError(
            f"not in the XY plane: extrusion ({ex:.6g}, {ey:.6g}, {ez:.6g}) is not ±z"
        )
    return 1.0 if ez > 0 else -1.0


def _check_flat(z: Sequence[float], size: float, what: str = "points") -> None:
    """Raise _SkipEntityError unless the z values agree (a plane parallel to XY)."""
    lo, hi = min(z), max(z)
    scale = max(size, abs(lo), abs(hi))
    if hi - lo > _FLAT_RTOL * scale:
        raise _SkipEntityError(
            f"not in a plane parallel to XY: its {what} have z from {lo:.6g} to {hi:.6g} "
            "drawing units"
        )


def _ref(entity: object, parent_ref: str) -> str:
    """The entity's handle for skip records, or its block reference's."""
    handle = entity.dxf.get("handle")  # type: ignore[attr-defined]
    return handle if handle else parent_ref


def _orientation(entity: object) -> tuple[float, bool]:
    """`_plane_sign`, and whether the extrusion is exactly +z (no OCS transform needed)."""
    ex, ey, ez = entity.dxf.extrusion  # type: ignore[attr-defined]
    if ex == 0 and ey == 0 and ez > 0:
        return 1.0, True
    return _plane_sign(entity), False


class _Reader:
    """Turns entities into segments (metres) and skip records."""

    def __init__(self, k: float, flatten_blocks: bool) -> None:
        self.k = k
        self.flatten_blocks = flatten_blocks
        self.batch = SegmentBatch()
        # the batch's slots and lines, appended to directly (see SegmentBatch)
        self.segments, self.lines = self.batch.slots, self.batch.lines
        self._mark = self.batch.mark()  # where what `_poly` puts in the batch starts
        self.skipped: list[Skipped] = []
        self.handlers: dict[str, Callable[[object], Sequence[Segment | None]]] = {
            "LINE": self.line,
            "ARC": self.arc,
            "CIRCLE": self.arc,
            "LWPOLYLINE": self.lwpolyline,
            "POLYLINE": self.polyline,
            "SPLINE": self.spline,
            "ELLIPSE": self.ellipse,
        }

    # ------------------------------------------------------------------ dispatch
    def entity(self, e: object, parent_ref: str, depth: int) -> None:
        kind = e.dxftype()  # type: ignore[attr-defined]
        handler = self.handlers.get(kind)
        if handler is None:
            if kind in ("INSERT", "MINSERT"):
                self.insert(e, _ref(e, parent_ref), depth)
                return
            reason = _SKIP_REASONS.get(kind, "unsupported entity type")
            self.skipped.append(Skipped(kind, reason, _ref(e, parent_ref)))
            return
        try:
            segs = handler(e)
        except _SkipEntityError as exc:
            self.skipped.append(Skipped(kind, str(exc), _ref(e, parent_ref)))
            return
        except (ValueError, ArithmeticError) as exc:
            # corrupt values (NaN coordinates, a curve that does not fit, ...)
            self.skipped.append(Skipped(kind, f"invalid geometry: {exc}", _ref(e, parent_ref)))
            return
        if segs is _STORED:  # in the batch, checked
            return
        if segs is _PENDING:  # in the batch, checked but for its arcs
            self.batch.wait(self._mark, len(self.skipped), kind, _ref(e, parent_ref))
            return
        reach = max(map(segment_reach, segs), default=0.0)  # type: ignore[arg-type]
        if not reach <= MAX_COORDINATE_M:
            self.skipped.append(Skipped(kind, beyond_reason(reach), _ref(e, parent_ref)))
            return
        self.segments.extend(segs)

    def insert(self, e: object, ref: str, depth: int) -> None:
        name = str(e.dxf.name)  # type: ignore[attr-defined]
        if not self.flatten_blocks:
            self.skipped.append(
                Skipped("INSERT", f"block {name!r} not expanded (flatten_blocks=False)", ref)
            )
            return
        if depth >= _MAX_DEPTH:
            self.skipped.append(
                Skipped(
                    "INSERT",
                    f"block {name!r} nested deeper than {_MAX_DEPTH} levels "
                    "(recursive block definition?)",
                    ref,
                )
            )
            return
        inner_ref = f"{ref}:{name}"
        for att in getattr(e, "attribs", ()):
            att_ref = att.dxf.get("handle") or inner_ref
            self.skipped.append(Skipped("ATTRIB", _SKIP_REASONS["ATTRIB"], att_ref))

        def on_skip(entity: object, reason: str) -> None:
            self.skipped.append(
                Skipped(
                    entity.dxftype(),  # type: ignore[attr-defined]
                    f"cannot be transformed by the block reference: {reason}",
                    inner_ref,
                )
            )

        try:
            refs = list(e.multi_insert()) if e.mcount > 1 else [e]  # type: ignore[attr-defined]
            for ins in refs:
                for v in ins.virtual_entities(skipped_entity_callback=on_skip):
                    self.entity(v, inner_ref, depth + 1)
        except Exception as exc:  # ezdxf raises various errors for odd block transforms
            self.skipped.append(
                Skipped("INSERT", f"block {name!r} could not be expanded: {exc}", ref)
            )

    # ------------------------------------------------------------------ entities
    def line(self, e: object) -> list[Segment | None]:
        s, t = e.dxf.start, e.dxf.end  # type: ignore[attr-defined]
        size = math.hypot(t.x - s.x, t.y - s.y)
        if s.z != t.z:
            _check_flat((s.z, t.z), size, "end points")
        if size == 0:
            raise _SkipEntityError("zero length")
        k, limit = self.k, MAX_COORDINATE_M
        x0, y0, x1, y1 = s.x * k, s.y * k, t.x * k, t.y * k
        if not (abs(x0) <= limit and abs(y0) <= limit and abs(x1) <= limit and abs(y1) <= limit):
            xy = (x0, y0, x1, y1)  # not finite, or too far: refused
            if not all(map(math.isfinite, xy)):
                return [LineSegment(xy[:2], xy[2:])]  # raises the segment's own error
            raise _SkipEntityError(beyond_reason(max(map(abs, xy))))  # as entity() does
        self.lines += (x0, y0, x1, y1)
        self.segments.append(None)
        return _STORED

    def arc(self, e: object) -> list[Segment]:
        sign, plus_z = _orientation(e)
        c = e.dxf.center  # type: ignore[attr-defined]
        r = float(e.dxf.radius)  # type: ignore[attr-defined]
        if not (math.isfinite(r) and r > 0):
            raise _SkipEntityError(f"radius must be positive, got {r} drawing units")
        if e.dxftype() == "CIRCLE":  # type: ignore[attr-defined]
            a0, sweep = 0.0, _TWO_PI
        else:
            a0 = math.radians(float(e.dxf.start_angle))  # type: ignore[attr-defined]
            span = (float(e.dxf.end_angle) - float(e.dxf.start_angle)) % 360.0  # type: ignore[attr-defined]
            sweep = math.radians(span) if span > 0 else _TWO_PI  # equal angles: full circle
        if plus_z:
            cx, cy, theta0 = c.x, c.y, a0
        else:
            # OCS -> WCS: the arc runs counter-clockwise about the extrusion, i.e.
            # clockwise seen from +z when the extrusion points down
            ocs = e.ocs()  # type: ignore[attr-defined]
            cw = ocs.to_wcs(c)
            p0 = ocs.to_wcs((c.x + r * math.cos(a0), c.y + r * math.sin(a0), c.z))
            cx, cy = cw.x, cw.y
            theta0 = math.atan2(p0.y - cw.y, p0.x - cw.x)
        k = self.k
        return [ArcSegment.from_numbers(cx * k, cy * k, r * k, theta0, sign * sweep)]

    def _poly(
        self, xy: Sequence[tuple[float, float]], bulges: Sequence[float], closed: bool
    ) -> list[Segment]:
        """Lines and bulge arcs through vertices (drawing units) scaled to metres.

        Held in the batch as numbers when it takes them (`_STORED`, or `_PENDING` with
        arcs, whose reach is only known at the end); else made here, to be refused.
        """
        if len(xy) < 2:
            raise _SkipEntityError(f"fewer than two vertices ({len(xy)})")
        self._mark = self.batch.mark()
        held = self.batch.add_polyline(xy, bulges, closed, self.k)
        if held is None:
            return self._poly_segments(xy, bulges, closed)
        return _PENDING if held else _STORED

    def _poly_segments(
        self, xy: Sequence[tuple[float, float]], bulges: Sequence[float], closed: bool
    ) -> list[Segment]:
        """`_poly`'s segments made one by one (they raise their errors)."""
        k, n = self.k, len(xy)
        out: list[Segment] = []
        for i in range(n if closed else n - 1):
            (x0, y0), (x1, y1) = xy[i], xy[(i + 1) % n]
            if x0 == x1 and y0 == y1:
                continue
            p0, p1, b = (x0 * k, y0 * k), (x1 * k, y1 * k), bulges[i]
            out.append(
                LineSegment(p0, p1) if abs(b) <= LINE_BULGE else ArcSegment.from_bulge(p0, p1, b)
            )
        if not out:
            raise _SkipEntityError("all vertices coincide (zero length)")
        return out

    def lwpolyline(self, e: object) -> list[Segment]:
        sign, plus_z = _orientation(e)
        # an LWPOLYLINE iterates as (x, y, start width, end width, bulge): one array
        pts = [(x, y, b) for x, y, _, _, b in np.array(list(e), dtype=float).tolist()]  # type: ignore[call-overload]
        bulges = [b * sign for _, _, b in pts]
        if plus_z:
            xy = [(x, y) for x, y, _ in pts]
        else:
            elev = float(e.dxf.elevation)  # type: ignore[attr-defined]
            w = list(e.ocs().points_to_wcs([(x, y, elev) for x, y, _ in pts]))  # type: ignore[attr-defined]
            xy = [(p.x, p.y) for p in w]
        return self._poly(xy, bulges, bool(e.closed))  # type: ignore[attr-defined]

    def polyline(self, e: object) -> list[Segment]:
        from ezdxf.lldxf.const import VTX_SPLINE_FRAME_CONTROL_POINT

        if e.is_poly_face_mesh or e.is_polygon_mesh:  # type: ignore[attr-defined]
            raise _SkipEntityError("polyface and polygon meshes are surfaces, not contours")
        verts = [
            v
            for v in e.vertices  # type: ignore[attr-defined]
            if not (v.dxf.flags & VTX_SPLINE_FRAME_CONTROL_POINT)
        ]
        closed = bool(e.is_closed)  # type: ignore[attr-defined]
        if e.is_3d_polyline:  # type: ignore[attr-defined]
            loc = [v.dxf.location for v in verts]
            if loc:
                xs, ys = [p.x for p in loc], [p.y for p in loc]
                size = max(max(xs) - min(xs), max(ys) - min(ys))
                _check_flat([p.z for p in loc], size, "vertices")
            return self._poly([(p.x, p.y) for p in loc], [0.0] * len(loc), closed)
        sign, plus_z = _orientation(e)
        bulges = [float(v.dxf.bulge) * sign for v in verts]
        elev = float(e.dxf.elevation.z)  # type: ignore[attr-defined]
        pts = [(v.dxf.location.x, v.dxf.location.y, elev) for v in verts]
        if plus_z:
            xy = [(x, y) for x, y, _ in pts]
        else:
            xy = [(p.x, p.y) for p in e.ocs().points_to_wcs(pts)]  # type: ignore[attr-defined]
        return self._poly(xy, bulges, closed)

    def spline(self, e: object) -> list[Segment]:
        try:
            bs = e.construction_tool()  # type: ignore[attr-defined]
        except Exception as exc:  # ezdxf: no control/fit points, bad knots, ...
            raise _SkipEntityError(f"invalid spline: {exc}") from exc
        cp = np.asarray(bs.control_points, dtype=float).reshape(-1, 3)
        if cp.shape[0] < 2 or not np.all(np.isfinite(cp)):
            raise _SkipEntityError("invalid spline: needs at least two finite control points")
        _check_flat(cp[:, 2], float(np.max(np.ptp(cp[:, :2], axis=0))), "control points")
        k = self.k
        if not bs.is_rational and bs.is_clamped:
            return [
                CurveSegment.from_bezier(np.asarray(b, dtype=float)[:, :2] * k)
                for b in bs.bezier_decomposition()
            ]
        # rational (NURBS) or unclamped: fit each knot span, where the curve is smooth
        p, knots = bs.degree, np.asarray(bs.knots(), dtype=float)
        lo, hi = knots[p], knots[bs.count]
        brk = np.unique(knots[(knots >= lo) & (knots <= hi)])
        out: list[Segment] = []
        for a, b in itertools.pairwise(brk.tolist()):
            if b - a <= 1e-12 * (hi - lo):
                continue

            def f(u: np.ndarray, a: float = a, b: float = b) -> np.ndarray:
                t = np.clip(a + (b - a) * np.asarray(u, dtype=float), a, b)
                pts = np.asarray(list(bs.points(t.tolist())), dtype=float).reshape(-1, 3)
                return pts[:, :2] * k

            out.extend(CurveSegment.from_function(f))
        if not out:
            raise _SkipEntityError("invalid spline: empty parameter range")
        return out

    def ellipse(self, e: object) -> list[Segment]:
        _plane_sign(e)
        ce = e.construction_tool()  # type: ignore[attr-defined]
        c, M, m = ce.center, ce.major_axis, ce.minor_axis
        a = math.hypot(M.x, M.y)
        if not (a > 0 and ce.ratio > 0):
            raise _SkipEntityError("degenerate ellipse (zero axis)")
        _check_flat((0.0, M.z, m.z), a, "axes")
        t0 = float(ce.start_param)
        span = (float(ce.end_param) - t0) % _TWO_PI
        if span <= 1e-12:
            span = _TWO_PI  # start = end: the full ellipse
        k = self.k
        cxy = np.array([c.x, c.y]) * k
        Mxy = np.array([M.x, M.y]) * k
        mxy = np.array([m.x, m.y]) * k

        def f(u: np.ndarray) -> np.ndarray:
            t = t0 + span * np.asarray(u, dtype=float)
            return cxy + np.cos(t)[:, None] * Mxy + np.sin(t)[:, None] * mxy

        return list(CurveSegment.from_function(f))
