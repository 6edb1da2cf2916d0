"""Speed of the dynamics-aware scan-time estimate (seed 003 part 2, issue 16 §7).

Prints, in one run on this machine, for one lattice layer of about 1e5 vectors (simple
cubic strut lattice, 47 mm disc outline, `microfab.process.slm.lattice.lattice_layer`) on
the SLM galvo twin (`microfab.plants.galvo_slm`):

* the dynamics-aware estimate (`dynamics_estimate`: exact per-vector propagation of the
  axis model, per-vector jump delays, position error at every laser switch), goal <= 1 s;
* as ratios: against the naive sum of L/v (`naive_estimate`) and against a per-sample
  compiled simulation of the same timeline (`simulate_timeline`), in the same run.

numba compilation and the axis tables are excluded (one warm-up call); timings are the
best of 3. Building the layer's geometry is timed apart. No asserts.

Run: ``make bench`` or ``python benchmarks/bench_slm.py``.
"""

from __future__ import annotations

from _timing import best, timed

from microfab.plants.galvo_slm import galvo_slm_twin
from microfab.process.slm.estimate import dynamics_estimate, naive_estimate, simulate_timeline
from microfab.process.slm.lattice import LatticeSpec, lattice_layer


def main() -> None:
    twin = galvo_slm_twin()
    spec = LatticeSpec(outline_radius_m=47e-3)  # inside the ±49.15 mm field
    t_geom, path = timed(lambda: lattice_layer(0.5 * spec.cell_m, spec))
    est = dynamics_estimate(path, twin)  # warm-up: compile, tables
    simulate_timeline(est.timeline, twin)
    t_dyn, _ = best(lambda: dynamics_estimate(path, twin))
    t_naive, _ = best(lambda: naive_estimate(path))
    t_sim, _ = best(lambda: simulate_timeline(est.timeline, twin), 2)
    print(f"SLM lattice layer: {len(path)} vectors, {est.timeline.total_ticks} ticks of 10 µs")
    print(f"  layer geometry built in {t_geom:.2f} s (not part of the estimate)")
    print(f"  dynamics-aware estimate {t_dyn:.3f} s (goal <= 1 s); scan time {est.total_s:.3f} s")
    print(
        f"  naive L/v estimate      {t_naive * 1e3:.2f} ms: "
        f"dynamics-aware / naive {t_dyn / t_naive:.1f}x"
    )
    print(
        f"  per-sample simulate     {t_sim:.3f} s: simulate / dynamics-aware "
        f"{t_sim / t_dyn:.1f}x faster"
    )


if __name__ == "__main__":
    main()
