"""Fuzz kinds of the seed 003 part 2 commands: ``identify chirp``, ``shaper design``, ``slm
scan-time`` (registered in `fuzz_cases.KINDS`; import `fuzz_cases` first, it imports this).

=============  ================================================  ===========================
kind           input                                             command
=============  ================================================  ===========================
identify-chirp chirp records (CSV, MAT, HDF5) of the SLM twin:   ``identify chirp``
               NaN/inf cells, non-uniform or decreasing time,
               missing columns, cut records, junk; band, poles,
               zeros and chirp options out of range
shaper-design  model JSON files (seed model, JSON-level and      ``shaper design``
               byte mutations, RHP zeros, unstable, junk) and
               options; FRF, trace and PSD files mutated
slm-scan-time  ``lattice:`` sources (random keys and values),    ``slm scan-time``
               shapes, small DXF drawings (open contours too),
               delays and speeds, shaper files mutated
=============  ================================================  ===========================

Accepted runs are kept cheap: the chirp record is a 10 ms sweep played three times
(3000 samples), a lattice or drawing that would be scanned lies within 3 mm of the
centre with a hatch of at least 20 µm.
"""

from __future__ import annotations

import copy
import functools
import json
import math
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from fuzz_cases import (
    SENTINEL,
    _serialise,
    junk_bytes,
    mutated,
    num_text,
    trial_columns,
)
from fuzz_driver import Case
from hypothesis import strategies as st

__all__ = ["SLM_KINDS", "base_chirp", "base_model", "base_shapers"]

# --------------------------------------------------------------------------- bases
_F0, _F1, _PERIOD = 100.0, 2000.0, 0.01  # a 10 ms sweep: 3000 samples in all at 10 µs
CHIRP_ARGS = ("--f0", "100", "--f1", "2000", "--period", "0.01", "--band", "100:2000")
SEED_NUM = [1.242e11]  # seed 003 part 2 §1
SEED_DEN = [1.0, 9517.0, 5.773e7, 1.272e11]  # seed 003 part 2 §1


@functools.cache
def base_chirp() -> tuple[tuple[str, np.ndarray], ...]:
    """The SLM twin's chirp record: time, input_x, output_x (3 sweeps, the first dropped)."""
    import scipy.signal

    from microfab.identify.chirp import ChirpDesign
    from microfab.plants.galvo_slm import galvo_slm_twin

    d = ChirpDesign(f0_hz=_F0, f1_hz=_F1, period_s=_PERIOD, n_periods=3, n_dropped=1)
    u = d.signal().input
    ax = galvo_slm_twin().axis_model
    y = np.ravel(scipy.signal.dlsim((ax.A, ax.B, ax.C, ax.D, ax.dt), u)[1])
    return (("time", np.arange(u.size) * d.dt), ("input_x", u), ("output_x", y))


def base_model() -> dict[str, Any]:
    """The seed's model as ``identify chirp --json`` writes it."""
    from microfab.identify.model import TFModel

    return TFModel(num=SEED_NUM, den=SEED_DEN, unit="bit/bit").to_dict()


@functools.cache
def _model_dict() -> str:
    return json.dumps(base_model())


@functools.cache
def base_shapers() -> tuple[tuple[str, str], ...]:
    """Shaper JSON texts (``shaper design`` output): inverse ZOH, ZPETC, ZV, EI."""
    from microfab.control.shaper_io import shaper_to_dict
    from microfab.control.shapers import design_shaper
    from microfab.control.shaping import InverseShaperConfig, design_inverse_shaper

    out = []
    for disc in ("zoh", "zpetc"):
        cfg = InverseShaperConfig(pole_hz=4000.0, order=4, dt=1e-5, discretization=disc)
        s = design_inverse_shaper((SEED_NUM, SEED_DEN), cfg)
        out.append((f"inverse-{disc}", json.dumps(shaper_to_dict(s))))
    for name in ("zv", "ei"):
        out.append((name, json.dumps(shaper_to_dict(design_shaper(name, 3000.0, 0.05)))))
    return tuple(out)


@functools.cache
def _frf_file() -> bytes:
    """The seed model's FRF, 100 Hz - 8 kHz, as an FRF CSV (freq_hz, re_x, im_x)."""
    from microfab.identify.model import TFModel
    from microfab.io.frf import write_frf

    f = np.linspace(100.0, 8000.0, 200)
    h = TFModel(num=SEED_NUM, den=SEED_DEN).frequency_response(f)
    h = h * (1 + 0.5 / (1 - (f / 3000.0) ** 2 + 0.04j * f / 3000.0))  # a mirror mode
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "frf.csv"
        write_frf(p, f, h[:, None], ("x",))
        return p.read_bytes()


def _psd_cols() -> dict[str, np.ndarray]:
    f = np.linspace(100.0, 8000.0, 200)
    return {"freq_hz": f, "psd": 1.0 / ((1 - (f / 3000.0) ** 2) ** 2 + (0.04 * f / 3000.0) ** 2)}


# --------------------------------------------------------------------------- JSON edits
_JSON_ODD: tuple[Any, ...] = (
    None, True, 0, -1, 1e308, -1e308, "abc", "1.0", [], {}, [1.0], [[1.0]], [1, "a"],
    [0.0], [0.0, 0.0], [1.0, -1e6, 1e12], [math.nan], [math.inf, 1.0], math.nan, math.inf,
    [1e308, 1e308, 1e308], list(range(40)),
)  # fmt: skip


def _paths(obj: Any, here: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [here]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, (*here, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, (*here, i))
    return out


@st.composite
def json_mutated(draw: st.DrawFn, base: Any, max_edits: int = 2) -> tuple[Any, str]:
    """``base`` (a JSON value) with 1 to ``max_edits`` edits: delete, replace, add a key."""
    obj = copy.deepcopy(base)
    notes = []
    for _ in range(draw(st.integers(1, max_edits))):
        paths = [p for p in _paths(obj) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = obj
        for k in path[:-1]:
            parent = parent[k]
        op = draw(st.sampled_from(("delete", "replace", "replace", "add")))
        if op == "delete":
            del parent[path[-1]]
        elif op == "replace":
            parent[path[-1]] = draw(st.sampled_from(_JSON_ODD))
        elif isinstance(parent, dict):
            parent[draw(st.sampled_from(("extra", "kind", "format", "num", "")))] = 1
        notes.append(f"{op}({'/'.join(map(str, path))})")
    return obj, "+".join(notes)


def _dumps(obj: Any) -> bytes:
    return json.dumps(obj, allow_nan=True).encode()


#: Model (num, den) pairs that are wrong in substance: RHP zero, unstable, improper, ...
_BAD_MODELS = {
    "rhp-zero": ([-1.272e8, 1.272e11], SEED_DEN),
    "unstable": (SEED_NUM, [1.0, -9517.0, 5.773e7, 1.272e11]),
    "integrator": (SEED_NUM, [1.0, 9517.0, 5.773e7, 0.0]),
    "improper": ([1.0, 2.0, 3.0, 4.0, 5.0], SEED_DEN),
    "biproper": ([1.0, 9517.0, 5.773e7, 1.272e11], SEED_DEN),
    "zero-gain": ([0.0], SEED_DEN),
    "lead-zero": (SEED_NUM, [0.0, 1.0, 9517.0, 5.773e7, 1.272e11]),
    "const": ([2.0], [1.0]),
    "empty": ([], SEED_DEN),
    "den-empty": (SEED_NUM, []),
    "tiny": ([1e-300], [1.0, 1e-300]),
    "huge": ([1e300], [1.0, 1e300, 1e300, 1e300]),
    "order-12": ([1.0], list(np.poly(-2 * np.pi * 1000.0 * np.ones(12)))),
    "slow": ([1.0], [1.0, 1.0]),
    "fast": ([1e30], [1.0, 2e10, 1e20, 1e30]),
}


@st.composite
def model_file(draw: st.DrawFn) -> tuple[bytes, str]:
    """A model JSON file: the seed's, edited, wrong in substance, cut, or junk."""
    how = draw(st.sampled_from(("valid", "json", "json", "bad", "bad", "bytes", "junk")))
    base = base_model()
    if how == "valid":
        return _dumps(base), "valid model"
    if how == "json":
        obj, note = draw(json_mutated(base))
        return _dumps(obj), f"model {note}"
    if how == "bad":
        name = draw(st.sampled_from(sorted(_BAD_MODELS)))
        num, den = _BAD_MODELS[name]
        return _dumps({"num": list(num), "den": list(den)}), f"model {name}"
    if how == "bytes":
        data, note = draw(mutated(_model_dict().encode()))
        return data, f"model bytes {note}"
    junk = draw(
        st.one_of(
            junk_bytes(),
            st.sampled_from(
                (b"[" * 100_000, b'{"num":' * 50_000, b"null", b"[]", b'"model"', b"1e999")
            ),
        )
    )
    return junk, "model junk"


# --------------------------------------------------------------------------- identify-chirp
_BANDS = (
    "100:2000", "100:2000", "200:1500", "10:2000", "100:60000", "100:50000", "0:2000",
    "2000:100", "100:100", "nan:2000", "100:inf", "-5:200", "100", ":", "", "a:b", "1e-300:1",
    "100:2000:3", "150:160", "100.0001:100.0002",
)  # fmt: skip


@st.composite
def chirp_case(draw: st.DrawFn) -> Case:
    """A chirp record through ``identify chirp`` with mostly the record's own options."""
    suffix = draw(st.sampled_from((".csv",) * 5 + (".mat",) * 2 + (".h5",) * 2 + (".txt",)))
    how = draw(st.sampled_from(("columns", "columns", "columns", "columns", "mutated", "junk")))
    base = dict(base_chirp())
    if how == "columns":  # 0 to 3 defects: a quarter of them valid
        cols, note = draw(trial_columns(second=False, base=base))
        style = draw(st.integers(0, 3))
        data = _serialise(cols, ".csv" if suffix == ".txt" else suffix, style)
    elif how == "mutated":
        data, note = draw(mutated(_serialise(base, suffix if suffix != ".txt" else ".csv", 0)))
    else:
        data, note = draw(junk_bytes()), "junk"
    argv = ["identify", "chirp", f"chirp{suffix}", *CHIRP_ARGS]
    opts: dict[str, st.SearchStrategy[str]] = {
        "--band": st.one_of(st.sampled_from(_BANDS), st.just("")),
        "--poles": st.sampled_from(("1", "2", "3", "3", "4", "6", "0", "-1", "x", "1.5")),
        "--zeros": st.sampled_from(("0", "0", "1", "2", "3", "5", "-1", "nan")),
        "--f0": num_text(st.floats(50.0, 200.0)),
        "--f1": num_text(st.floats(1000.0, 3000.0)),
        "--period": st.sampled_from(("0.01", "0.005", "0.02", "0.01001", "1e-5", "2e-5", "0",
                                     "-0.01", "nan", "inf", "1e308", "0.0100000001")),
        "--periods": st.sampled_from(("1", "2", "3", "4", "0", "-1", "1000000")),
        "--drop": st.sampled_from(("0", "1", "2", "3", "-1", "1000")),
        "--amplitude": num_text(st.floats(90.0, 110.0)),
        "--sweep": st.sampled_from(("linear", "log", "LOG", "", "cubic")),
        "--method": st.sampled_from(("periodic", "h1", "H1", "welch", "")),
        "--min-coherence": num_text(st.floats(0.0, 1.0)),
        "--axis": st.sampled_from(("x", "x", "y", "", "x y", "é", "time")),
    }  # fmt: skip
    n_opts = draw(st.sampled_from((0, 0, 1, 1, 2, 3)))
    for opt in draw(st.lists(st.sampled_from(sorted(opts)), max_size=n_opts, unique=True)):
        argv += [opt, draw(opts[opt])]
        note += f" {opt}"
    argv += ["--json", "model.json"]
    if draw(st.integers(0, 5)) == 0:
        argv += ["--plot", "fit.png"]
    files = ((f"chirp{suffix}", data), ("model.json", SENTINEL), ("fit.png", SENTINEL))
    return Case("identify-chirp", tuple(argv), files, note=f"{suffix} {how} {note}")


# --------------------------------------------------------------------------- shaper-design
_KINDS_OPT = ("inverse", "inverse", "zv", "zvd", "mzv", "ei", "2hump_ei", "3hump_ei", "ZV", "",
              "zz", "inverse ")  # fmt: skip


@st.composite
def shaper_case(draw: st.DrawFn) -> Case:
    """``shaper design``: a model file and option values, FRF / trace / PSD files."""
    kind = draw(st.sampled_from(_KINDS_OPT[:8] if draw(st.integers(0, 9)) else _KINDS_OPT))
    argv = ["shaper", "design"]
    files: list[tuple[str, bytes]] = [("shaper.json", SENTINEL)]
    notes = [f"kind {kind!r}"]
    inverse = kind.startswith("inverse")
    src = draw(st.sampled_from(("freq", "freq", "frf", "frf", "trace", "psd", "psd", "two")))
    if inverse:  # a source with the inverse is refused: rarely
        src = src if draw(st.integers(0, 5)) == 0 else "none"
    # a classic kind takes MODEL as the --frf baseline only; elsewhere rarely
    if inverse or src in ("frf", "two"):
        with_model = draw(st.integers(0, 3)) > 0
    else:
        with_model = draw(st.integers(0, 9)) == 0
    if with_model:
        data, note = draw(model_file())
        files.append(("model.json", data))
        argv.append("model.json")
        notes.append(note)
    argv += ["--kind", kind]
    opts: dict[str, st.SearchStrategy[str]] = {
        "--poles-hz": num_text(st.floats(2000.0, 20000.0)),
        "--order": st.sampled_from(("3", "4", "5", "2", "0", "-1", "40", "1000", "x")),
        "--dt": st.one_of(st.sampled_from(("1e-5", "2e-5", "1e-6", "1e-3", "0.1")), num_text()),
        "--discretization": st.sampled_from(("zoh", "zpetc", "tustin", "", "ZOH")),
        "--damping": num_text(st.floats(0.0, 0.9)),
        "--axis": st.sampled_from(("x", "y", "", "re_x")),
        "--freq-range": st.sampled_from(("1000:5000", "100:8000", "5000:1000", "0:1", "a",
                                         "1e6:2e6", "2900:3100", "")),
    }  # fmt: skip
    n_opts = draw(st.sampled_from((0, 1, 1, 2, 3)))
    for opt in draw(st.lists(st.sampled_from(sorted(opts)), max_size=n_opts, unique=True)):
        argv += [opt, draw(opts[opt])]
        notes.append(opt)
    if src != "none":
        if src in ("freq", "two"):
            argv += ["--freq-hz", draw(num_text(st.floats(500.0, 8000.0)))]
        if src in ("frf", "two"):
            how = draw(st.sampled_from(("valid", "valid", "bytes", "junk")))
            data = _frf_file()
            if how == "bytes":
                data = draw(mutated(data))[0]
            elif how == "junk":
                data = draw(junk_bytes())
            files.append(("frf.csv", data))
            argv += ["--frf", "frf.csv"]
            notes.append(f"frf {how}")
        if src == "trace":
            base = dict(base_chirp())
            cols, note = draw(trial_columns(second=False, base=base))
            files.append(("trace.h5", _serialise(cols, ".h5", 0)))
            argv += ["--frf", "trace.h5"]
            notes.append(f"trace {note}")
        if src == "psd":
            cols, note = draw(trial_columns(second=False, base=_psd_cols()))
            data = _serialise(cols, ".csv", 0)
            files.append(("psd.csv", data))
            argv += ["--psd", "psd.csv"]
            notes.append(f"psd {note}")
    argv += ["--out", "shaper.json"]
    return Case("shaper-design", tuple(argv), tuple(files), note="; ".join(notes))


# --------------------------------------------------------------------------- slm-scan-time
#: Values of a lattice key: (cheap and valid, refused or out of range).
_LATTICE_VALUES = {
    "z": (("0", "4e-4", "1e-4", "-2e-3", "1e-3"), ("nan", "inf", "1e308", "-1e308", "abc")),
    "radius": (("1e-3", "2e-3", "3e-3", "5e-4", "1e-5"),
               ("0", "-1e-3", "nan", "inf", "0.1", "1e308", "0.05", "", "1e-300")),
    "strut": (("250e-6", "200e-6", "400e-6", "1e-3", "0.01"),
              ("0", "-1", "nan", "inf", "1e308", "1e-300", "1e-9", "1e-6")),
    "fraction": (("0.05", "0.1", "0.2", "0.02"),
                 ("0", "1", "1.5", "-0.1", "nan", "0.9", "0.99", "1e-9")),
    "hatch": (("1e-4", "5e-5", "2e-4", "1e-3"),
              ("0", "-1e-4", "nan", "inf", "1e308", "1e-12", "1e-6")),
    "sides": (("8", "16", "32", "12"), ("0", "4", "6", "7.5", "-8", "nan", "1e9", "1e308", "x")),
}  # fmt: skip
_CHEAP_RADIUS = 3e-3


@st.composite
def lattice_source(draw: st.DrawFn) -> tuple[str, str]:
    """``lattice:...`` with random keys: cheap valid values, or refused / odd ones."""
    pairs = []
    keys = draw(st.lists(st.sampled_from(sorted(_LATTICE_VALUES)), max_size=4, unique=True))
    if "radius" not in keys:
        keys.append("radius")  # the default, 20 mm, is too big for a cheap case
    bad = 0
    for key in keys:
        good, odd = _LATTICE_VALUES[key]
        if draw(st.integers(0, 2)) == 0:
            val, bad = draw(st.sampled_from(odd)), bad + 1
        else:
            val = draw(st.sampled_from(good))
        pairs.append(f"{draw(st.sampled_from((key, key, key.upper(), f' {key} ')))}={val}")
    extra = draw(st.sampled_from(("",) * 12 + ("size=1", "radius=1e-3", "z", ",", "=", "=1")))
    if extra:
        pairs.insert(draw(st.integers(0, len(pairs))), extra)
    src = draw(st.sampled_from(("lattice:", "lattice:", "LATTICE:", " lattice:"))) + ",".join(
        draw(st.permutations(pairs))
    )
    return src, f"lattice ({bad} odd values)"


def _dxf(entities: list[str], units: str = "4") -> bytes:
    head = "  0\nSECTION\n  2\nHEADER\n  9\n$ACADVER\n  1\nAC1015\n"
    head += f"  9\n$INSUNITS\n 70\n{units}\n  0\nENDSEC\n"
    body = "  0\nSECTION\n  2\nENTITIES\n" + "".join(entities) + "  0\nENDSEC\n  0\nEOF\n"
    return (head + body).encode()


def _lwpoly(pts: list[tuple[str, str]], closed: bool) -> str:
    s = "  0\nLWPOLYLINE\n  5\nA0\n100\nAcDbEntity\n  8\n0\n100\nAcDbPolyline\n"
    s += f" 90\n{len(pts)}\n 70\n{1 if closed else 0}\n"
    return s + "".join(f" 10\n{x}\n 20\n{y}\n" for x, y in pts)


@st.composite
def small_dxf(draw: st.DrawFn) -> tuple[bytes, str]:
    """A DXF within 3 mm of the origin (mm): squares, circles, open polylines; or mutated."""
    c = st.floats(-2.5, 2.5).map(lambda x: f"{x:.4g}")
    ents = []
    notes = []
    for _ in range(draw(st.integers(0, 3))):
        what = draw(st.sampled_from(("square", "circle", "open", "poly", "line")))
        notes.append(what)
        if what == "square":
            x, y, s = draw(st.floats(-2, 1)), draw(st.floats(-2, 1)), draw(st.floats(0.05, 1))
            pts = [(x, y), (x + s, y), (x + s, y + s), (x, y + s)]
            ents.append(_lwpoly([(f"{a:.4g}", f"{b:.4g}") for a, b in pts], True))
        elif what == "circle":
            r = draw(st.sampled_from(("0.5", "1", "2", "0", "-1", "nan", "1e-9", "3")))
            ents.append(
                f"  0\nCIRCLE\n  5\nB0\n100\nAcDbEntity\n  8\n0\n100\nAcDbCircle\n 10\n"
                f"{draw(c)}\n 20\n{draw(c)}\n 30\n0\n 40\n{r}\n"
            )
        elif what in ("open", "poly"):
            pts = draw(st.lists(st.tuples(c, c), min_size=0, max_size=6))
            ents.append(_lwpoly(pts, what == "poly"))
        else:
            ents.append(
                f"  0\nLINE\n  5\nC0\n100\nAcDbEntity\n  8\n0\n100\nAcDbLine\n"
                f" 10\n{draw(c)}\n 20\n{draw(c)}\n 30\n0\n 11\n{draw(c)}\n"
                f" 21\n{draw(c)}\n 31\n0\n"
            )
    units = draw(st.sampled_from(("4", "4", "4", "1", "6", "0", "13")))
    data = _dxf(ents, units)
    note = f"dxf units {units}: {', '.join(notes) or 'empty'}"
    if draw(st.integers(0, 4)) == 0:
        data, more = draw(mutated(data))
        note += f"; {more}"
    return data, note


_SHAPES = (
    "circle:radius=2e-3", "circle:radius=1e-3", "square:side=3e-3", "rectangle:width=4e-3,"
    "height=2e-3", "polygon:n_sides=6,radius=2e-3", "spiral", "circle:radius=0.1",
    "circle:radius=0.04", "circle:radius=nan", "circle", "ellipse:a=2e-3,b=1e-3",
    "lissajous:ax=2e-3,ay=2e-3", "text:A", "blob", "", " ", "x.dxf", "lattice",
)  # fmt: skip


@st.composite
def slm_case(draw: st.DrawFn) -> Case:
    """``slm scan-time``: a source, delays, speeds, and sometimes a shaper file."""
    files: list[tuple[str, bytes]] = [("scan.json", SENTINEL)]
    how = draw(st.sampled_from(("lattice", "lattice", "lattice", "shape", "dxf", "dxf")))
    if how == "lattice":
        source, note = draw(lattice_source())
    elif how == "shape":
        source = draw(st.sampled_from(_SHAPES))
        note = f"shape {source!r}"
    else:
        data, note = draw(small_dxf())
        files.append(("part.dxf", data))
        source = "part.dxf"
    argv = ["slm", "scan-time", source]
    delay = st.one_of(
        st.sampled_from(("0", "10", "250", "750", "755", "5", "-10", "1e6", "1000010", "nan",
                         "inf", "1e308", "0.5", "9.999999999", "10.000000001", "1e-300")),
        st.integers(0, 200).map(lambda k: str(10 * k)),
    )  # fmt: skip
    opts: dict[str, st.SearchStrategy[str]] = {
        "--mark-speed": num_text(st.floats(0.1, 5.0)),
        "--jump-speed": num_text(st.floats(1.0, 10.0)),
        "--jump-delay-us": delay,
        "--shaped-jump-delay-us": delay,
        "--mark-delay-us": delay,
        "--polygon-delay-us": delay,
        "--laser-on-delay-us": delay,
        "--laser-off-delay-us": delay,
        "--sky-writing": st.sampled_from(("0", "1", "2", "3", "4", "-1")),
        "--sky-prev": st.sampled_from(("0", "5", "50", "1000", "-1", "1001", "1000000000", "x")),
        "--sky-post": st.sampled_from(("0", "5", "50", "1000", "-1", "100000", "1000000000")),
        "--tolerance-pct": num_text(st.floats(0.5, 10.0)),
        "--hatch-um": st.one_of(
            num_text(st.floats(50.0, 300.0)).filter(_cheap_hatch),
            st.sampled_from(("1e-3", "1.4", "1e-300")),
        ),
        "--hatch-angle-deg": num_text(st.floats(-180.0, 180.0)),
    }
    flags = ("--variable-polygon", "--no-contours", "--naive-jump-delay", "--mirror-mode")
    n_opts = draw(st.sampled_from((0, 1, 1, 2, 3)))
    for opt in draw(st.lists(st.sampled_from(sorted(opts)), max_size=n_opts, unique=True)):
        argv += [opt, draw(opts[opt])]
        note += f" {opt}"
    argv += draw(st.lists(st.sampled_from(flags), max_size=2, unique=True))
    if draw(st.integers(0, 3)) == 0:
        how = draw(st.sampled_from(("valid", "valid", "json", "bytes", "model", "junk")))
        name, text = draw(st.sampled_from(base_shapers()))
        if how == "valid":
            data = text.encode()
        elif how == "json":
            obj, more = draw(json_mutated(json.loads(text)))
            data, name = _dumps(obj), f"{name} {more}"
        elif how == "bytes":
            data, more = draw(mutated(text.encode()))
            name = f"{name} {more}"
        elif how == "model":
            data, name = draw(model_file())
        else:
            data, name = draw(junk_bytes()), "junk"
        files.append(("shaper.json", data))
        argv += ["--shaper", "shaper.json"]
        note += f"; shaper {how} {name}"
    if draw(st.integers(0, 2)):
        argv += ["--json", "scan.json"]
    return Case("slm-scan-time", tuple(argv), tuple(files), note=note)


def _cheap_hatch(text: str) -> bool:
    """False for a hatch spacing (µm) that is valid but fine enough to make a slow case."""
    try:
        x = float(text)
    except ValueError:
        return True
    return not (1.5 <= x < 20.0)  # below one bit (1.5 µm) is refused


# --------------------------------------------------------------------------- table
#: The kinds of this module: strategy and share of a full run's cases (small).
SLM_KINDS: dict[str, tuple[Callable[[], st.SearchStrategy[Case]], float]] = {
    "identify-chirp": (chirp_case, 0.03),
    "shaper-design": (shaper_case, 0.03),
    "slm-scan-time": (slm_case, 0.03),
}
