"""Read the planar geometry of a DXF drawing into a :class:`~microfab.geometry.layer.Layer`.

The modelspace is read with `ezdxf <https://ezdxf.readthedocs.io>`_; block references
(INSERT, MINSERT) are expanded recursively with ezdxf's virtual entities, so nested
blocks, scale, rotation, mirroring and non-uniform scale (which turns arcs into
ellipses) all come out in world coordinates. Every entity becomes exact segments:

============================  ===================================================
DXF entity                    segments
============================  ===================================================
LINE                          :class:`LineSegment`
ARC, CIRCLE                   :class:`ArcSegment` (clockwise for extrusion −z)
LWPOLYLINE, 2D POLYLINE       lines and bulge arcs (:meth:`ArcSegment.from_bulge`)
3D POLYLINE                   lines (when it lies in a plane parallel to XY)
SPLINE                        Bézier pieces (:meth:`CurveSegment.from_bezier`),
                              exact; rational or unclamped splines are fitted per
                              knot span (:meth:`CurveSegment.from_function`)
ELLIPSE                       :meth:`CurveSegment.from_function`, ~1e-13 relative
============================  ===================================================

Only geometry lying in a plane parallel to XY (constant z, any elevation; extrusion
±z) is taken, projected onto XY. Everything else — other entity types (TEXT, HATCH,
DIMENSION, POINT, 3DFACE, …), tilted or 3-D geometry, polyface meshes, degenerate
entities — is reported in :attr:`Layer.skipped` with the entity's handle (for entities
inside blocks, the INSERT's handle followed by the block names), never dropped
silently. Paper space is not read.

The pieces are converted to metres from the header's ``$INSUNITS`` (or the ``units``
override) and joined by :func:`~microfab.geometry.chain.chain_segments`. Open chains
stay open paths (engraving lines); call :meth:`Layer.require_closed` where closed
contours are needed.

The entity reader (`_Reader`: entities to segments and skip records) is in
:mod:`.dxf_entities`, re-exported here.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import math
import os
import struct
from collections import Counter
from collections.abc import Iterator
from pathlib import Path as FsPath

from microfab.core.validate import check_positive
from microfab.geometry.chain import _chain
from microfab.geometry.dxf_batch import extent
from microfab.geometry.dxf_entities import _FLAT_RTOL as _FLAT_RTOL
from microfab.geometry.dxf_entities import _MAX_DEPTH as _MAX_DEPTH
from microfab.geometry.dxf_entities import _PENDING as _PENDING
from microfab.geometry.dxf_entities import _SKIP_REASONS as _SKIP_REASONS
from microfab.geometry.dxf_entities import _STORED as _STORED
from microfab.geometry.dxf_entities import _TWO_PI as _TWO_PI
from microfab.geometry.dxf_entities import _check_flat as _check_flat
from microfab.geometry.dxf_entities import _orientation as _orientation
from microfab.geometry.dxf_entities import _plane_sign as _plane_sign
from microfab.geometry.dxf_entities import _Reader
from microfab.geometry.dxf_entities import _ref as _ref
from microfab.geometry.dxf_entities import _SkipEntityError as _SkipEntityError
from microfab.geometry.layer import MIN_LENGTH_M, Layer, Skipped
from microfab.geometry.path import Path

__all__ = ["INSUNITS_M", "UNITS_M", "read_dxf"]

#: metres per drawing unit for the ``$INSUNITS`` codes (exact definitions)
INSUNITS_M: dict[int, float] = {
    1: 0.0254,  # inches
    2: 0.3048,  # feet
    3: 1609.344,  # miles
    4: 1e-3,  # millimetres
    5: 1e-2,  # centimetres
    6: 1.0,  # metres
    7: 1e3,  # kilometres
    8: 2.54e-8,  # microinches
    9: 2.54e-5,  # mils
    10: 0.9144,  # yards
    11: 1e-10,  # ångströms
    12: 1e-9,  # nanometres
    13: 1e-6,  # microns
    14: 1e-1,  # decimetres
    15: 1e1,  # decametres
    16: 1e2,  # hectometres
    21: 1200.0 / 3937.0,  # US survey feet
    22: 100.0 / 3937.0,  # US survey inches
    23: 3600.0 / 3937.0,  # US survey yards
    24: 6336000.0 / 3937.0,  # US survey miles
}

#: metres per unit for the names accepted by ``read_dxf(units=...)``
UNITS_M: dict[str, float] = {
    "m": 1.0,
    "cm": 1e-2,
    "mm": 1e-3,
    "um": 1e-6,
    "µm": 1e-6,
    "micron": 1e-6,
    "nm": 1e-9,
    "in": 0.0254,
    "inch": 0.0254,
    "mil": 2.54e-5,
    "ft": 0.3048,
    "foot": 0.3048,
}


#: What ezdxf raises on a damaged file: its own errors, and, for a file cut short or
#: holding odd tags, errors of its tag loaders (StopIteration at the end of a truncated
#: header, IndexError in a cut binary file, ...).
_EZDXF_READ_ERRORS = (
    OSError,
    UnicodeDecodeError,
    ValueError,
    struct.error,
    StopIteration,
    IndexError,
    KeyError,
    TypeError,
    AttributeError,
    EOFError,
    ArithmeticError,
)

# ezdxf reports the repairs it makes (duplicate handles, ...) through logging; without a
# handler Python prints them on stderr, which would break a command's one-line error.
logging.getLogger("ezdxf").addHandler(logging.NullHandler())


def _unit_factor(doc: object, units: str | None, name: str) -> float:
    """Metres per drawing unit, from the override or the header's ``$INSUNITS``."""
    accepted = ", ".join(repr(u) for u in UNITS_M)
    raw = doc.header.get("$INSUNITS", 0)  # type: ignore[attr-defined]
    try:
        code = int(raw if raw is not None else 0)
    except (TypeError, ValueError):
        code = -1
    if units is not None:
        key = str(units).strip().lower()
        if key not in UNITS_M:
            raise ValueError(f"unknown units {units!r}; accepted units are {accepted}")
        given = UNITS_M[key]
        header = INSUNITS_M.get(code)
        if header is not None and not math.isclose(given, header, rel_tol=1e-12):
            raise ValueError(
                f"{name}: the drawing's header gives its units ($INSUNITS = {code}, "
                f"{header:g} m); units {units!r} ({given:g} m) would scale it by "
                f"{given / header:.6g}: leave the units out, or correct the header"
            )
        return given
    if code in INSUNITS_M:
        return INSUNITS_M[code]
    what = (
        "has no units ($INSUNITS = 0, unitless)"
        if code == 0
        else (f"has unsupported units ($INSUNITS = {raw!r})")
    )
    raise ValueError(
        f"{name}: the drawing {what}; pass units= (one of {accepted}), "
        "e.g. read_dxf(..., units='mm') or on the command line --units mm"
    )


@contextlib.contextmanager
def _gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector (restored afterwards).

    A large drawing allocates some ten objects per entity; the collector's full passes
    over them would cost about a third of the reading time.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def read_dxf(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    tol: float | None = None,
    flatten_blocks: bool = True,
) -> Layer:
    """Read the planar geometry of a DXF file as contours in metres.

    Parameters
    ----------
    path : str or os.PathLike
        The DXF file (ASCII or binary, any version ezdxf reads).
    units : str, optional
        The drawing unit where the header's ``$INSUNITS`` gives none (a header that gives
        another unit is refused, never silently rescaled): one of ``"m"``,
        ``"cm"``, ``"mm"``, ``"um"`` (``"µm"``, ``"micron"``), ``"nm"``, ``"in"``
        (``"inch"``), ``"mil"``, ``"ft"`` (``"foot"``). Needed when the drawing is
        unitless.
    tol : float, optional
        Chaining tolerance, m: segment ends closer than this are joined (and snapped,
        see :func:`~microfab.geometry.chain.chain_segments`). Default 1e-6 of the
        drawing's size, at least 1e-9 m.
    flatten_blocks : bool
        Expand block references (INSERT) into their geometry; if False they are
        reported as skipped.

    Returns
    -------
    Layer
        The chained contours (closed and open) in drawing order of their first piece,
        what was skipped and why, and ``source`` = the file name.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        If the file is not a readable DXF file, its units are unknown (pass ``units``),
        ``units`` or ``tol`` is invalid, or it holds no importable geometry.
    """
    import ezdxf

    fs = FsPath(path)
    name = fs.name
    if not fs.exists():
        raise FileNotFoundError(f"DXF file not found: {str(fs)!r}")
    if not fs.is_file():
        raise ValueError(f"{str(fs)!r} is not a file")
    if tol is not None:
        check_positive("chaining tolerance tol", tol, "m")
    with _gc_paused():
        try:
            doc = ezdxf.readfile(fs)
        except (ezdxf.DXFError, *_EZDXF_READ_ERRORS) as exc:
            if isinstance(exc, StopIteration | EOFError):
                why = "it ends too early: cut short?"
            else:  # ezdxf's messages may span lines ('Invalid group code "x\n"'): one
                why = " ".join(str(exc).split()) or type(exc).__name__
            raise ValueError(f"{name}: not a readable DXF file ({why})") from exc
        reader = _Reader(_unit_factor(doc, units, name), flatten_blocks)
        for e in doc.modelspace():
            reader.entity(e, "", 0)
        del doc
        segments, starts, ends, others = reader.batch.finish(reader.skipped)

    if not segments:
        counts = Counter(s.kind for s in reader.skipped)
        what = ", ".join(f"{n} {kind}" for kind, n in sorted(counts.items())) or (
            "nothing (the modelspace is empty)"
        )
        raise ValueError(f"{name}: no importable geometry; skipped: {what}")
    with _gc_paused():
        if tol is None:
            tol = max(1e-6 * extent(others, starts, ends), 1e-9)
        contours, snapped = _chain(segments, tol, (starts, ends))
        kept: list[Path] = []
        moved: list[int] = []  # kept contours whose segments the chaining moved
        for c, snap in zip(contours, snapped.tolist(), strict=True):
            if c.length >= MIN_LENGTH_M:
                if snap:
                    moved.append(len(kept))
                kept.append(c)
            elif c.length < MIN_LENGTH_M:  # a CAD artefact far below any fabrication scale
                x, y = (float(v) for v in c.start)
                reason = f"shorter than {MIN_LENGTH_M:g} m ({c.length:.3g} m)"
                reader.skipped.append(Skipped("contour", reason, f"at ({x:.6g}, {y:.6g}) m"))
        if not kept:
            raise ValueError(f"{name}: no importable geometry; every contour is shorter than 1 nm")
        # every segment of the other contours is an entity's, checked within the bounds
        # by _Reader.entity (reversing keeps a segment's reach)
        return Layer(tuple(kept), tuple(reader.skipped), name).require_extent(only=moved)
