"""Example 3: drop-on-demand breakup of NaAlg (seed 003 part 1), headless.

Simulates the seed's 50 V bipolar drive for one NaAlg concentration, prints the breakup
time, mode and head speed, renders the silhouettes as noisy shadowgraph frames, measures
them back with the image analyser and writes a frame montage to
``example_03_frames.png``.

Run: ``.venv/bin/python examples/03_droplet_breakup.py [CONCENTRATION_PCT] [OUT_DIR]``
"""

from __future__ import annotations

import sys
from pathlib import Path

from microfab.measure.imaging import analyze
from microfab.measure.shadowgraph import Camera, render_sequence
from microfab.process.inkjet.droplet import simulate_droplet
from microfab.process.inkjet.fluids import naalg
from microfab.report.canvas import save_figure
from microfab.report.inkjet import fig_montage


def main(concentration_pct: float = 0.15, out_dir: Path = Path()) -> Path:
    res = simulate_droplet(naalg(concentration_pct), duration_s=400e-6, frame_interval_s=5e-6)
    t = "none" if res.breakup_time_s is None else f"{res.breakup_time_s * 1e6:.1f} µs"
    print(f"{res.fluid.name}: breakup {t} ({res.breakup_mode}), head {res.head_speed_m_s:.2f} m/s")
    sil = [s for s in res.silhouettes if s.bodies]
    cam = Camera(pixel_size_m=2e-6, width_px=120, height_px=600, noise_std=0.02, blur_px=1.0)
    frames = render_sequence(sil, cam, seed=0)
    measured = analyze(
        frames, pixel_size_m=cam.pixel_size_m, frame_interval_s=5e-6, t0_s=sil[0].time_s
    )
    tm = measured.breakup_time_s
    print(
        "measured from frames: breakup "
        + ("none" if tm is None else f"{tm * 1e6:.1f} µs ({measured.breakup_mode})")
        + f", head {measured.head_speed_m_s or 0.0:.2f} m/s, satellites {measured.satellites}"
    )
    fig = fig_montage(frames[::4], [s.time_s for s in sil][::4], cam)
    return save_figure(fig, out_dir / "example_03_frames.png")


if __name__ == "__main__":
    c = float(sys.argv[1]) if len(sys.argv) > 1 else 0.15
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path()
    print(f"wrote {main(c, out)}")
