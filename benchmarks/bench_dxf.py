"""Speed of the DXF reader on a drawing of 100 000 entities.

Builds, in a temporary folder, a DXF file of mostly LINEs forming closed squares (in
random order and directions), plus slots of two arcs and two lines, LWPOLYLINEs with
bulges, circles and a few splines, then times ``ezdxf.readfile`` alone and the whole
:func:`microfab.geometry.dxf.read_dxf` (parse, convert, chain), best of 3 calls each,
alternating, and prints their ratio (goal: <= 1.2). Each call starts with the garbage of
the previous ones collected (outside the timing).

Run: ``python benchmarks/bench_dxf.py [n_entities]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import ezdxf
import numpy as np
from _timing import timed

from microfab.geometry.dxf import read_dxf


def build(path: Path, n_entities: int = 100_000, seed: int = 0) -> dict[str, int]:
    """Write the test drawing; return the entity counts and the expected contour count."""
    rng = np.random.default_rng(seed)
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    n_splines = 100
    n_slots = n_entities // 50  # 4 entities each
    n_lwp = n_entities // 20
    n_circles = n_entities // 15
    n_squares = (n_entities - n_splines - 4 * n_slots - n_lwp - n_circles) // 4
    n_circles = n_entities - n_splines - 4 * n_slots - n_lwp - 4 * n_squares
    jobs: list[tuple[str, tuple]] = []
    cell = 0

    def origin() -> tuple[float, float]:
        nonlocal cell
        cell += 1
        return (3.0 * (cell % 400), 3.0 * (cell // 400))

    for _ in range(n_squares):
        x, y = origin()
        c = [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)]
        for i in range(4):
            a, b = c[i], c[(i + 1) % 4]
            jobs.append(("line", (b, a) if rng.random() < 0.5 else (a, b)))
    for _ in range(n_slots):
        x, y = origin()
        jobs.append(("line", ((x + 0.5, y), (x + 1.5, y))))
        jobs.append(("line", ((x + 1.5, y + 1), (x + 0.5, y + 1))))
        jobs.append(("arc", ((x + 1.5, y + 0.5), 0.5, -90.0, 90.0)))
        jobs.append(("arc", ((x + 0.5, y + 0.5), 0.5, 90.0, 270.0)))
    for _ in range(n_lwp):
        x, y = origin()
        pts = [(x, y, 0.3), (x + 1, y, 0.0), (x + 1, y + 1, -0.2), (x, y + 1, 0.0)]
        jobs.append(("lwp", (pts,)))
    for _ in range(n_circles):
        x, y = origin()
        jobs.append(("circle", ((x + 0.5, y + 0.5), 0.4)))
    for _ in range(n_splines):
        x, y = origin()
        cps = [(x + 0.25 * i, y + (0.5 if i % 2 else 0.0)) for i in range(8)]
        jobs.append(("spline", (cps,)))
    for i in rng.permutation(len(jobs)):
        kind, args = jobs[i]
        if kind == "line":
            msp.add_line(*args)
        elif kind == "arc":
            msp.add_arc(*args)
        elif kind == "lwp":
            msp.add_lwpolyline(args[0], format="xyb", close=True)
        elif kind == "circle":
            msp.add_circle(*args)
        else:
            msp.add_open_spline(args[0], degree=3)
    doc.saveas(path)
    return {
        "entities": len(jobs),
        "contours": n_squares + n_slots + n_lwp + n_circles + n_splines,
        "lines": 4 * n_squares + 2 * n_slots,
        "arcs": 2 * n_slots,
        "lwpolylines": n_lwp,
        "circles": n_circles,
        "splines": n_splines,
    }


def main(n_entities: int = 100_000) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.dxf"
        t_build, counts = timed(lambda: build(path, n_entities))
        size_mb = path.stat().st_size / 1e6
        print(f"drawing: {counts}, {size_mb:.1f} MB, written in {t_build:.1f} s")
        # alternate the two (best of 3 each), so that a busy spell of the machine hits both
        t_parse = t_read = float("inf")
        layer = None
        for _rep in range(3):
            layer = None  # nothing of an earlier call stays alive
            t_parse = min(t_parse, timed(lambda: ezdxf.readfile(path), collect=True)[0])
            t, layer = timed(lambda: read_dxf(path), collect=True)
            t_read = min(t_read, t)
    n = counts["entities"]
    n_closed = sum(1 for c in layer if c.closed)
    print(f"ezdxf.readfile: {t_parse:6.2f} s  {n / t_parse:9.0f} entities/s")
    print(f"read_dxf:       {t_read:6.2f} s  {n / t_read:9.0f} entities/s")
    print(f"read_dxf / readfile: {t_read / t_parse:.2f}")
    print(
        f"contours: {len(layer)} ({n_closed} closed; expected {counts['contours']}), "
        f"skipped: {len(layer.skipped)}"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
