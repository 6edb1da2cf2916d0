"""Wall time of the slender-jet solver: verification threads and drop-on-demand runs.

Run: ``python benchmarks/bench_droplet.py [--full]``. Prints, for both jet models
(Lagrangian and Eulerian, each with its own calibrated relaxation law), the wall time of
each full drop-on-demand breakup simulation at 50 V, the Newtonian limit of the same run
as the baseline, and for the Eulerian model the same 1 % run with its meniscus held at
the rim (no coupled acoustics) for the cost of the meniscus in the bore. Goals: the 1 %
run to breakup + 20 µs in at most 1 s with the default model (``DEFAULT_JET_MODEL``), at
most 10 s with the other. With ``--full`` the whole Fig. 4 sweep (six concentrations at
50 V), one point after another and on a local Dask cluster of two worker processes (its
start-up included).
"""

from __future__ import annotations

import math
import sys

import numpy as np
from _timing import timed

from microfab.machines.printhead.machine import droplet_sweep, sweep_points
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL, simulate_droplet
from microfab.process.inkjet.fluids import naalg
from microfab.process.inkjet.jet import JetModel, Numerics, run_jet, thread_body


def _thread() -> object:
    return thread_body(math.pi / 0.6, lambda z: 1.0 + 0.05 * np.cos(0.6 * z), cells=60)


def _time(label: str, fn) -> float:
    wall, out = timed(fn)
    run = getattr(out, "run", out)
    nodes = sum(b.z.size for b in run.bodies)
    print(
        f"{label:<58s} {wall:7.2f} s  steps {run.steps:6d} (+{run.rejected} rejected)  "
        f"final nodes {nodes:5d}  stop: {run.stop_reason}"
    )
    return wall


def _dod(fluid: object, model: str, meniscus: str | None = None) -> object:
    return simulate_droplet(
        fluid, duration_s=400e-6, after_breakup_s=20e-6, model=model, meniscus=meniscus
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
        "warm-up of the Eulerian kernels (numba compile)",
        lambda: simulate_droplet(naalg(0.15), duration_s=20e-6, model="eulerian"),
    )
    for model in ("lagrangian", "eulerian"):
        walls = {}
        for c in (0.15, 1.0):
            walls[c] = _time(
                f"{model}: DOD {c} % NaAlg, 50 V, to breakup + 20 µs",
                lambda c=c, m=model: _dod(naalg(c, model=m), m),
            )
        base = _time(
            f"{model}: DOD 1 % NaAlg as Newtonian (baseline)",
            lambda m=model: _dod(naalg(1.0, relaxation_time_s=0.0), m),
        )
        if model == "eulerian":
            pinned = _time(
                "eulerian: DOD 1 % NaAlg, meniscus held at the rim (one-way)",
                lambda: _dod(naalg(1.0, model="eulerian"), "eulerian", "pinned"),
            )
            print(
                f"eulerian: the meniscus in the bore and the coupled acoustics cost "
                f"{walls[1.0] / pinned:.2f}x the run with the meniscus held at the rim"
            )
        goal = 1.0 if model == DEFAULT_JET_MODEL else 10.0
        role = "the default model" if model == DEFAULT_JET_MODEL else "the other model"
        print(
            f"{model} ({role}): viscoelastic 1 % run: {walls[1.0]:.2f} s = "
            f"{walls[1.0] / base:.1f}x its Newtonian limit (goal <= {goal:g} s: "
            f"{'met' if walls[1.0] <= goal else 'NOT met'})"
        )
    if "--full" in sys.argv:
        sweep_walls = {}
        for workers in (1, 2):
            sweep_walls[workers], sweep = timed(
                lambda w=workers: droplet_sweep(sweep_points(voltages_v=()), workers=w)
            )
            rows = sweep.rows
            print(
                f"Fig. 4 sweep, {len(rows)} concentrations at 50 V, workers={workers} "
                f"(local Dask cluster when > 1): {sweep_walls[workers]:.1f} s"
            )
        print(f"parallel sweep speed-up on 2 workers: {sweep_walls[1] / sweep_walls[2]:.2f}x")
        for r in rows:
            tb = r["breakup_time_s"]
            print(
                f"  {r['concentration_pct']:5.2f} %: "
                + ("no breakup" if tb is None else f"{tb * 1e6:6.1f} µs {r['breakup_mode']}")
            )


if __name__ == "__main__":
    main()
