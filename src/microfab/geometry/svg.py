"""SVG import: path data and drawings to a :class:`~microfab.geometry.layer.Layer`.

Path data (the ``d`` attribute) is tokenised and parsed by :func:`svgpathtools.parse_path`;
each of its pieces becomes an exact segment:

- ``Line`` → :class:`~microfab.geometry.segments.LineSegment`;
- ``QuadraticBezier`` / ``CubicBezier`` → :meth:`CurveSegment.from_bezier` (exact);
- ``Arc`` with equal radii → :class:`~microfab.geometry.segments.ArcSegment` (exact), an
  elliptical ``Arc`` → :meth:`CurveSegment.from_function` (~1e-13 relative).

Segments are built in SVG user units and then mapped to metres by one affine map (the
element's accumulated ``transform``, the unit scale and the y flip); lines, Bézier curves
and arcs under a similarity map exactly, an arc under a shear or an unequal scale becomes
an elliptic :class:`~microfab.geometry.segments.CurveSegment`.

Each subpath (started by ``M``/``m``, or implicitly after ``Z``) is one contour. It is
closed when it ends with ``Z``/``z``, or when its end point coincides with its start
(within the :class:`~microfab.geometry.path.Path` gap tolerance, 1e-9 of its size): some
exporters draw closed outlines without ``Z``.
"""

from __future__ import annotations

import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Callable
from pathlib import Path as FsPath

import numpy as np
import svgpathtools
from svgpathtools.parser import parse_transform

from microfab.core.validate import check_positive
from microfab.geometry.layer import MAX_COORDINATE_M, MIN_LENGTH_M, Layer, Skipped
from microfab.geometry.path import Path
from microfab.geometry.segments import (
    ArcSegment,
    CurveSegment,
    LineSegment,
    Segment,
    segment_reach,
)

__all__ = ["PX", "UNITS", "parse_svg_path", "read_svg"]

PX = 0.0254 / 96.0
"""One CSS pixel, m: the SVG user unit when a drawing gives no physical size (CSS 2.1)."""

UNITS: dict[str, float] = {
    "": PX,
    "px": PX,
    "pt": 0.0254 / 72.0,
    "pc": 0.0254 / 6.0,
    "in": 0.0254,
    "cm": 1e-2,
    "mm": 1e-3,
    "q": 0.25e-3,
    "m": 1.0,
}
"""Metres per SVG/CSS length unit."""

_COMMANDS = "MmZzLlHhVvCcSsQqTtAa"
_COMMAND_SPLIT = re.compile(f"([{_COMMANDS}])")
_BAD_CHAR = re.compile(rf"[^{_COMMANDS}0-9eE+\-.,\s]")
_FLOAT = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
_LENGTH = re.compile(
    r"^\s*([-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Z%]*)\s*$"
)

#: Elements that are never rendered directly (their content is referenced elsewhere).
_NOT_RENDERED = {
    "defs", "clipPath", "mask", "symbol", "marker", "pattern", "metadata", "title", "desc",
    "style", "script", "linearGradient", "radialGradient", "filter",
}  # fmt: skip
_CONTAINERS = {"g", "a", "switch"}
_SHAPES = {"path", "rect", "circle", "ellipse", "line", "polyline", "polygon"}


class _ExtentError(ValueError):
    """Geometry beyond `MAX_COORDINATE_M`: the whole drawing is refused, not one element."""


# --------------------------------------------------------------------------- path data
def _split_subpaths(d: str) -> list[tuple[str, bool]]:
    """Split path data into subpaths: ``[(text, ends_with_z), ...]``.

    A subpath starts at a moveto, or at the first drawing command after a closepath
    (its text then does not start with ``M``/``m``).
    """
    bad = _BAD_CHAR.search(d)
    if bad:
        raise ValueError(
            f"SVG path data: unexpected character {bad.group()!r} at position {bad.start()} "
            f"in {d[:80]!r}"
        )
    parts = _COMMAND_SPLIT.split(d)
    if parts[0].strip(" \t\r\n,"):
        raise ValueError(f"SVG path data must start with a moveto command (M or m), got {d[:80]!r}")
    cmds = [(parts[i], parts[i + 1]) for i in range(1, len(parts), 2)]
    if not cmds:
        if d.strip():
            raise ValueError(f"SVG path data has no commands: {d[:80]!r}")
        return []
    if cmds[0][0] not in "Mm":
        raise ValueError(
            f"SVG path data must start with a moveto command (M or m), got {cmds[0][0]!r}"
        )
    out: list[tuple[str, bool]] = []
    cur: list[str] = []
    for c, args in cmds:
        if c in "Mm" and cur:
            out.append(("".join(cur), False))
            cur = []
        if c in "Zz" and args.strip(" \t\r\n,"):
            raise ValueError(f"SVG path data: closepath takes no numbers, got {c}{args!r}")
        cur.append(c + args)
        if c in "Zz":
            out.append(("".join(cur), True))
            cur = []
    if cur:
        out.append(("".join(cur), False))
    return out


def _c2(z: complex) -> np.ndarray:
    return np.array([z.real, z.imag])


def _arc_segments(arc: svgpathtools.Arc) -> list[Segment]:
    """An svgpathtools ``Arc`` in user units as exact segments (user units)."""
    rx, ry = arc.radius.real, arc.radius.imag
    c = _c2(arc.center)
    phi = math.radians(arc.rotation)
    theta, delta = math.radians(arc.theta), math.radians(arc.delta)
    if not all(math.isfinite(v) for v in (rx, ry, c[0], c[1], phi, theta, delta)):
        raise ValueError(f"an arc with a non-finite radius, angle or centre: {arc}")
    if delta == 0.0:
        return []
    if abs(rx - ry) <= 1e-12 * max(rx, ry):
        # point(t) = c + r (cos(θ + φ + tΔ), sin(θ + φ + tΔ)) for a circle
        return [ArcSegment(c, 0.5 * (rx + ry), theta + phi, delta)]
    cp, sp = math.cos(phi), math.sin(phi)

    def f(u: np.ndarray) -> np.ndarray:
        a = theta + np.asarray(u, dtype=float) * delta
        ca, sa = np.cos(a), np.sin(a)
        return np.column_stack(
            [rx * cp * ca - ry * sp * sa + c[0], rx * sp * ca + ry * cp * sa + c[1]]
        )

    return list(CurveSegment.from_function(f))


def _to_segments(seg: object) -> list[Segment]:
    if isinstance(seg, svgpathtools.Line):
        return [LineSegment(_c2(seg.start), _c2(seg.end))]
    if isinstance(seg, svgpathtools.QuadraticBezier | svgpathtools.CubicBezier):
        ctrl = np.array([_c2(p) for p in seg.bpoints()])
        return [CurveSegment.from_bezier(ctrl)]
    if isinstance(seg, svgpathtools.Arc):
        return _arc_segments(seg)
    raise TypeError(f"unknown svgpathtools segment {type(seg).__name__}")  # pragma: no cover


# absurd coordinates overflow in the curves' reach (numpy's Chebyshev sums): no warning
# printed, the extent checks below refuse them
@np.errstate(over="ignore", invalid="ignore")
def _parse_d(d: str, A: np.ndarray, b: np.ndarray, ref: str) -> tuple[list[Path], list[Skipped]]:
    """Contours of path data ``d`` mapped by ``p -> A p + b`` (user units -> m)."""
    contours: list[Path] = []
    skipped: list[Skipped] = []
    where = f" of {ref}" if ref else ""
    pos = 0j  # current point
    start = 0j  # start of the last subpath (the current point after Z)
    for k, (text, has_z) in enumerate(_split_subpaths(d)):
        if text[0] not in "Mm":
            text = f"M {start.real!r} {start.imag!r} " + text
        try:
            with warnings.catch_warnings():
                # a zero-radius arc is a straight line (SVG 1.1 F.6.2), not worth a warning
                warnings.simplefilter("ignore")
                sp = svgpathtools.parse_path(text, current_pos=pos)
        except AssertionError as exc:
            raise ValueError(
                f"SVG path data{where}: subpath {k} has an arc whose end points coincide "
                f"(SVG draws nothing there); remove it: {text[:80]!r}"
            ) from exc
        except (ValueError, IndexError) as exc:
            raise ValueError(f"SVG path data{where}: subpath {k} is malformed: {exc}") from exc
        if len(sp):
            start = sp[0].start
        else:  # a bare moveto: "M x y" / "m dx dy"
            nums = _FLOAT.findall(text[1:])
            if len(nums) < 2:
                raise ValueError(f"SVG path data{where}: moveto needs two numbers: {text[:80]!r}")
            mv = float(nums[0]) + 1j * float(nums[1])
            start = mv if text[0] == "M" else pos + mv
        pos = start if has_z else (sp[-1].end if len(sp) else start)
        if not len(sp):
            continue  # a lone moveto draws nothing
        vals = [v for s in sp for p in (s.start, s.end) for v in (p.real, p.imag)]
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"SVG path data{where}: subpath {k} has non-finite coordinates")
        segs: list[Segment] = []
        for s in sp:
            segs.extend(_to_segments(s))
        # bound the image first, so that an absurd transform cannot overflow the maps
        bound = 2.0 * float(np.max(np.abs(A))) * max(segment_reach(s) for s in segs)
        bound += float(np.max(np.abs(b)))
        if not bound <= 1e100:
            what = f"about {bound:.3g} m" if math.isfinite(bound) else "non-finite coordinates"
            raise _ExtentError(
                f"SVG path data{where}: subpath {k} reaches {what}, beyond "
                f"±{MAX_COORDINATE_M:g} m (check the transforms and the width/viewBox units)"
            )
        try:
            segs = [s.transformed(A, b) for s in segs]
        except ValueError as exc:
            skipped.append(
                Skipped("subpath", f"cannot map it to metres: {exc}", f"{ref} subpath {k}".strip())
            )
            continue
        reach = max(segment_reach(s) for s in segs)
        if not reach <= MAX_COORDINATE_M:
            what = f"{reach:.3g} m" if math.isfinite(reach) else "non-finite coordinates"
            raise _ExtentError(
                f"SVG path data{where}: subpath {k} reaches {what}, beyond "
                f"±{MAX_COORDINATE_M:g} m (check the transforms and the width/viewBox units)"
            )
        if not any(s.length > 0 for s in segs):
            skipped.append(
                Skipped("subpath", "zero length (degenerate)", f"{ref} subpath {k}".strip())
            )
            continue
        total = sum(s.length for s in segs)
        if total < MIN_LENGTH_M:  # far below any fabrication scale: an exporter's artefact
            why = f"shorter than {MIN_LENGTH_M:g} m ({total:.3g} m)"
            skipped.append(Skipped("subpath", why, f"{ref} subpath {k}".strip()))
            continue
        open_path = Path(tuple(segs), closed=False)
        closed = has_z or bool(
            np.hypot(*(open_path.end - open_path.start)) <= open_path.gap_tol  # type: ignore[operator]
        )
        contours.append(Path(tuple(segs), closed=True) if closed else open_path)
    return contours, skipped


def parse_svg_path(d: str, *, scale: float = 1e-3, flip_y: bool = True) -> Layer:
    """Contours of SVG path data (the ``d`` attribute of a ``<path>``).

    Parameters
    ----------
    d : str
        Path data: ``M/L/H/V/C/S/Q/T/A/Z``, absolute (upper case) or relative (lower case).
    scale : float
        Metres per user unit; the default reads the numbers as millimetres.
    flip_y : bool
        Map ``y -> -y`` (SVG's y axis points down), so that the shape reads the right way
        up and a counter-clockwise contour on screen is counter-clockwise here.

    Returns
    -------
    Layer
        One contour per subpath, in order (a subpath ending with ``Z`` is closed; see the
        module notes); degenerate (zero-length) subpaths are listed in ``skipped``.

    Raises
    ------
    ValueError
        If the path data is malformed (unknown characters, missing numbers, not starting
        with a moveto, an arc with coincident end points) or ``scale`` is not positive.
    """
    if not isinstance(d, str):
        raise TypeError(f"path data must be a string, got {type(d).__name__}")
    s = check_positive("scale", scale, "m per user unit")
    A = np.diag([s, -s if flip_y else s])
    contours, skipped = _parse_d(d, A, np.zeros(2), "")
    return Layer(tuple(contours), tuple(skipped), source="svg path data")


# --------------------------------------------------------------------------- documents
def _local(tag: object) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _length(text: str | None) -> tuple[float, str] | None:
    """A CSS length ``"12.5mm"`` as (value, unit); None if absent or not a length."""
    if text is None:
        return None
    m = _LENGTH.match(text)
    if not m:
        return None
    return float(m.group(1)), m.group(2).lower()


def _user_unit(root: ET.Element) -> tuple[float, tuple[float, float, float, float] | None]:
    """Metres per user unit, and the viewBox (x, y, w, h) if any."""
    vb = None
    if root.get("viewBox") is not None:
        nums = [float(v) for v in _FLOAT.findall(root.get("viewBox", ""))]
        if len(nums) != 4 or nums[2] <= 0 or nums[3] <= 0:
            raise ValueError(
                f"SVG viewBox must be four numbers 'min-x min-y width height' with positive "
                f"width and height, got {root.get('viewBox')!r}"
            )
        vb = (nums[0], nums[1], nums[2], nums[3])
    w = _length(root.get("width"))
    raw = root.get("width")
    if w is None and raw is not None and raw.strip() not in ("", "auto"):
        raise ValueError(
            f"SVG width {raw!r} is not a length: give a number and a unit (e.g. '120mm'), "
            "or remove it"
        )
    if w is not None and not np.isfinite(w[0]):
        raise ValueError(f"SVG width must be a finite length, got {raw!r}")
    if w is None or w[1] == "%" or vb is None:
        # no physical size, a percentage, or no viewBox: user units are CSS px
        return PX, vb
    if w[1] not in UNITS:
        raise ValueError(f"SVG width {root.get('width')!r}: unknown unit {w[1]!r}")
    if w[0] <= 0:
        raise ValueError(f"SVG width must be positive, got {root.get('width')!r}")
    return w[0] * UNITS[w[1]] / vb[2], vb


def _num(el: ET.Element, name: str, default: float | None = 0.0) -> float:
    """A plain-number attribute (user units); ValueError if it has units or is bad."""
    v = el.get(name)
    if v is None:
        if default is None:
            raise ValueError(f"attribute {name!r} is missing")
        return default
    try:
        x = float(v)
    except ValueError:
        raise ValueError(f"attribute {name}={v!r} is not a plain number of user units") from None
    if not math.isfinite(x):
        raise ValueError(f"attribute {name}={v!r} is not finite")
    return x


def _rect_d(el: ET.Element) -> str:
    x, y = _num(el, "x"), _num(el, "y")
    w, h = _num(el, "width", None), _num(el, "height", None)
    if w <= 0 or h <= 0:
        raise ValueError(f"width {w} and height {h} must be positive (SVG draws nothing)")
    rx_s, ry_s = el.get("rx"), el.get("ry")
    rx = _num(el, "rx") if rx_s is not None else None
    ry = _num(el, "ry") if ry_s is not None else None
    rx = ry if rx is None else rx
    ry = rx if ry is None else ry
    rx = min(abs(rx or 0.0), w / 2.0)  # SVG 1.1 §9.2: clamp to half the side
    ry = min(abs(ry or 0.0), h / 2.0)
    if rx == 0.0 or ry == 0.0:
        return f"M{x!r},{y!r} H{x + w!r} V{y + h!r} H{x!r} Z"
    a = f"A{rx!r},{ry!r} 0 0 1"
    return (
        f"M{x + rx!r},{y!r} H{x + w - rx!r} {a} {x + w!r},{y + ry!r} V{y + h - ry!r} "
        f"{a} {x + w - rx!r},{y + h!r} H{x + rx!r} {a} {x!r},{y + h - ry!r} V{y + ry!r} "
        f"{a} {x + rx!r},{y!r} Z"
    )


def _ellipse_d(el: ET.Element, circle: bool) -> str:
    cx, cy = _num(el, "cx"), _num(el, "cy")
    if circle:
        rx = ry = _num(el, "r", None)
    else:
        rx, ry = _num(el, "rx", None), _num(el, "ry", None)
    if rx <= 0 or ry <= 0:
        raise ValueError(f"radii ({rx}, {ry}) must be positive (SVG draws nothing)")
    # two half arcs from the 3 o'clock point (SVG 1.1 §9.3)
    return (
        f"M{cx + rx!r},{cy!r} A{rx!r},{ry!r} 0 0 1 {cx - rx!r},{cy!r} "
        f"A{rx!r},{ry!r} 0 0 1 {cx + rx!r},{cy!r} Z"
    )


def _points_d(el: ET.Element, closed: bool) -> str:
    nums = _FLOAT.findall(el.get("points", ""))
    if len(nums) < 4 or len(nums) % 2:
        raise ValueError(f"points needs at least two x,y pairs, got {len(nums)} numbers")
    pairs = [f"{nums[i]} {nums[i + 1]}" for i in range(0, len(nums), 2)]
    return "M" + " L".join(pairs) + (" Z" if closed else "")


_TO_D: dict[str, Callable[[ET.Element], str]] = {
    "path": lambda el: el.get("d", ""),
    "rect": _rect_d,
    "circle": lambda el: _ellipse_d(el, circle=True),
    "ellipse": lambda el: _ellipse_d(el, circle=False),
    "line": lambda el: (
        f"M{_num(el, 'x1')!r},{_num(el, 'y1')!r} L{_num(el, 'x2')!r},{_num(el, 'y2')!r}"
    ),
    "polyline": lambda el: _points_d(el, closed=False),
    "polygon": lambda el: _points_d(el, closed=True),
}


def read_svg(path: str | os.PathLike[str], *, scale: float | None = None) -> Layer:
    """Contours of every ``<path>`` and basic shape in an SVG file.

    ``<path>``, ``<rect>`` (rounded corners included), ``<circle>``, ``<ellipse>``,
    ``<line>``, ``<polyline>`` and ``<polygon>`` are read, inside any nesting of ``<g>``,
    ``<a>`` and ``<switch>``, with every ``transform`` attribute applied. Whatever is not
    geometry it can take (``<text>``, ``<image>``, ``<use>``, nested ``<svg>``, shapes
    with unit-bearing or invalid attributes) is reported in ``Layer.skipped``; the
    content of ``<defs>``, ``<clipPath>``, ``<mask>`` etc. is not drawn and is ignored.

    Units: when the root ``<svg>`` has a ``width`` with a unit (mm, cm, in, px, pt, pc,
    q, m) and a ``viewBox``, a user unit is ``width / viewBox-width`` (converted to m);
    otherwise a user unit is one CSS px, 0.0254/96 m. The x scale is used for both axes
    (``preserveAspectRatio`` is ignored). y is flipped about the bottom of the viewBox
    (or of the ``height``, else about y = 0), so that the page's lower-left corner is the
    origin and the drawing reads the right way up.

    Parameters
    ----------
    path : str or os.PathLike
        The SVG file.
    scale : float, optional
        Metres per user unit, overriding the document's units.

    Returns
    -------
    Layer
        One contour per subpath, in document order; ``source`` is the file name.

    Raises
    ------
    ValueError
        If the file is not SVG/XML, has a malformed ``viewBox``, ``width`` or
        ``transform``, a ``<path>`` has malformed data, geometry reaches beyond
        `~microfab.geometry.layer.MAX_COORDINATE_M` (the message names the element), or
        nothing in it is importable geometry.
    """
    fname = os.fspath(path)
    try:
        root = ET.parse(fname).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"{fname}: not a well-formed SVG/XML file: {exc}") from exc
    if _local(root.tag) != "svg":
        raise ValueError(f"{fname}: the root element is <{_local(root.tag)}>, not <svg>")
    unit, vb = _user_unit(root)
    s = check_positive("scale", scale, "m per user unit") if scale is not None else unit
    x0 = vb[0] if vb else 0.0
    if vb is not None:
        y_bottom = vb[1] + vb[3]
    else:
        h = _length(root.get("height"))
        y_bottom = h[0] if h is not None and h[1] in ("", "px") else 0.0
    # user (x, y) -> ((x - x0) s, (y_bottom - y) s)
    page_A = np.diag([s, -s])
    page_b = np.array([-x0 * s, y_bottom * s])

    contours: list[Path] = []
    skipped: list[Skipped] = []
    counter = {"n": 0}

    def ref_of(el: ET.Element, tag: str) -> str:
        counter["n"] += 1
        ident = el.get("id")
        return f"<{tag} id={ident!r}>" if ident else f"<{tag}> #{counter['n']}"

    def walk(el: ET.Element, tf: np.ndarray) -> None:
        for child in el:
            tag = _local(child.tag)
            if not tag or tag in _NOT_RENDERED:
                continue
            ref = ref_of(child, tag)
            try:
                with np.errstate(over="ignore", invalid="ignore"):  # checked just below
                    ctf = tf @ parse_transform(child.get("transform"), strict=True)
            except ValueError as exc:
                raise ValueError(f"{fname}: {ref}: malformed transform: {exc}") from exc
            if not np.all(np.isfinite(ctf)):
                raise ValueError(
                    f"{fname}: {ref}: transform {child.get('transform')!r} overflows "
                    "(with the transforms around it)"
                )
            if tag in _CONTAINERS:
                walk(child, ctf)
            elif tag in _SHAPES:
                try:
                    d = _TO_D[tag](child)
                except ValueError as exc:
                    skipped.append(Skipped(tag, str(exc), ref))
                    continue
                with np.errstate(over="ignore", invalid="ignore"):  # _parse_d bounds them
                    A = page_A @ ctf[:2, :2]
                    b = page_A @ ctf[:2, 2] + page_b
                try:
                    c, sk = _parse_d(d, A, b, ref)
                except ValueError as exc:
                    if tag == "path" or isinstance(exc, _ExtentError):
                        raise ValueError(f"{fname}: {exc}") from exc
                    skipped.append(Skipped(tag, str(exc), ref))
                    continue
                contours.extend(c)
                skipped.extend(sk)
            elif tag == "svg":
                skipped.append(Skipped(tag, "nested <svg> viewports are not supported", ref))
            else:
                skipped.append(Skipped(tag, f"<{tag}> is not geometry this reader takes", ref))

    walk(root, np.eye(3))
    name = FsPath(fname).name
    if not contours:
        counts = Counter(sk.kind for sk in skipped)
        what = ", ".join(f"{n} {kind}" for kind, n in sorted(counts.items())) or (
            "nothing (the drawing is empty)"
        )
        raise ValueError(f"{name}: no importable geometry; skipped: {what}")
    return Layer(tuple(contours), tuple(skipped), source=name)
