"""Example 1: frequency-domain ILC on the galvo twin (seed 000), headless.

Learns the 0.6 mm square at 400 features/s for a few iterations on both axes, prints the
RMS error per iteration and writes the xy figure (seed Fig. 4a) to ``example_01_xy.png``.

Run: ``.venv/bin/python examples/01_galvo_ilc.py [ITERATIONS] [OUT_DIR]``
"""

from __future__ import annotations

import sys
from pathlib import Path

from microfab.machines.galvo.ilc import run_msl_ilc
from microfab.report.canvas import save_figure
from microfab.report.galvo_ilc import fig_xy


def main(iterations: int = 10, out_dir: Path = Path()) -> Path:
    result = run_msl_ilc(features_per_s=400, iterations=iterations)
    for i, (ex, ey) in enumerate(result.rms_history * 1e3, start=1):
        print(f"iteration {i:2d}: RMS error x {ex:7.2f} mV, y {ey:7.2f} mV")
    return save_figure(fig_xy(result), out_dir / "example_01_xy.png")


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path()
    print(f"wrote {main(n, out)}")
