"""Hypothesis strategies for bad (and some good) inputs of every kind a user hands microfab.

Each kind is a strategy of `fuzz_driver.Case`: the files of one working folder and the
``microfab`` command that reads them.

========  =====================================================  ==========================
kind      input                                                  command
========  =====================================================  ==========================
dxf       DXF drawings: built from random entities (NaN, huge,   ``path show``, a few
          zero-length, self-intersecting), ezdxf documents cut,  ``trajectory``
          mutated or binary, random bytes
svg       SVG files: random elements, path data, transforms      ``path show``, a few
          (``scale(1e308)``), viewBoxes; cut, mutated, empty     ``trajectory``
dat       Selig / Lednicer airfoil files                         ``path show``
shape     shape, text and airfoil specifications, chord, height  ``path show``
traj      ``trajectory`` options (limits, rate, grid, contour)   ``trajectory``
job       job TOML files (wrong types, unknown keys, negative,   ``run --check``
          zero, NaN, 1e308), cut or mutated
trial     trial files (CSV, MAT, HDF5): NaN, wrong lengths,      ``ilc step`` (first call,
          missing or odd columns, non-uniform or decreasing      or on a saved state)
          time, wrong sample rate, empty, short periods
droplet   ``droplet simulate`` and ``droplet sweep`` options     ``droplet simulate|sweep``
frames    camera frames (PNG, TIFF: cut, junk, sizes that        ``droplet analyze``
          differ, noise) and their ``frames.json``
========  =====================================================  ==========================

The seed 003 part 2 kinds (``identify-chirp``, ``shaper-design``, ``slm-scan-time``) are
in `fuzz_slm`, registered in `KINDS` at the end of this module.

Accepted cases are kept cheap: droplet durations that pass are a few µs, trajectory grids
small.
"""

from __future__ import annotations

import functools
import io
import math
import re
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from fuzz_driver import Case
from hypothesis import strategies as st

__all__ = ["BASE_TRIAL_FILE", "KINDS", "base_trial_csv"]

SENTINEL = b"previous content: a refused command must leave this file as it was\n"

# --------------------------------------------------------------------------- numbers
SPECIAL_TEXT = (
    "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e308", "-1e308",
    "1.7976931348623157e308", "1e400", "-1e400", "1e-308", "5e-324", "0", "-0", "0.0",
    "1e12", "-1e12", "1e-12", "1e6", "-1", "1", "2.5", "", " ", "abc", "1,5", "0x10",
    "1e", "--1", "1_000",
)  # fmt: skip
SPECIAL_FLOATS = (
    math.nan, math.inf, -math.inf, 1e308, -1e308, 1.7976931348623157e308, 1e-308, 5e-324,
    0.0, -0.0, 1e12, -1e12, 1e-12, -1.0, 1.0, 1e6, 1e-6,
)  # fmt: skip


def floats_any() -> st.SearchStrategy[float]:
    """Floats from everywhere, special values often."""
    return st.one_of(
        st.sampled_from(SPECIAL_FLOATS),
        st.floats(allow_nan=True, allow_infinity=True),
        st.floats(-1e3, 1e3),
    )


def num_text(reasonable: st.SearchStrategy[float] | None = None) -> st.SearchStrategy[str]:
    """The text of a number: reasonable values, special values, or not a number at all."""
    parts = [
        st.sampled_from(SPECIAL_TEXT),
        floats_any().map(repr),
        st.integers(-(10**6), 10**6).map(str),
    ]
    if reasonable is not None:
        parts = [reasonable.map(lambda x: f"{x:.6g}")] * 3 + parts
    return st.one_of(parts)


def fmt(x: float) -> str:
    """A float as a file would hold it (``nan``, ``inf`` spelled out)."""
    return repr(float(x))


# --------------------------------------------------------------------------- bytes
_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


@st.composite
def mutated(draw: st.DrawFn, base: bytes, max_mutations: int = 3) -> tuple[bytes, str]:
    """``base`` with 1 to ``max_mutations`` random edits; returns (bytes, what was done)."""
    data = bytearray(base)
    notes = []
    for _ in range(draw(st.integers(1, max_mutations))):
        op = draw(
            st.sampled_from(
                (
                    "cut",
                    "cut_line",
                    "drop_line",
                    "dup_line",
                    "junk_line",
                    "number",
                    "insert",
                    "flip",
                    "append",
                )
            )
        )
        lines = bytes(data).split(b"\n")
        if op == "cut":
            k = draw(st.integers(0, len(data)))
            data = data[:k]
        elif op == "cut_line":
            k = draw(st.integers(0, len(lines)))
            data = bytearray(b"\n".join(lines[:k]) + (b"\n" if draw(st.booleans()) else b""))
        elif op in ("drop_line", "dup_line", "junk_line") and lines:
            k = draw(st.integers(0, len(lines) - 1))
            if op == "drop_line":
                del lines[k]
            elif op == "dup_line":
                lines.insert(k, lines[k])
            else:
                lines[k] = draw(
                    st.one_of(
                        st.sampled_from(SPECIAL_TEXT).map(str.encode),
                        st.binary(max_size=20),
                        st.text(max_size=20).map(lambda s: s.encode("utf-8", "surrogatepass")),
                    )
                )
            data = bytearray(b"\n".join(lines))
        elif op == "number":
            found = list(_NUMBER.finditer(bytes(data)))
            if found:
                m = found[draw(st.integers(0, len(found) - 1))]
                new = draw(st.sampled_from(SPECIAL_TEXT)).encode()
                data[m.start() : m.end()] = new
        elif op == "insert":
            k = draw(st.integers(0, len(data)))
            data[k:k] = draw(st.binary(min_size=1, max_size=16))
        elif op == "flip" and data:
            k = draw(st.integers(0, len(data) - 1))
            data[k] ^= draw(st.integers(1, 255))
        elif op == "append":
            data += draw(st.binary(min_size=1, max_size=64))
        notes.append(op)
    return bytes(data), "+".join(notes)


def junk_bytes() -> st.SearchStrategy[bytes]:
    """Random bytes, empty files and text that is no format at all."""
    return st.one_of(
        st.just(b""),
        st.binary(max_size=300),
        st.text(max_size=200).map(lambda s: s.encode("utf-8", "surrogatepass")),
        st.sampled_from((b"\x00" * 64, b"\xff\xfe\x00\x00", b"\n\n\n", b"PK\x03\x04junk")),
    )


# --------------------------------------------------------------------------- DXF
def _tags(pairs: Sequence[tuple[int, str]]) -> str:
    return "".join(f"{c:>3}\n{v}\n" for c, v in pairs)


def _coord(reasonable: float = 50.0, clean: bool = False) -> st.SearchStrategy[str]:
    good = st.floats(-reasonable, reasonable, allow_nan=False)
    return good.map(lambda x: f"{x:.6g}") if clean else num_text(good)


def _num(low: float, high: float, clean: bool) -> st.SearchStrategy[str]:
    good = st.floats(low, high)
    return good.map(lambda x: f"{x:.6g}") if clean else num_text(good)


@st.composite
def _dxf_entity(draw: st.DrawFn, clean: bool = False) -> list[tuple[int, str]]:
    kind = draw(
        st.sampled_from(("LINE", "CIRCLE", "ARC", "LWPOLYLINE", "POINT", "TEXT", "ELLIPSE"))
    )
    head = [(0, kind), (5, f"{draw(st.integers(16, 4096)):X}"), (100, "AcDbEntity"), (8, "0")]
    c = _coord(clean=clean)
    if kind == "LINE":
        x0, y0 = draw(c), draw(c)
        same = draw(st.booleans())  # zero length half of the time
        x1, y1 = (x0, y0) if same else (draw(c), draw(c))
        z1 = draw(st.sampled_from(("0", "0", "1", "nan")))
        line = [(100, "AcDbLine"), (10, x0), (20, y0), (30, "0"), (11, x1), (21, y1), (31, z1)]
        return [*head, *line]
    if kind in ("CIRCLE", "ARC"):
        out = [*head, (100, "AcDbCircle"), (10, draw(c)), (20, draw(c)), (30, "0")]
        out.append((40, draw(_num(0.01, 50, clean))))
        if draw(st.booleans()):
            out += [(210, draw(c)), (220, draw(c)), (230, draw(st.sampled_from(("1", "-1", "0"))))]
        if kind == "ARC":
            ang = _num(-720, 720, clean)
            out += [(100, "AcDbArc"), (50, draw(ang)), (51, draw(ang))]
        return out
    if kind == "LWPOLYLINE":
        n = draw(st.integers(0, 8))
        pts = draw(st.lists(st.tuples(c, c), min_size=n, max_size=n))
        if pts and draw(st.booleans()):  # a bow tie: self-intersecting
            pts = [("0", "0"), ("10", "10"), ("10", "0"), ("0", "10")]
        out = [*head, (100, "AcDbPolyline"), (90, str(draw(st.integers(-1, 10)))), (70, "1")]
        for x, y in pts:
            out += [(10, x), (20, y)]
            if draw(st.integers(0, 3)) == 0:
                out.append((42, draw(_num(-2, 2, clean))))
        return out
    if kind == "ELLIPSE":
        return [
            *head,
            (100, "AcDbEllipse"),
            (10, draw(c)),
            (20, draw(c)),
            (30, "0"),
            (11, draw(c)),
            (21, draw(c)),
            (31, "0"),
            (40, draw(_num(0.01, 1, clean))),
            (41, draw(_num(0, 7, clean))),
            (42, draw(_num(0, 7, clean))),
        ]
    if kind == "POINT":
        return [*head, (100, "AcDbPoint"), (10, draw(c)), (20, draw(c)), (30, "0")]
    return [*head, (100, "AcDbText"), (10, draw(c)), (20, draw(c)), (40, "1"), (1, "hello")]


@st.composite
def dxf_built(draw: st.DrawFn) -> tuple[bytes, str]:
    """A DXF written tag by tag from random entities and a random ``$INSUNITS``."""
    units = draw(st.sampled_from(("4", "4", "1", "6", "13", "0", "99", "-1", "abc", None)))
    head = [(0, "SECTION"), (2, "HEADER"), (9, "$ACADVER"), (1, "AC1015")]
    if units is not None:
        head += [(9, "$INSUNITS"), (70, units)]
    head += [(0, "ENDSEC")]
    clean = draw(st.booleans())  # numbers all reasonable: most such drawings are read
    ents = draw(st.lists(_dxf_entity(clean), max_size=6))
    body = [(0, "SECTION"), (2, "ENTITIES")]
    for e in ents:
        body += e
    body += [(0, "ENDSEC"), (0, "EOF")]
    kinds = ", ".join(e[0][1] for e in ents)
    note = f"built{' clean' if clean else ''}: units {units}, {len(ents)} entities ({kinds})"
    return _tags(head + body).encode(), note


@functools.cache
def dxf_documents() -> tuple[tuple[str, bytes], ...]:
    """A few ezdxf documents (text and binary), the bases that get cut and mutated."""
    import tempfile
    from pathlib import Path

    import ezdxf

    out = []
    with tempfile.TemporaryDirectory() as tmp:
        d = ezdxf.new("R2010")
        d.header["$INSUNITS"] = 4
        d.modelspace().add_lwpolyline([(0, 0), (10, 0), (10, 10), (0, 10)], close=True)
        out.append(("square", d))
        d = ezdxf.new("R2018")
        d.header["$INSUNITS"] = 4
        m = d.modelspace()
        m.add_line((0, 0), (5, 0))
        m.add_line((5, 0), (5, 5))
        m.add_line((5, 5), (0, 0))
        m.add_arc((20, 0), 3, 0, 180)
        m.add_circle((40, 0), 2)
        m.add_lwpolyline([(0, 20, 0), (10, 20, 0.5), (10, 30, 0), (0, 30, 0)], format="xyb")
        m.add_spline_control_frame([(0, 40), (5, 45), (10, 40), (15, 45)])
        m.add_ellipse((30, 30), major_axis=(5, 0), ratio=0.5)
        m.add_text("hi")
        m.add_point((1, 1))
        blk = d.blocks.new("B")
        blk.add_circle((0, 0), 1)
        m.add_blockref("B", (50, 50), dxfattribs={"xscale": 2, "yscale": 1, "rotation": 30})
        out.append(("mixed", d))
        d = ezdxf.new("R12")
        d.modelspace().add_line((0, 0), (1, 1))
        d.modelspace().add_circle((0, 0), 1)
        out.append(("r12-unitless", d))
        docs = []
        for name, doc in out:
            p = Path(tmp) / f"{name}.dxf"
            doc.saveas(p)
            docs.append((name, p.read_bytes()))
            if name == "square":
                doc.saveas(p, fmt="bin")
                docs.append((f"{name}-binary", p.read_bytes()))
    return tuple(docs)


@st.composite
def dxf_file(draw: st.DrawFn) -> tuple[bytes, str]:
    """Bytes of a DXF file, good or bad, and what was done."""
    how = draw(st.sampled_from(("built", "built", "built_mutated", "doc", "doc", "junk")))
    if how.startswith("built"):
        data, note = draw(dxf_built())
        if how == "built_mutated":
            data, more = draw(mutated(data))
            note += f"; {more}"
        return data, note
    if how == "doc":
        name, base = draw(st.sampled_from(dxf_documents()))
        if draw(st.integers(0, 9)) == 0:
            return base, f"ezdxf {name} as written"
        if draw(st.booleans()) and b"$INSUNITS" in base and not name.endswith("binary"):
            # cut right around the $INSUNITS header value (the reported StopIteration)
            i = base.index(b"$INSUNITS")
            k = draw(st.integers(i, min(i + 40, len(base))))
            return base[:k], f"ezdxf {name} cut {k - i} bytes after $INSUNITS"
        data, note = draw(mutated(base))
        return data, f"ezdxf {name} {note}"
    return draw(junk_bytes()), "junk"


@st.composite
def dxf_case(draw: st.DrawFn) -> Case:
    """A DXF through ``path show`` (mostly) or ``trajectory``."""
    data, note = draw(dxf_file())
    argv: list[str]
    if draw(st.integers(0, 9)) == 0:
        argv = [*_TRAJ_ARGS, "part.dxf"]
    else:
        argv = ["path", "show", "part.dxf", "--out", "part.png"]
        if draw(st.booleans()):
            argv.append("--json")
    if draw(st.integers(0, 3)) == 0:
        argv += ["--units", draw(st.sampled_from(("mm", "inch", "um", "furlong", "", "MM")))]
    return Case("dxf", tuple(argv), (("part.dxf", data), *_OUTPUTS), note=note)


_TRAJ_ARGS = ("trajectory", "--speed", "0.05", "--amax", "1e9", "--rate", "2000")
_TRAJ_ARGS = (*_TRAJ_ARGS, "--out", "ref.csv")
#: Outputs of a previous run, which a refusal must leave as they are.
_OUTPUTS = (
    ("part.png", SENTINEL),
    ("ref.csv", SENTINEL),
    ("ref_profile.png", SENTINEL),
)


# --------------------------------------------------------------------------- SVG
_TRANSFORMS = (
    "scale({a})",
    "scale({a},{b})",
    "translate({a},{b})",
    "rotate({a})",
    "rotate({a},{b},{b})",
    "skewX({a})",
    "matrix({a} 0 0 {b} {a} {b})",
    "matrix({a},{b},{b},{a},0,0)",
    "scale(",
    "wobble(2)",
    "",
)


@st.composite
def _transform(draw: st.DrawFn, clean: bool = False) -> str:
    n = draw(st.integers(1, 2))
    parts = []
    for _ in range(n):
        t = draw(st.sampled_from(_TRANSFORMS[:8] if clean else _TRANSFORMS))
        a = draw(_num(0.2, 3, clean))
        b = draw(_num(-3, 3, clean))
        parts.append(t.format(a=a, b=b))
    return " ".join(parts)


_PATH_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7, "Z": 0}


@st.composite
def _path_data(draw: st.DrawFn, clean: bool = False) -> str:
    c = _num(-100, 100, clean)
    out = []
    if draw(st.integers(0, 5)):
        out.append(f"M {draw(c)} {draw(c)}")
    for _ in range(draw(st.integers(0, 8))):
        cmd = draw(st.sampled_from(sorted(_PATH_ARGS)))
        cmd = cmd.lower() if draw(st.booleans()) else cmd
        n = _PATH_ARGS[cmd.upper()]
        if not clean and draw(st.integers(0, 7)) == 0:
            n = draw(st.integers(0, 8))  # a wrong number of arguments
        args = [draw(c) for _ in range(n)]
        if cmd.upper() == "A" and len(args) == 7:
            args[3] = draw(st.sampled_from(("0", "1", "2", "-1")))
            args[4] = draw(st.sampled_from(("0", "1", "x")))
        out.append(cmd + " " + " ".join(args))
    if draw(st.booleans()):  # zero-length and self-intersecting pieces
        out.append(draw(st.sampled_from(("L 0 0 L 0 0", "M 0 0 L 10 10 L 10 0 L 0 10 Z", "Z"))))
    return " ".join(out)


@st.composite
def _svg_element(draw: st.DrawFn, depth: int = 0, clean: bool = False) -> str:
    tags = ["path", "path", "rect", "circle", "ellipse", "line", "polyline", "polygon", "text"]
    tags += ["use", "svg", "defs"] + (["g", "g"] if depth < 2 else [])
    tag = draw(st.sampled_from(tags))
    c = _num(-50, 100, clean)
    attrs: dict[str, str] = {}
    if draw(st.integers(0, 3)) == 0:
        attrs["transform"] = draw(_transform(clean))
    if tag == "path":
        attrs["d"] = draw(_path_data(clean))
    elif tag == "rect":
        for k in ("x", "y", "width", "height", "rx"):
            if draw(st.integers(0, 5)):
                attrs[k] = draw(c)
    elif tag in ("circle", "ellipse"):
        keys = ("cx", "cy", "r") if tag == "circle" else ("cx", "cy", "rx", "ry")
        for k in keys:
            if draw(st.integers(0, 5)):
                attrs[k] = draw(c)
    elif tag == "line":
        for k in ("x1", "y1", "x2", "y2"):
            attrs[k] = draw(c)
    elif tag in ("polyline", "polygon"):
        attrs["points"] = " ".join(draw(c) for _ in range(draw(st.integers(0, 10))))
    inner = ""
    if tag in ("g", "svg", "defs"):
        kids = draw(st.lists(_svg_element(depth + 1, clean), max_size=3))
        inner = "".join(kids)
    elif tag == "text":
        inner = "hello"
    a = "".join(f' {k}="{v}"' for k, v in attrs.items())
    return f"<{tag}{a}>{inner}</{tag}>"


@st.composite
def svg_built(draw: st.DrawFn) -> tuple[bytes, str]:
    """An SVG document from random elements and root attributes."""
    root: dict[str, str] = {}
    clean = draw(st.booleans())  # numbers all reasonable: most such drawings are read
    if draw(st.booleans()):
        w = draw(_num(1, 200, clean))
        root["width"] = w + draw(st.sampled_from(("mm", "", "px", "in", "%", "furlong", "cm")))
    if draw(st.booleans()):
        root["height"] = draw(_num(1, 200, clean))
    if draw(st.booleans()):
        n = 4 if clean else draw(st.integers(3, 5))
        vb = [draw(_num(1, 200, clean)) for _ in range(n)]
        root["viewBox"] = " ".join(vb)
    kids = draw(st.lists(_svg_element(0, clean), max_size=5))
    a = "".join(f' {k}="{v}"' for k, v in root.items())
    text = f'<svg xmlns="http://www.w3.org/2000/svg"{a}>{"".join(kids)}</svg>'
    note = f"built{' clean' if clean else ''}: {len(kids)} elements"
    return text.encode("utf-8", "surrogatepass"), note


_SVG_BASES = (
    b'<svg xmlns="http://www.w3.org/2000/svg" width="20mm" height="20mm" viewBox="0 0 20 20">'
    b'<path d="M 2 2 L 18 2 L 18 18 L 2 18 Z"/><circle cx="10" cy="10" r="4"/>'
    b'<g transform="rotate(30 10 10)"><rect x="5" y="5" width="4" height="3" rx="1"/></g>'
    b"</svg>",
    b'<svg xmlns="http://www.w3.org/2000/svg"><g transform="scale(1e308)">'
    b'<path d="M 0 0 L 100 0 L 100 100 Z"/></g></svg>',
    b'<svg xmlns="http://www.w3.org/2000/svg"></svg>',
    b'<svg xmlns="http://www.w3.org/2000/svg"><text>only text</text></svg>',
    b"<?xml version='1.0'?><svg xmlns='http://www.w3.org/2000/svg'>"
    b"<path d='M0 0 C 10 20 30 -20 40 0 A 5 5 0 1 1 50 0'/></svg>",
)


@st.composite
def svg_case(draw: st.DrawFn) -> Case:
    """An SVG through ``path show`` (mostly) or ``trajectory``."""
    how = draw(st.sampled_from(("built", "built", "built_mutated", "base", "base_mutated", "junk")))
    if how.startswith("built"):
        data, note = draw(svg_built())
    elif how.startswith("base"):
        data = draw(st.sampled_from(_SVG_BASES))
        note = f"base {data[:60]!r}"
    else:
        data, note = draw(junk_bytes()), "junk"
    if how.endswith("mutated"):
        data, more = draw(mutated(data))
        note += f"; {more}"
    if draw(st.integers(0, 9)) == 0:
        argv = (*_TRAJ_ARGS, "part.svg")
    else:
        argv = ("path", "show", "part.svg", "--out", "part.png")
    return Case("svg", argv, (("part.svg", data), *_OUTPUTS), note=note)


# --------------------------------------------------------------------------- airfoils
@functools.cache
def _e344() -> bytes:
    from importlib import resources

    return resources.files("microfab.data").joinpath("airfoils", "e344.dat").read_bytes()


@st.composite
def dat_case(draw: st.DrawFn) -> Case:
    """A Selig or Lednicer airfoil file through ``path show``."""
    how = draw(st.sampled_from(("e344", "mutated", "points", "lednicer", "junk")))
    if how == "e344":
        data, note = _e344(), "e344 as shipped"
    elif how == "mutated":
        data, note = draw(mutated(_e344()))
    elif how == "points":
        c = num_text(st.floats(-0.1, 1.1))
        rows = draw(st.lists(st.tuples(c, c), max_size=12))
        name = draw(st.sampled_from(("NACA", "", "1 2 3", "airfoil")))
        data = (name + "\n" + "\n".join(f"{x} {y}" for x, y in rows)).encode()
        note = f"{len(rows)} random points"
    elif how == "lednicer":
        nu, nl = draw(num_text(st.integers(2, 5).map(float))), draw(num_text())
        body = "\n".join(f"{x / 4:g} {0.05 * (-1) ** x:g}" for x in range(6))
        data = f"LEDNICER\n{nu} {nl}\n{body}\n".encode()
        note = f"Lednicer counts {nu} {nl}"
    else:
        data, note = draw(junk_bytes()), "junk"
    argv = ["path", "show", "wing.dat", "--out", "part.png"]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--chord", draw(num_text(st.floats(0.001, 1)))]
    return Case("dat", tuple(argv), (("wing.dat", data), *_OUTPUTS), note=note)


# --------------------------------------------------------------------------- shapes
_SHAPE_ARGS = {
    "rectangle": {"width": "0.02", "height": "0.01", "corner_radius": "0.002"},
    "square": {"side": "0.01", "corner_radius": "0.001"},
    "circle": {"radius": "0.005", "theta0": "0.3"},
    "polygon": {"n_sides": "6", "radius": "0.01", "theta0": "0"},
    "spiral": {"b": "0.001", "theta0": "0", "theta1": "12"},
    "ellipse": {"a": "0.01", "b": "0.004", "angle": "0.5"},
    "lissajous": {"ax": "0.01", "ay": "0.008", "fx": "3", "fy": "2", "phase": "1.5"},
    "butterfly": {"scale": "0.003"},
}
_SHAPE_BAD = (
    *SPECIAL_TEXT,
    *("1e7", "1e9", "1e12", "1e300", "100001", "1001", "3.5", "2", "-3", "1e-300", "7"),
)


@st.composite
def shape_case(draw: st.DrawFn) -> Case:
    """A shape, text or airfoil specification through ``path show``."""
    how = draw(st.sampled_from(("shape", "shape", "shape", "text", "airfoil", "other")))
    argv = ["path", "show"]
    if how == "shape":
        name = draw(st.sampled_from([*_SHAPE_ARGS, "blob", "CIRCLE"]))
        args = dict(_SHAPE_ARGS.get(name.lower(), {"radius": "0.01"}))
        keys = sorted(args)
        for k in draw(st.lists(st.sampled_from(keys), max_size=len(keys), unique=True)):
            del args[k]  # the defaults, or a missing required argument
        for _ in range(draw(st.integers(0, 2))):
            key = draw(st.sampled_from([*keys, "bogus", ""]))
            args[key] = draw(st.one_of(st.sampled_from(_SHAPE_BAD), num_text()))
        pairs = [f"{k}={v}" for k, v in args.items()]
        if draw(st.integers(0, 7)) == 0:
            pairs.append(draw(st.sampled_from(("radius", "=", ",,", "radius==1"))))
        spec = name + (":" + ",".join(pairs) if pairs or draw(st.booleans()) else "")
    elif how == "text":
        spec = "text:" + draw(
            st.one_of(
                st.text(max_size=12),
                st.sampled_from(("urch", " ", "", "\u200b", "😀", "\x00", "\n")),
            )
        )
        if draw(st.booleans()):
            argv += ["--text-height", draw(num_text(st.floats(1e-4, 0.05)))]
    elif how == "airfoil":
        spec = "airfoil:" + draw(st.sampled_from(("e344", "", "naca0012", "../e344", "E344")))
        if draw(st.booleans()):
            argv += ["--chord", draw(num_text(st.floats(1e-3, 0.5)))]
    else:
        spec = draw(st.one_of(st.text(max_size=20), st.sampled_from(("", ":", "x.dxf", "a.svg"))))
    return Case("shape", (*argv, spec, "--out", "part.png"), _OUTPUTS, note=f"spec {spec!r}")


# --------------------------------------------------------------------------- trajectory
@st.composite
def traj_case(draw: st.DrawFn) -> Case:
    """``trajectory`` with random options on a few small drawings."""
    src = draw(
        st.sampled_from(
            (
                "square:side=0.01,corner_radius=0.002",
                "circle:radius=0.005",
                "text:ab",
                "part.svg",
                "spiral",
            )
        )
    )
    argv = ["trajectory", src]
    mode = draw(st.sampled_from(("speed", "optimal", "both", "none")))
    pos = num_text(st.floats(0.05, 2))  # accepted speeds keep references short
    if mode in ("speed", "both"):
        argv += ["--speed", draw(pos)]
    if mode in ("optimal", "both"):
        argv += ["--time-optimal", "--n-grid", str(draw(st.sampled_from((-1, 0, 9, 10, 40, 80))))]
    opts = {
        "--vmax": pos,
        "--amax": num_text(st.floats(1, 1e6)),
        "--jmax": num_text(st.floats(1e3, 1e9)),
        "--workspace": num_text(st.floats(1e-3, 1)),
        "--feed": pos,
        "--rate": num_text(st.floats(100, 5000)),
        "--contour": st.integers(-3, 5).map(str),
    }
    for opt in draw(st.lists(st.sampled_from(sorted(opts)), max_size=4, unique=True)):
        argv += [opt, draw(opts[opt])]
    if "--rate" not in argv:
        argv += ["--rate", "2000"]  # the default 10 kHz makes long references
    out = draw(st.sampled_from(("ref.csv", "ref.csv", "ref.h5", "ref.mat", "ref.txt", "ref")))
    argv += ["--out", out]
    svg = _SVG_BASES[0]
    files = (("part.svg", svg), *_OUTPUTS)
    return Case("traj", tuple(argv), files, note=f"{mode} on {src}")


# --------------------------------------------------------------------------- job TOML
def _toml_value(x: Any) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(x, int):
        return str(x)
    if isinstance(x, str):
        return '"' + x.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(x, list):
        return "[" + ", ".join(_toml_value(v) for v in x) + "]"
    if isinstance(x, dict):
        return "{" + ", ".join(f'"{k}" = {_toml_value(v)}' for k, v in x.items()) + "}"
    if isinstance(x, _Raw):
        return x.text
    raise TypeError(type(x))


class _Raw:
    """TOML written as is (dates, huge integers)."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _job_schema() -> dict[str, dict[str, tuple[str, ...]]]:
    from microfab.experiments.catalog import JOB_KINDS

    return {
        name: {sec: tuple(k.name for k in keys) for sec, keys in kind.schema.items()}
        for name, kind in JOB_KINDS.items()
    }


def toml_values() -> st.SearchStrategy[Any]:
    """Values of every TOML type, special floats often."""
    scalars = st.one_of(
        st.integers(-(2**63), 2**63 - 1),
        st.sampled_from((0, -1, 1, 2, 3, 30, 400, 1000, 10**9, 10**8)),
        floats_any(),
        st.booleans(),
        st.text(max_size=10),
        st.sampled_from((_Raw("1979-05-27T07:32:00Z"), _Raw("0x7f"), _Raw("1_000"))),
    )
    return st.one_of(
        scalars,
        scalars,
        st.lists(scalars, max_size=4),
        st.dictionaries(st.text("abc", min_size=1, max_size=3), scalars, max_size=2),
    )


@st.composite
def job_text(draw: st.DrawFn) -> tuple[bytes, str]:
    """A job file: known and unknown sections and keys, values of any type."""
    schema = _job_schema()
    kind = draw(st.sampled_from([*schema, *schema, "nope", None]))
    lines = ["[job]"]
    if kind is not None:
        lines.append(f"kind = {_toml_value(kind)}")
    if draw(st.booleans()):
        lines.append(f"out = {_toml_value(draw(st.sampled_from(('rep', '', 3, '/'))))}")
    if draw(st.integers(0, 5)) == 0:
        key = draw(st.sampled_from(("name", "bogus")))
        lines.append(f"{key} = {_toml_value(draw(toml_values()))}")
    sections = schema.get(kind or "msl-ilc", {}) if isinstance(kind, str) else {}
    sec_names = [*sections, "extra"]
    for sec in draw(st.lists(st.sampled_from(sec_names), max_size=3, unique=True)):
        lines.append(f"[{sec}]")
        keys = [*sections.get(sec, ()), "bogus", "rate_hz"]
        for key in draw(st.lists(st.sampled_from(keys), max_size=4, unique=True)):
            lines.append(f"{key} = {_toml_value(draw(toml_values()))}")
    text = "\n".join(lines) + "\n"
    return text.encode("utf-8", "surrogatepass"), f"kind {kind!r}, {len(lines)} lines"


@st.composite
def job_case(draw: st.DrawFn) -> Case:
    """A job file through ``run JOB --check``."""
    how = draw(st.sampled_from(("built", "built", "built", "mutated", "example", "junk")))
    if how == "built":
        data, note = draw(job_text())
    elif how == "mutated":
        data, note = draw(job_text())
        data, more = draw(mutated(data, 2))
        note += f"; {more}"
    elif how == "example":
        base = draw(st.sampled_from(_examples()))
        data, note = draw(mutated(base))
    else:
        data, note = draw(junk_bytes()), "junk"
    return Case("job", ("run", "job.toml", "--check"), (("job.toml", data),), note=note)


@functools.cache
def _examples() -> tuple[bytes, ...]:
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "examples"
    return tuple(p.read_bytes() for p in sorted(root.glob("*.toml")))


# --------------------------------------------------------------------------- trials
BASE_TRIAL_FILE = "base_trial.csv"
_N, _DT = 100, 1e-5  # one period of 1 ms: harmonics at 1 kHz steps, 8 below the cutoff


def base_trial(second: bool = True) -> dict[str, np.ndarray]:
    """A valid trial of two axes; ``second``: the next measurement on the saved state."""
    t = np.arange(_N) * _DT
    ph = 2 * np.pi * t / (_N * _DT)
    ref_x = 0.5 * np.sin(ph) + 0.1 * np.sin(3 * ph)
    ref_y = 0.3 * np.cos(ph) - 0.1
    rng = np.random.default_rng(1 if second else 0)
    cols = {"time": t}
    for a, r in (("x", ref_x), ("y", ref_y)):
        out = 0.9 * np.roll(r, 1) + 1e-3 * rng.standard_normal(_N)
        cols |= {f"reference_{a}": r, f"input_{a}": r.copy(), f"output_{a}": out}
    return cols


def _csv(cols: dict[str, Any], style: int = 0) -> bytes:
    names = list(cols)
    n = max((len(np.atleast_1d(v)) for v in cols.values()), default=0)
    rows = []
    for i in range(n):
        cells = []
        for k in names:
            v = np.atleast_1d(cols[k])
            cells.append(fmt(v[i]) if i < len(v) else "")
        rows.append(",".join(cells).rstrip(","))
    head = ",".join(names)
    if style == 1:
        head = ",".join(f'"{k}"' for k in names)
    text = head + "\n" + "\n".join(rows) + "\n"
    if style == 2:
        text = "# unit: V\n" + text.replace("\n", "\r\n")
    if style == 3:
        text = "\ufeff" + text
    return text.encode()


def base_trial_csv(second: bool = True) -> bytes:
    """`base_trial` as CSV."""
    return _csv(base_trial(second))


def _mat(cols: dict[str, Any]) -> bytes:
    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, cols, oned_as="column")
    return buf.getvalue()


def _h5(cols: dict[str, Any]) -> bytes:
    import h5py

    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        for k, v in cols.items():
            if isinstance(v, dict):
                f.create_group(k)
            elif np.asarray(v).dtype.kind == "U":  # HDF5 holds byte strings
                f.create_dataset(k, data=np.char.encode(np.asarray(v)))
            elif np.asarray(v).dtype.kind == "O":  # a dict cut by "short": its text
                f.create_dataset(k, data=np.bytes_(repr(v)))
            else:
                f.create_dataset(k, data=v)
    return buf.getvalue()


_RENAMES = (
    "reference_",
    "input_",
    "output_",
    "Time",
    "time ",
    "reference_x y",
    "reference_é",
    "reference_1",
    "reference_x_",
    "unit",
    "reference_time",
    "",
)


@st.composite
def trial_columns(
    draw: st.DrawFn, second: bool, base: dict[str, Any] | None = None
) -> tuple[dict[str, Any], str]:
    """Trial columns (or the columns ``base``) with 0 to 3 defects."""
    cols: dict[str, Any] = dict(base_trial(second) if base is None else base)
    notes = []
    for _ in range(draw(st.integers(0, 3))):
        op = draw(
            st.sampled_from(
                (
                    "value",
                    "length",
                    "drop",
                    "rename",
                    "extra",
                    "jitter",
                    "decreasing",
                    "rate",
                    "t0",
                    "short",
                    "empty",
                    "scale",
                    "reference",
                    "first",
                    "type",
                )
            )
        )
        names = list(cols)
        if not names:
            break
        name = draw(st.sampled_from(names))
        col = _vector(cols[name])
        if op == "value" and col.size:
            col[draw(st.integers(0, col.size - 1))] = draw(st.sampled_from(SPECIAL_FLOATS))
            cols[name] = col
        elif op == "length":
            cols[name] = col[: draw(st.integers(0, max(col.size - 1, 0)))]
        elif op == "drop":
            del cols[name]
        elif op == "rename":
            new = draw(st.sampled_from(_RENAMES))
            cols = {(new if k == name else k): v for k, v in cols.items()}
        elif op == "extra":
            cols[draw(st.sampled_from(("reference_z", "input_z", "output_x", "note")))] = col
        elif op == "jitter" and "time" in cols and _vector(cols["time"]).size > 2:
            t = _vector(cols["time"])
            t[draw(st.integers(1, t.size - 2))] += draw(st.sampled_from((1e-7, 3e-6, -2e-5)))
            cols["time"] = t
        elif op == "decreasing" and "time" in cols:
            cols["time"] = _vector(cols["time"])[::-1]
        elif op == "rate" and "time" in cols:
            cols["time"] = _vector(cols["time"]) * draw(
                st.sampled_from((2.0, 0.5, 1.0 + 1e-9, 1e-9, 1e6, 0.0))
            )
        elif op == "t0" and "time" in cols:
            cols["time"] = _vector(cols["time"]) + draw(floats_any())
        elif op == "short":
            k = draw(st.sampled_from((0, 1, 2, 7, 8, 9, 12)))
            cols = {key: np.atleast_1d(v)[:k] for key, v in cols.items()}
        elif op == "empty":
            cols = {key: np.atleast_1d(v)[:0] for key, v in cols.items()}
        elif op == "scale":
            cols[name] = col * draw(st.sampled_from((1e3, 1e6, 1e300, -1.0, 0.0)))
        elif op == "reference" and name.startswith("reference_"):
            cols[name] = col + 0.01
        elif op == "first":  # the trial the saved state learned from, again
            cols = dict(base_trial(second=False))
        elif op == "type":
            cols[name] = draw(
                st.sampled_from(
                    (
                        np.array(["a"] * 4),
                        np.arange(12, dtype=np.int16),
                        np.ones((3, 4)),
                        np.array(2.0),
                        np.ones(_N) * (1 + 1j),
                        {},
                    )
                )
            )
        notes.append(f"{op}({name})")
    return cols, "+".join(notes) or "valid"


def _vector(value: Any) -> np.ndarray:
    """A column as a fresh 1-D float array; one made odd by an earlier defect (text, a
    matrix, a scalar, complex numbers, a dict) becomes three zeros or its real part."""
    try:
        with np.errstate(all="ignore"):
            arr = np.atleast_1d(np.asarray(value))
            if np.iscomplexobj(arr):
                arr = arr.real
            return np.array(arr, dtype=float, copy=True).ravel()
    except (TypeError, ValueError):
        return np.zeros(3)


def _serialise(cols: dict[str, Any], suffix: str, style: int) -> bytes:
    if suffix == ".csv":
        try:  # a complex column is written as its real part, as a CSV can only hold that
            flat = {k: np.ravel(np.real(np.asarray(v)).astype(float)) for k, v in cols.items()}
        except (TypeError, ValueError):
            flat = {k: np.ravel(np.real(np.asarray(v)).astype(str)) for k, v in cols.items()}
            return (",".join(flat) + "\n1,2\n").encode()
        return _csv(flat, style)
    good = {k: v for k, v in cols.items() if re.fullmatch(r"[A-Za-z]\w*", k)}
    if suffix == ".mat":
        return _mat({k: v for k, v in good.items() if not isinstance(v, dict)})
    try:
        return _h5(cols)
    except (ValueError, TypeError):
        return _h5(good)


@st.composite
def trial_case(draw: st.DrawFn) -> Case:
    """A trial file through ``ilc step``, on a fresh or a saved state."""
    state = draw(st.booleans())
    suffix = draw(st.sampled_from((".csv", ".csv", ".csv", ".mat", ".h5", ".txt")))
    how = draw(st.sampled_from(("columns", "columns", "columns", "columns", "mutated", "junk")))
    if how == "columns":
        cols, note = draw(trial_columns(second=state))
        data = _serialise(cols, ".csv" if suffix == ".txt" else suffix, draw(st.integers(0, 3)))
    elif how == "mutated":
        data, note = draw(mutated(_serialise(base_trial(state), suffix, 0)))
    else:
        data, note = draw(junk_bytes()), "junk"
    argv = ["ilc", "step", f"trial{suffix}", "--state", "st", "--out"]
    argv.append(draw(st.sampled_from(("next.csv",) * 6 + ("next.mat", "next.h5", "next.txt"))))
    opts = {
        "--cutoff-hz": num_text(st.floats(100, 20000)),
        "--gain": num_text(st.floats(0.01, 1.9)),
        "--max-position": num_text(st.floats(0.1, 20)),
        "--max-velocity": num_text(st.floats(1e3, 1e5)),
        "--max-acceleration": num_text(st.floats(1e8, 1e11)),
    }
    if draw(st.integers(0, 3)) == 0:
        for opt in draw(st.lists(st.sampled_from(sorted(opts)), max_size=2, unique=True)):
            argv += [opt, draw(opts[opt])]
    files = ((f"trial{suffix}", data), ("next.csv", SENTINEL))
    setup = ("ilc_state",) if state else ()
    return Case("trial", tuple(argv), files, setup, note=f"{suffix} {how} {note}")


# --------------------------------------------------------------------------- droplet
def _long(text: str) -> bool:
    """True for a duration (µs) that is valid but too long for a cheap case."""
    try:
        x = float(text)
    except ValueError:
        return False
    return 3.0 < x <= 5000.0


def _cheap_duration() -> st.SearchStrategy[str]:
    """Durations, µs: out-of-range values, and valid ones short enough to simulate."""
    return st.one_of(
        st.sampled_from([t for t in SPECIAL_TEXT if not _long(t)]),
        st.sampled_from(("0.5", "1", "2", "1e9", "5001", "-5", "1e308", "inf")),
        st.floats(0.2, 2.0).map(lambda x: f"{x:.3g}"),
    )


@st.composite
def droplet_case(draw: st.DrawFn) -> Case:
    """``droplet simulate`` (mostly) or ``droplet sweep`` with random parameters."""
    if draw(st.integers(0, 4)) == 0:
        lists = st.one_of(
            st.sampled_from(("", ",", "1", "0.15,2", "nan", "1,abc", "1e308", "-1", "3", "inf")),
            st.lists(num_text(st.floats(0, 2)), max_size=3).map(",".join),
        )
        argv = ["droplet", "sweep", "--concentrations", draw(lists), "--voltages", draw(lists)]
        argv += ["--voltage-concentration", draw(num_text(st.floats(0, 2)))]
        # durations the sweep refuses (10 to 5000 µs is allowed): none is simulated
        argv += ["--duration", draw(st.sampled_from((*SPECIAL_TEXT[:21], "9.99", "5001")))]
        argv += ["--jobs", str(draw(st.sampled_from((1, 0, -1, 300))))]
        argv += ["--out", "rep"]
        files = (("rep/sweep.json", SENTINEL),)
        return Case("droplet", tuple(argv), files, note="sweep")
    argv = ["droplet", "simulate"]
    opts = {
        "--concentration": num_text(st.floats(0, 2)),
        "--voltage": num_text(st.floats(40, 70)),
        "--duration": _cheap_duration(),
        "--after-breakup": _cheap_duration(),
    }
    chosen = draw(st.lists(st.sampled_from(sorted(opts)), max_size=4, unique=True))
    if "--duration" not in chosen:
        chosen.append("--duration")  # the default (300 µs) is too long for a fuzz case
    for opt in chosen:
        argv += [opt, draw(opts[opt])]
    argv += ["--out", "rep"]
    if draw(st.booleans()):
        argv += ["--json", "summary.json"]
    files = (("rep/droplet.json", SENTINEL), ("summary.json", SENTINEL))
    return Case("droplet", tuple(argv), files, note="simulate")


# --------------------------------------------------------------------------- frames
def _image(kind: str, h: int, w: int, seed: int) -> np.ndarray:
    """A small gray frame in [0, 1]: blank, noise, or a dark jet from the top."""
    rng = np.random.default_rng(seed)
    if kind == "blank":
        return np.full((h, w), 0.85)
    if kind == "noise":
        return rng.random((h, w))
    img = np.full((h, w), 0.85)
    img[: max(1, h // 6), w // 4 : 3 * w // 4] = 0.1  # the nozzle
    length = int(h * (0.3 + 0.6 * rng.random()))
    img[:length, w // 2 - 2 : w // 2 + 2] = 0.1  # the jet
    return img


def _encode(img: np.ndarray, ext: str, depth: str) -> bytes:
    import imageio.v3 as iio

    arr = (
        (np.clip(img, 0, 1) * 255).astype(np.uint8)
        if depth == "8"
        else (np.clip(img, 0, 1) * 65535).astype(np.uint16)
    )
    return iio.imwrite("<bytes>", arr, extension=ext)


def json_values() -> st.SearchStrategy[Any]:
    """JSON values of every type, numbers special often."""
    return st.one_of(
        st.sampled_from((2e-6, 1e-5, 5e-6, 0, -1, 3, 59, 1e308, "2e-6", None, True, [1.0], {})),
        floats_any().filter(math.isfinite),
        st.integers(-100, 100),
    )


@st.composite
def frames_case(draw: st.DrawFn) -> Case:
    """A folder of frames and its ``frames.json`` through ``droplet analyze``."""
    import json

    n = draw(st.integers(0, 4))
    h, w = draw(st.sampled_from(((60, 40), (3, 3), (2, 5), (40, 40))))
    kind = draw(st.sampled_from(("jet", "jet", "noise", "blank")))
    files: list[tuple[str, bytes]] = []
    notes = [f"{n} {kind} frames {w}x{h}"]
    for i in range(n):
        ext = draw(st.sampled_from((".png", ".png", ".tif")))
        how = draw(st.sampled_from(("ok", "ok", "ok", "size", "junk", "cut")))
        hh, ww = (h + 3, w) if how == "size" else (h, w)
        data = _encode(_image(kind, hh, ww, i), ext, draw(st.sampled_from(("8", "16"))))
        if how == "junk":
            data = draw(junk_bytes())
        elif how == "cut":
            data = data[: draw(st.integers(0, len(data)))]
        if how != "ok":
            notes.append(f"{how}({i})")
        files.append((f"frames/frame_{i:04d}{ext}", data))
    meta = {"pixel_size_m": 2e-6, "frame_interval_s": 1e-5, "nozzle_row": h // 6 - 1}
    for key in draw(st.lists(st.sampled_from([*meta, "t0_s"]), max_size=2, unique=True)):
        meta[key] = draw(json_values())
        notes.append(f"{key}={meta[key]!r}")
    sidecar = draw(st.sampled_from(("json", "json", "none", "junk")))
    if sidecar == "json":
        files.append(("frames/frames.json", json.dumps(meta).encode()))
    elif sidecar == "junk":
        files.append(("frames/frames.json", draw(junk_bytes())))
    argv = ["droplet", "analyze", "frames", "--json", "analysis.json"]
    opts = {
        "--pixel-size": num_text(st.floats(0.5, 10)),
        "--frame-interval": num_text(st.floats(1, 50)),
        "--nozzle-row": st.integers(-3, 70).map(str),
    }
    for opt in draw(st.lists(st.sampled_from(sorted(opts)), max_size=2, unique=True)):
        argv += [opt, draw(opts[opt])]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--out", "analysis.png"]
    files += [("analysis.json", SENTINEL), ("analysis.png", SENTINEL)]
    return Case("frames", tuple(argv), tuple(files), note=", ".join(notes))


# --------------------------------------------------------------------------- table
#: Every kind: its strategy and its share of the cases of a full run.
KINDS: dict[str, tuple[Callable[[], st.SearchStrategy[Case]], float]] = {
    "dxf": (dxf_case, 0.17),
    "svg": (svg_case, 0.17),
    "dat": (dat_case, 0.06),
    "shape": (shape_case, 0.08),
    "traj": (traj_case, 0.06),
    "job": (job_case, 0.14),
    "trial": (trial_case, 0.20),
    "droplet": (droplet_case, 0.07),
    "frames": (frames_case, 0.05),
}

# the seed 003 part 2 commands' kinds live in their own module (this one is long enough)
from fuzz_slm import SLM_KINDS  # noqa: E402

KINDS.update(SLM_KINDS)

# every option of every command, enumerated from the CLI (output aliasing, wrong-kind
# paths, extreme magnitudes, --set, damaged state)
from fuzz_options import OPTION_KINDS  # noqa: E402

KINDS.update(OPTION_KINDS)

from fuzz_concurrency import TOGETHER_KINDS  # noqa: E402

KINDS.update(TOGETHER_KINDS)

# a generator per file kind of microfab.io.filekinds.FILE_KINDS, from its schema
from fuzz_files import FILE_KINDS_CASES  # noqa: E402

KINDS.update(FILE_KINDS_CASES)
