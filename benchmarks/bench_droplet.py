"""Wall time of the slender-jet solver: verification threads and drop-on-demand runs.

Run: ``python benchmarks/bench_droplet.py [--full]``. ``--full`` adds the full 300 µs
drop-on-demand runs at 0.15 % and 1 % NaAlg, 50 V (minutes with the current solver).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from microfab.process.inkjet.droplet import simulate_droplet
from microfab.process.inkjet.fluids import naalg
from microfab.process.inkjet.jet import JetModel, Numerics, run_jet, thread_body


def _thread() -> object:
    return thread_body(math.pi / 0.6, lambda z: 1.0 + 0.05 * np.cos(0.6 * z), cells=60)


def _time(label: str, fn) -> None:
    t0 = time.perf_counter()
    out = fn()
    wall = time.perf_counter() - t0
    run = getattr(out, "run", out)
    nodes = sum(b.z.size for b in run.bodies)
    print(
        f"{label:<46s} {wall:7.2f} s  steps {run.steps:6d} (+{run.rejected} rejected)  "
        f"final nodes {nodes:5d}  stop: {run.stop_reason}"
    )


def main() -> None:
    _time(
        "warm-up (numba compile)", lambda: run_jet([_thread()], JetModel(ohnesorge=1.0), t_end=1.0)
    )
    _time(
        "Newtonian thread, Oh 0.5, to h = 3e-4",
        lambda: run_jet([_thread()], JetModel(ohnesorge=0.5), Numerics(h_break=3e-4), t_end=1e3),
    )
    _time(
        "Oldroyd-B thread, De 10, to h = 1e-2",
        lambda: run_jet(
            [_thread()],
            JetModel(ohnesorge=0.3, polymer_ohnesorge=3.0, deborah=10.0),
            Numerics(h_break=1e-2, resolution=0.8),
            t_end=400.0,
        ),
    )
    _time(
        "DOD 0.15 % NaAlg, 50 V, first 80 µs",
        lambda: simulate_droplet(naalg(0.15), duration_s=80e-6),
    )
    if "--full" in sys.argv:
        for c in (0.15, 1.0):
            _time(
                f"DOD {c} % NaAlg, 50 V, 300 µs",
                lambda c=c: simulate_droplet(naalg(c), duration_s=300e-6),
            )


if __name__ == "__main__":
    main()
