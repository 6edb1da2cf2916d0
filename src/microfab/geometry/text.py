"""Text outlines as exact contours, from the fonts matplotlib ships.

A glyph outline is a chain of straight lines and quadratic (TrueType) or cubic
(PostScript/CFF) Bézier curves; :class:`matplotlib.textpath.TextPath` lays the text out and
returns them, and each becomes an exact :class:`~microfab.geometry.segments.LineSegment` or
:class:`~microfab.geometry.segments.CurveSegment` (Bézier → Chebyshev conversion is exact).
Each distinct outline is converted (and flattened, boxed, measured) once and every other
occurrence of it is a shifted copy, so that a long text costs little more than its
distinct glyphs (800 characters "ABAB…": 40 s when every glyph was converted, 0.4 s).
"""

from __future__ import annotations

import itertools

import numpy as np
from matplotlib.font_manager import FontProperties, findfont, get_font
from matplotlib.path import Path as MplPath
from matplotlib.textpath import TextPath, text_to_path

from microfab.core.validate import check_in_range
from microfab.geometry.layer import MAX_COORDINATE_M, Layer
from microfab.geometry.path import Path
from microfab.geometry.segments import CurveSegment, LineSegment, Segment

__all__ = ["SEED002_LETTERS", "letters_seed002", "text_layer"]

SEED002_LETTERS = ("u", "r", "c", "h")
"""The letters test case of seed 002 §II-C: "u", "r", "c", "h" of the ETH Zürich logo."""


def _placed(mpl: MplPath, k: float, shift: np.ndarray) -> list[tuple[Path, np.ndarray]]:
    """Closed contours of a matplotlib path, mapped by ``p -> k p + shift``, as templates.

    A text repeats its glyphs: each distinct outline (from one MOVETO to the next, the
    same codes and the same vertices relative to its first one, exactly) is made into
    exact segments once (:func:`_contours`), relative to its first vertex, with its
    polyline, box, area and midpoint computed; an occurrence is that template and where
    it goes.

    Returns
    -------
    list of (Path, numpy.ndarray)
        Template (shared by the occurrences of one outline) and its shift, shape (2,), m,
        for each contour, in the path's order.
    """
    verts = np.asarray(mpl.vertices, dtype=float)
    codes = np.asarray(mpl.codes)
    starts = np.flatnonzero(codes == MplPath.MOVETO)
    bounds = np.unique(np.r_[0, starts, codes.size])
    templates: dict[tuple[bytes, bytes], list[Path]] = {}
    out: list[tuple[Path, np.ndarray]] = []
    for a, b in itertools.pairwise(bounds.tolist()):
        c, v = codes[a:b], verts[a:b]
        rel = v - v[0]
        rel[c == MplPath.CLOSEPOLY] = 0.0  # a CLOSEPOLY's vertex means nothing
        key = (c.tobytes(), rel.tobytes())
        if key not in templates:
            templates[key] = [_computed(p) for p in _contours(MplPath(rel, c), k, np.zeros(2))]
        d = k * v[0] + shift
        out.extend((p, d) for p in templates[key])
    return out


def _computed(path: Path) -> Path:
    """``path`` with what `Layer` and ``path show`` ask of a contour computed (and cached).

    Its polyline, box, area and probe point, which `Path._shifted` then carries to every
    copy of it.
    """
    path.flatten()
    _ = path.bbox, path.signed_area, path.first_midpoint
    return path


def _contours(mpl: MplPath, k: float, shift: np.ndarray) -> list[Path]:
    """Closed contours of a matplotlib path, mapped by ``p -> k p + shift``."""
    out: list[Path] = []
    segs: list[Segment] = []
    first = cur = None

    def close() -> None:
        nonlocal segs
        if segs:
            assert first is not None and cur is not None
            if np.any(cur != first):
                segs.append(LineSegment(cur, first))
            kept = [s for s in segs if s.length > 0]
            # FreeType leaves zero-length stub contours (a moveto and a lineto to the same
            # point); they draw nothing and are dropped
            if kept:
                out.append(Path(tuple(kept), closed=True))
        segs = []

    for verts, code in mpl.iter_segments(simplify=False, curves=True):
        v = k * np.asarray(verts, dtype=float).reshape(-1, 2) + shift
        if code == MplPath.MOVETO:
            close()
            first = cur = v[-1]
        elif code == MplPath.LINETO:
            segs.append(LineSegment(cur, v[0]))
            cur = v[0]
        elif code in (MplPath.CURVE3, MplPath.CURVE4):
            segs.append(CurveSegment.from_bezier(np.vstack([cur, v])))
            cur = v[-1]
        elif code == MplPath.CLOSEPOLY:
            close()
            cur = first
        else:  # pragma: no cover - TextPath emits only the codes above
            raise ValueError(f"unexpected matplotlib path code {code}")
    close()  # an outline left open is closed by a straight segment
    return out


def text_layer(
    text: str,
    *,
    height: float = 0.01,
    font: str = "DejaVu Sans",
    weight: str = "normal",
) -> Layer:
    """Outlines of ``text`` set in a font matplotlib can find, as closed contours.

    Parameters
    ----------
    text : str
        The text, one line (no layout beyond matplotlib's: a newline is not a line break).
    height : float
        Font size, m: the height of the font's em square, the usual typographic size. A
        glyph is smaller than that: in DejaVu Sans a capital letter is 0.729 ``height``
        tall, a lower-case "x" 0.547 ``height``, and the glyph box of the text is
        ``height`` × (its ink extent in em units); outlines scale linearly with it.
        matplotlib delivers outline coordinates on a grid of 1/6400 em (FreeType 26.6
        fixed point at its internal size 100), i.e. to within ``height / 6400``. At most
        `~microfab.geometry.layer.MAX_COORDINATE_M`.
    font : str
        Font family name, e.g. ``"DejaVu Sans"`` (bundled with matplotlib, always there)
        or ``"DejaVu Serif"``.
    weight : str
        Font weight: ``"normal"``, ``"bold"``, ``"light"``, …

    Returns
    -------
    Layer
        The glyph contours, closed, each outer boundary followed by its holes (the
        counter of an "o"); oriented with outer boundaries counter-clockwise and holes
        clockwise (:meth:`~microfab.geometry.layer.Layer.oriented`); translated so that
        the lower-left corner of the text's bounding box (ink, not advance box) is the
        origin. ``source`` is the text.

    Raises
    ------
    ValueError
        If the text has no visible outline (empty or blank), holds a control character or
        a character the font lacks, ``height`` is not a positive length, or the font is
        not found.
    """
    if not isinstance(text, str):
        raise TypeError(f"text must be a string, got {type(text).__name__}")
    if not text.strip():
        raise ValueError(f"text {text!r} has no visible characters; give at least one glyph")
    h = check_in_range("text height", height, 0.0, MAX_COORDINATE_M, "m", low_closed=False)
    prop = FontProperties(family=font, weight=weight)
    try:
        ft = get_font(findfont(prop, fallback_to_default=False))
    except ValueError as exc:
        raise ValueError(f"font {font!r} (weight {weight!r}) not found: {exc}") from exc
    for ch in text:
        # a glyph the font lacks would be drawn as a placeholder box (dozens of contours)
        if not ch.isprintable() or (not ch.isspace() and ft.get_char_index(ord(ch)) == 0):
            what = "not a printable character" if not ch.isprintable() else f"not in font {font!r}"
            raise ValueError(
                f"text {text!r}: character {ch!r} (U+{ord(ch):04X}) is {what}; "
                "give letters the font has"
            )
    # at size FONT_SCALE matplotlib's outline comes unscaled: font units on its grid,
    # where two copies of a glyph are the same numbers relative to their first vertex
    tp = TextPath((0.0, 0.0), text, size=text_to_path.FONT_SCALE, prop=prop)
    if len(tp.vertices) == 0:
        raise ValueError(f"text {text!r} has no outline in font {font!r}")
    k = h / text_to_path.FONT_SCALE
    ext = tp.get_extents()  # exact: Bézier extrema, not the control polygon
    shift = -k * np.array([ext.x0, ext.y0])
    placed = _placed(tp, k, shift)
    if not placed:
        raise ValueError(f"text {text!r} has no outline in font {font!r}")
    layer = Layer(tuple(t._shifted(d) for t, d in placed), (), source=text)
    # outer boundaries counter-clockwise, holes clockwise (`Layer.oriented`), a contour
    # turned round as its template is, once per template
    depth = layer.depth
    turned: dict[int, Path] = {}
    out = []
    for i in _outer_first(layer):
        (template, d), c = placed[i], layer[i]
        if depth[i] >= 0 and template.orientation != ("ccw" if depth[i] % 2 == 0 else "cw"):
            if id(template) not in turned:
                turned[id(template)] = _computed(template.reversed())
            c = turned[id(template)]._shifted(d)
        out.append(c)
    return Layer(tuple(out), (), source=text)


def _outer_first(layer: Layer) -> list[int]:
    """The contours' order depth-first: each outer boundary followed by its holes (and islands).

    Fonts list a glyph's contours in any order (DejaVu's "o" gives the hole first). Every
    glyph contour is closed, so the containing contours are those of
    :attr:`Layer.containers <microfab.geometry.layer.Layer.containers>`.
    """
    depth = layer.depth
    keys = [(*sorted(anc, key=lambda j: depth[j]), i) for i, anc in enumerate(layer.containers)]
    return sorted(range(len(layer)), key=lambda i: keys[i])


def letters_seed002(height: float = 0.01) -> dict[str, Layer]:
    """The letters "u", "r", "c", "h" of seed 002 §II-C (the "letters" test case).

    The seed takes the four letters from the ETH Zürich logo, whose typeface is not
    available here; DejaVu Sans (bundled with matplotlib) stands in. Each letter is a
    single closed contour with sharp corners, straight segments and curves of varying
    curvature, which is what the test case is for (seed 002 §II-C).

    Parameters
    ----------
    height : float
        Font size, m (see :func:`text_layer`).

    Returns
    -------
    dict of str to Layer
        One layer per letter, each with its lower-left ink corner at the origin.
    """
    return {ch: text_layer(ch, height=height) for ch in SEED002_LETTERS}
