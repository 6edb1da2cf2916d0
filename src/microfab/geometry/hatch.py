"""Hatching: fill a layer's closed contours with parallel scan vectors.

A laser scanner (SLM, seed 003 part 2) executes two kinds of vectors: *scan-vectors*
("mark" vectors), traversed at the scan speed with the laser on, and *jump-vectors*,
traversed as fast as possible with the laser off, to the start of the next scan-vector.
:func:`hatch` fills the material of a layer (even–odd rule: holes stay empty, islands in
holes are filled) with parallel scan lines, alternating their direction from line to line
(meander, "zig-zag"), and returns the marks and the jumps between consecutive marks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from microfab.core.arrays import readonly
from microfab.core.validate import check_finite, check_positive
from microfab.geometry.layer import Layer
from microfab.geometry.path import Path

__all__ = ["ScanVectors", "hatch", "layer_polygon"]


@dataclass(frozen=True, eq=False)
class ScanVectors:
    """Mark (scan) and jump vectors of a hatch, in execution order.

    Parameters
    ----------
    marks : numpy.ndarray
        Shape (n, 2, 2): ``marks[i] = [start, end]`` of the i-th laser-on vector, m.
    jumps : numpy.ndarray
        Shape (max(n − 1, 0), 2, 2): ``jumps[i] = [marks[i, 1], marks[i + 1, 0]]``, the
        laser-off move from the end of mark i to the start of mark i + 1, m.
    initial_jump : numpy.ndarray or None
        Shape (2, 2): the move from a given start point to ``marks[0, 0]``, if any, m.
    """

    marks: np.ndarray
    jumps: np.ndarray
    initial_jump: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        m = readonly(self.marks).reshape(-1, 2, 2)
        j = readonly(self.jumps).reshape(-1, 2, 2)
        if j.shape[0] != max(m.shape[0] - 1, 0):
            raise ValueError(
                f"{m.shape[0]} marks need {max(m.shape[0] - 1, 0)} jumps, got {j.shape[0]}"
            )
        object.__setattr__(self, "marks", readonly(m))
        object.__setattr__(self, "jumps", readonly(j))
        if self.initial_jump is not None:
            object.__setattr__(self, "initial_jump", readonly(self.initial_jump).reshape(2, 2))

    def __len__(self) -> int:
        return int(self.marks.shape[0])

    @property
    def mark_lengths(self) -> np.ndarray:
        """Length of each mark, m."""
        return np.linalg.norm(self.marks[:, 1] - self.marks[:, 0], axis=1)

    @property
    def jump_lengths(self) -> np.ndarray:
        """Length of each jump between marks, m (the initial jump not included)."""
        return np.linalg.norm(self.jumps[:, 1] - self.jumps[:, 0], axis=1)

    @property
    def total_mark_length(self) -> float:
        """Summed length of the marks (laser on), m."""
        return float(self.mark_lengths.sum())

    @property
    def total_jump_length(self) -> float:
        """Summed length of the jumps (laser off), initial jump included, m."""
        extra = 0.0
        if self.initial_jump is not None:
            extra = float(np.linalg.norm(self.initial_jump[1] - self.initial_jump[0]))
        return float(self.jump_lengths.sum()) + extra

    def vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """All vectors in execution order, and which are marks.

        Returns
        -------
        vectors : numpy.ndarray
            Shape (m, 2, 2): the initial jump (if any), then mark 0, jump 0, mark 1, …, m.
        is_mark : numpy.ndarray
            Shape (m,), bool: True for a mark (laser on), False for a jump.
        """
        n = len(self)
        out = np.empty((max(2 * n - 1, 0), 2, 2))
        out[0::2] = self.marks
        out[1::2] = self.jumps
        is_mark = np.zeros(out.shape[0], dtype=bool)
        is_mark[0::2] = True
        if self.initial_jump is not None:
            out = np.concatenate([self.initial_jump[None], out])
            is_mark = np.concatenate([[False], is_mark])
        return out, is_mark

    def to_paths(self) -> list[Path]:
        """Each mark as an open straight :class:`~microfab.geometry.path.Path`."""
        return [Path.polyline(m) for m in self.marks]

    def plot(self, ax: object, *, mark_color: str = "C0", jump_color: str = "C3") -> None:
        """Draw the marks (solid) and jumps (dotted) on a matplotlib ``Axes``."""
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(self.marks, colors=mark_color, linewidths=0.8))  # type: ignore[attr-defined]
        jumps = self.jumps
        if self.initial_jump is not None:
            jumps = np.concatenate([self.initial_jump[None], jumps])
        if len(jumps):
            ax.add_collection(  # type: ignore[attr-defined]
                LineCollection(jumps, colors=jump_color, linewidths=0.5, linestyles=":")
            )
        ax.set_aspect("equal")  # type: ignore[attr-defined]
        ax.autoscale_view()  # type: ignore[attr-defined]


def layer_polygon(layer: Layer, tol: float | None = None) -> shapely.Geometry:
    """The material of a layer's closed contours as a shapely (Multi)Polygon, m.

    Each closed contour is flattened to a polygon within ``tol`` (m) and the polygons are
    combined by the even–odd rule (their symmetric difference): nesting depth 0 is
    material, depth 1 a hole, depth 2 an island in the hole, and so on.

    Raises
    ------
    ValueError
        If the layer has open contours or none at all (via
        :meth:`~microfab.geometry.layer.Layer.require_closed`).
    """
    layer.require_closed()
    geom = shapely.Polygon()
    for c in layer.contours:
        poly = shapely.make_valid(shapely.Polygon(c.flatten(tol)))
        geom = shapely.symmetric_difference(geom, poly)
    return geom


def _line_parts(geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Straight pieces (k, 2, 2) of intersection results, and the index of their line."""
    parts, owner = shapely.get_parts(geoms, return_index=True)
    # a line that misses the material gives LINESTRING EMPTY: no coordinates, no piece
    full = ~shapely.is_empty(parts)
    parts, owner = parts[full], owner[full]
    keep = shapely.get_type_id(parts) == shapely.GeometryType.LINESTRING
    if np.any(shapely.get_type_id(parts) == shapely.GeometryType.GEOMETRYCOLLECTION):
        sub, sub_owner = shapely.get_parts(parts[~keep], return_index=True)
        owner2 = owner[~keep][sub_owner]
        k2 = (shapely.get_type_id(sub) == shapely.GeometryType.LINESTRING) & ~shapely.is_empty(sub)
        parts = np.concatenate([parts[keep], sub[k2]])
        owner = np.concatenate([owner[keep], owner2[k2]])
    else:
        parts, owner = parts[keep], owner[keep]
    if parts.size == 0:
        return np.zeros((0, 2, 2)), np.zeros(0, dtype=np.int64)
    coords, idx = shapely.get_coordinates(parts, return_index=True)
    counts = np.bincount(idx, minlength=parts.size)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    last = first + counts - 1
    # a piece of a straight line is straight: its first and last points are its ends
    return np.stack([coords[first], coords[last]], axis=1), owner


def hatch(
    layer: Layer,
    *,
    spacing: float,
    angle: float = 0.0,
    offset: float = 0.0,
    tol: float | None = None,
    start: object = None,
) -> ScanVectors:
    """Fill a layer's closed contours with parallel, alternating scan vectors.

    Scan lines run in the direction ``(cos angle, sin angle)`` and lie at signed
    distances ``offset + k·spacing`` (k integer) from the origin along the normal
    ``(−sin angle, cos angle)``. Each line is clipped to the material (even–odd rule, see
    :func:`layer_polygon`); every resulting piece is a mark. Lines are taken in order of
    increasing normal distance; counting only the lines that have marks, the pieces of
    the first, third, … line run in the scan direction and those of the second, fourth,
    … against it (meander), each line's pieces in that order, so that a jump to the next
    line is short. Pieces lying on the boundary (a scan line along a
    straight edge, up to 1e-9 of the part's size) are dropped.

    Parameters
    ----------
    layer : Layer
        Closed contours, m.
    spacing : float
        Distance between scan lines (hatch distance), m, positive.
    angle : float
        Scan direction, rad, counter-clockwise from +x.
    offset : float
        Shift of the family of lines along its normal, m.
    tol : float, optional
        Chord tolerance for flattening curved contours, m; ``spacing / 1000`` by default.
    start : array_like, optional
        Position (2,) before the first mark, m; adds ``ScanVectors.initial_jump``.

    Returns
    -------
    ScanVectors
        The marks in execution order and the jumps between them. A part narrower than
        the spacing may fall between two lines: the result is then empty (no marks).

    Raises
    ------
    ValueError
        If ``spacing`` is not a positive length, ``angle``/``offset`` are not finite, or
        the layer has open contours or none.
    """
    h = check_positive("hatch spacing", spacing, "m")
    check_finite("hatch angle", angle, "rad")
    check_finite("hatch offset", offset, "m")
    tol = h * 1e-3 if tol is None else float(tol)
    check_positive("flattening tolerance", tol, "m")
    geom = layer_polygon(layer, tol)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])  # scan frame (u along the lines, v across) -> xy
    start_pt = None
    if start is not None:
        start_pt = np.asarray(start, dtype=float).reshape(-1)
        if start_pt.shape != (2,) or not np.all(np.isfinite(start_pt)):
            raise ValueError(f"start must be a finite point (x, y) in m, got {start!r}")
    empty = ScanVectors(np.zeros((0, 2, 2)), np.zeros((0, 2, 2)))
    if geom.is_empty:
        return empty
    # the polygon in the scan frame: xy -> (u, v) = R^T xy
    g = shapely.transform(geom, lambda p: p @ R)
    umin, vmin, umax, vmax = g.bounds
    k0 = int(np.ceil((vmin - offset) / h))
    k1 = int(np.floor((vmax - offset) / h))
    if k1 < k0:
        return empty
    v = offset + h * np.arange(k0, k1 + 1)
    pad = 1.0 + 1e-3 * (umax - umin)
    ends = np.empty((v.size, 2, 2))
    ends[:, 0, 0], ends[:, 1, 0] = umin - pad, umax + pad
    ends[:, :, 1] = v[:, None]
    lines = shapely.linestrings(ends)
    pieces, line_of = _line_parts(shapely.intersection(lines, g))
    if pieces.shape[0] == 0:
        return empty
    # drop pieces along the boundary (a scan line on a straight edge: up to rounding, its
    # quarter points all lie on the boundary; a piece touching a vertex has at most one)
    eps = 1e-9 * max(umax - umin, vmax - vmin)
    boundary = g.boundary
    shapely.prepare(boundary)
    q = pieces[:, None, 0, :] + np.array([0.25, 0.5, 0.75])[None, :, None] * (
        pieces[:, None, 1, :] - pieces[:, None, 0, :]
    )
    near = shapely.dwithin(boundary, shapely.points(q.reshape(-1, 2)), eps).reshape(-1, 3)
    keep = (near.sum(axis=1) < 2) & (np.abs(pieces[:, 1, 0] - pieces[:, 0, 0]) > 0)
    pieces, line_of = pieces[keep], line_of[keep]
    if pieces.shape[0] == 0:
        return empty
    # each piece runs +u; on odd lines (counted from the first line with marks) reverse
    lo = pieces[:, :, 0].min(axis=1)
    hi = pieces[:, :, 0].max(axis=1)
    pieces[:, 0, 0], pieces[:, 1, 0] = lo, hi
    rank = np.unique(line_of, return_inverse=True)[1]
    odd = rank % 2 == 1
    pieces[odd] = pieces[odd][:, ::-1]
    order = np.lexsort((np.where(odd, -lo, lo), rank))
    marks_uv = pieces[order]
    marks = marks_uv @ R.T
    jumps = np.stack([marks[:-1, 1], marks[1:, 0]], axis=1)
    initial = None if start_pt is None else np.stack([start_pt, marks[0, 0]])
    return ScanVectors(marks, jumps, initial)
