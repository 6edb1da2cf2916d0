"""Example 2: seed 002's letters and airfoil, from outlines to limit-safe references.

Loads the letters "u", "r", "c", "h" (DejaVu Sans glyph outlines standing in for the ETH
Zürich logo of seed 002) and the Eppler e344 airfoil, plans the minimum-time reference
of each under the seed 002 stage limits plus a jerk limit, prints the durations next to a
constant-speed baseline, and writes the letter "r"'s profile to
``example_02_profile.png``.

Run: ``.venv/bin/python examples/02_letters_time_optimal.py [N_GRID] [OUT_DIR]``
"""

from __future__ import annotations

import sys
from pathlib import Path

from microfab.core.limits import MachineLimits
from microfab.geometry.load import load_drawing
from microfab.report.canvas import save_figure
from microfab.report.geometry import fig_profile
from microfab.trajectory.optimal import time_optimal


def main(n_grid: int = 400, out_dir: Path = Path()) -> Path:
    # seed 002 Table I (1.5 m/s, 40 m/s², ±0.19 m), a_max 1 m/s² as in §V-A, jerk 50 m/s³
    limits = MachineLimits.seed002_stage()
    limits = MachineLimits(
        workspace=limits.workspace,
        velocity=limits.velocity,
        acceleration=(1.0, 1.0),
        jerk=(50.0, 50.0),
    )
    profile = None
    for spec in ("text:u", "text:r", "text:c", "text:h", "airfoil:e344"):
        path = load_drawing(spec, text_height=0.05, chord=0.1)[0]
        res = time_optimal(path, limits, n_grid=n_grid, sample_rate_hz=1000.0)
        print(
            f"{spec:13s} length {path.length * 1e3:7.2f} mm, time-optimal {res.duration:6.3f} s,"
            f" {len(res.segments)} segments, utilisation min {res.utilisation.min():.3f}"
        )
        if spec == "text:r":
            profile = fig_profile(res.trajectory, limits, title='letter "r", time-optimal')
    assert profile is not None
    return save_figure(profile, out_dir / "example_02_profile.png")


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 400
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path()
    print(f"wrote {main(n, out)}")
