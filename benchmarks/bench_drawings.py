"""``microfab path show`` on large valid drawings: seconds against the 5 s goal.

Builds, in a temporary folder, five drawings of thousands of contours:

- ``circles.dxf``: 5 000 DXF CIRCLEs, radius 0.1-1 mm, at random in a 100 mm square
  (overlapping ones nest: outer, hole, island);
- ``paths4000.svg`` and ``paths5000.svg``: 4 000 and 5 000 small closed SVG paths
  (``M x y l 1 0 l 0 1 z``) in a 100 mm viewBox;
- ``mixed.dxf``: 5 000 entities, LINE, ARC and closed bulged LWPOLYLINE in turn;
- ``text:`` followed by 2 000 characters (``ABAB…``: 5 000 glyph contours),

then times ``microfab path show DRAWING --out PNG``, with and without ``--json``, on each
as a user runs it (a fresh process through the console script beside this interpreter:
start-up, reading, nesting, the listing or the JSON of every contour, and the picture),
best of ``repeats`` runs, and prints a table of seconds against the goal (each at most
5 s on an idle 2-core machine) with the machine's load.

Run: ``python benchmarks/bench_drawings.py [repeats]``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ezdxf
import numpy as np

GOAL_S = 5.0


def build(folder: Path, seed: int = 0) -> dict[str, str]:
    """Write the drawings into ``folder``; name -> the ``path show`` argument."""
    rng = np.random.default_rng(seed)
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4  # mm
    msp = doc.modelspace()
    for _ in range(5000):
        msp.add_circle(tuple(rng.uniform(0, 100, 2)), float(rng.uniform(0.1, 1.0)))
    doc.saveas(folder / "circles.dxf")
    for n in (4000, 5000):
        xy = rng.uniform(0, 98, (n, 2))
        body = "\n".join(f'<path d="M {x:.3f} {y:.3f} l 1 0 l 0 1 z"/>' for x, y in xy)
        (folder / f"paths{n}.svg").write_text(
            '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
            f'viewBox="0 0 100 100">\n{body}\n</svg>\n'
        )
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    for i in range(5000):
        x, y = (float(v) for v in rng.uniform(0, 98, 2))
        if i % 3 == 0:
            msp.add_line((x, y), (x + rng.uniform(0.1, 1), y + rng.uniform(0.1, 1)))
        elif i % 3 == 1:
            r, a0, a1 = rng.uniform(0.1, 1), rng.uniform(0, 180), rng.uniform(180, 360)
            msp.add_arc((x, y), float(r), float(a0), float(a1))
        else:
            pts = [(x, y, 0.2), (x + 1, y, 0.0), (x + 1, y + 1, 0.0), (x, y + 1, 0.0)]
            msp.add_lwpolyline(pts, format="xyb", close=True)
    doc.saveas(folder / "mixed.dxf")
    return {
        "5000 DXF circles": str(folder / "circles.dxf"),
        "4000 SVG paths": str(folder / "paths4000.svg"),
        "5000 SVG paths": str(folder / "paths5000.svg"),
        "5000 DXF LINE/ARC/LWPOLYLINE": str(folder / "mixed.dxf"),
        "text: 2000 characters": "text:" + "AB" * 1000,
    }


def run(cmd: list[str], cwd: Path) -> tuple[float, str]:
    """Wall time of one run of ``cmd``, s, and its standard output (it must exit 0)."""
    t0 = time.perf_counter()
    res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)
    dt = time.perf_counter() - t0
    if res.returncode != 0:
        raise RuntimeError(f"{cmd[:3]} exited {res.returncode}: {res.stderr[-500:]}")
    return dt, res.stdout


def best(cmd: list[str], cwd: Path, repeats: int) -> tuple[float, str]:
    """Shortest wall time of ``repeats`` runs of ``cmd``, s, and the last one's output."""
    runs = [run(cmd, cwd) for _ in range(max(1, repeats))]
    return min(t for t, _ in runs), runs[-1][1]


def contours(stdout: str) -> int:
    """How many contours ``path show`` reported."""
    more = re.search(r"more contours \(of (\d+):", stdout)
    return int(more.group(1)) if more else sum(ln.startswith("#") for ln in stdout.splitlines())


def main(repeats: int = 3) -> None:
    mf = str(Path(sys.executable).parent / "microfab")
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        t0 = time.perf_counter()
        cases = build(cwd)
        print(f"drawings written in {time.perf_counter() - t0:.1f} s")
        t_floor = min(run([mf, "path", "show", "square:side=0.01"], cwd)[0] for _ in range(3))
        print(f"path show of one square (start-up and a picture): {t_floor:.2f} s")
        print(f"{'drawing':<30} {'contours':>8} {'listing s':>9} {'--json s':>9} {'goal':>6}")
        worst = 0.0
        for name, spec in cases.items():
            cmd = [mf, "path", "show", spec, "--out", str(cwd / "x.png")]
            t_list, out = best(cmd, cwd, repeats)
            t_json, _ = best([*cmd, "--json"], cwd, repeats)
            worst = max(worst, t_list, t_json)
            verdict = "ok" if max(t_list, t_json) <= GOAL_S else "OVER"
            print(
                f"{name:<30} {contours(out):>8} {t_list:>9.2f} {t_json:>9.2f} "
                f"{GOAL_S:>5.0f}s {verdict}"
            )
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"slowest {worst:.2f} s (goal <= {GOAL_S:.0f} s each); load average {load:.2f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
