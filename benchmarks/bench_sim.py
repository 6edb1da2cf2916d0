"""Speed of the closed-loop simulators and of the ILC run on the galvo twin.

Prints, in one run on this machine:

1. ILC run at 1 MHz (30 iterations, both axes, settle period + measured period per trial):
   simulated seconds per wall second, per scan rate. Goal: >= 20x real time.
   (a) ``run_msl_ilc`` as a user calls it (twin built, eq. (5) checked, learning loop
   with its trial checks and record): simulated time = 30 periods (the recorded ones),
   best of 2 calls after one warm-up call (numba, caches);
   (b) the bare loop ``machine.run`` + ``FrequencyILC.update`` on a prebuilt twin:
   simulated time = every period played (settling included).
2. Per-sample simulator (numba) steps/s against a pure-Python loop of the same plant and
   controller, and the vectorised lifted LTI path, on one galvo axis.
3. The galvo twin (`SimulatedMachine`, both axes) forced down each of its three paths,
   the same plant and controller: samples/s of `run` and the compiled-over-Python ratio.

Timings are the best of a few repeats (the machine may be shared).

Run: ``make bench`` or ``python benchmarks/bench_sim.py``.
"""

from __future__ import annotations

import time

import numpy as np
from _timing import best

from microfab.control.base import LTIController
from microfab.control.ilc import FrequencyILC, Trial
from microfab.experiments.seed000_msl.run import run_msl_ilc
from microfab.machines.galvo import discrete_controller, galvo_twin
from microfab.machines.simulated import SimPath
from microfab.plants.base import LTIPlant
from microfab.plants.galvo import default_galvo_axes
from microfab.sim.loop import simulate, simulate_python
from microfab.sim.lti_fast import LTILoop
from microfab.trajectory.periodic import square_scan


def bench_ilc(rate: int, iterations: int = 30) -> tuple[float, float]:
    axes = default_galvo_axes()
    machine = galvo_twin(axes, seed=0)
    ref = square_scan(rate, (1.0, 1.44), 1e6)
    machine.run(ref)  # warm-up (numba compile, caches)
    machine.samples_simulated = 0
    ilc = FrequencyILC(ref, machine.dt, machine.axes)
    u = ilc.initial_input()
    t0 = time.perf_counter()
    for _ in range(iterations):
        y = machine.run(u).output
        u = ilc.update(Trial(dt=machine.dt, reference=ref, input=u, output=y, axes=machine.axes))
    wall = time.perf_counter() - t0
    sim_s = machine.samples_simulated * machine.dt
    return sim_s, wall


def bench_run_msl_ilc(rate: int, iterations: int = 30, repeats: int = 2) -> tuple[float, float]:
    """``run_msl_ilc`` wall time (best of ``repeats``) and the simulated time it records."""
    axes = default_galvo_axes()
    wall, _ = best(lambda: run_msl_ilc(rate, iterations, axes=axes), repeats)
    return iterations / rate, wall


def bench_per_sample(n_fast: int = 1_000_000, n_py: int = 20_000) -> None:
    ax = default_galvo_axes()["x"]
    plant, ctrl = LTIPlant(ax.discrete_plant()), LTIController(discrete_controller(ax))
    rng = np.random.default_rng(0)
    ref = np.tile(square_scan(400, (1.0, 1.44), 1e6)[:, :1], (n_fast // 2500, 1))
    noise = rng.normal(0, ax.noise_rms_v, ref.shape)
    simulate(plant, ctrl, ref[:100], noise[:100])  # compile
    t_numba, _ = best(lambda: simulate(plant, ctrl, ref, noise))
    t_py, _ = best(lambda: simulate_python(plant, ctrl, ref[:n_py], noise[:n_py]))
    loop = LTILoop([ax.discrete_plant()], [discrete_controller(ax)])
    loop.run(ref[:100], noise[:100])

    def vec() -> None:
        loop.reset()
        loop.run(ref, noise, with_command=False)

    t_vec, _ = best(vec)
    s_numba, s_py, s_vec = n_fast / t_numba, n_py / t_py, n_fast / t_vec
    print("\nper-sample simulator, one galvo axis (12 states), steps/s")
    print(f"  pure-Python loop          {s_py:12.3g}   (baseline)")
    print(f"  numba per-sample loop     {s_numba:12.3g}   {s_numba / s_py:8.0f}x Python")
    print(f"  vectorised lifted LTI     {s_vec:12.3g}   {s_vec / s_py:8.0f}x Python")


def bench_paths(rate: int = 400) -> None:
    """The galvo twin down each path: same plant, controller, noise; one `run` each."""
    ref = square_scan(rate, (1.0, 1.44), 1e6)
    speed = {}
    for path in SimPath:
        m = galvo_twin(seed=0, path=path)
        m.run(ref)  # warm-up (numba compile, caches)
        # a run takes ~0.3 s on the Python path and ~1 ms on the others: more repeats of
        # the short ones, so that a brief busy spell of the machine does not decide
        repeats = 2 if path == "python" else 20
        n0 = m.samples_simulated
        wall, _ = best(lambda m=m: m.run(ref, with_actuator=True), repeats)
        per_run = (m.samples_simulated - n0) // repeats
        speed[path] = per_run * len(m.axes) / wall  # axis-samples per s
    print(f"\ngalvo twin, {rate} f/s square, run() with actuator, both axes: axis-samples/s")
    print(f"  {'python':<10} {speed[SimPath.PYTHON]:12.3g}   (baseline)")
    for path in (SimPath.COMPILED, SimPath.LIFTED):
        ratio = speed[path] / speed[SimPath.PYTHON]
        print(f"  {path.value:<10} {speed[path]:12.3g}   {ratio:8.0f}x Python")
    print(
        "  compiled per-sample loop / Python loop, same controller: "
        f"{speed[SimPath.COMPILED] / speed[SimPath.PYTHON]:.0f}x"
    )


def main() -> None:
    run_msl_ilc(400, 2, axes=default_galvo_axes())  # warm-up (numba, caches)
    head = f"  {'rate':>12} {'simulated s':>12} {'wall s':>8} {'x real time':>12}"
    print("ILC run on the galvo twin at 1 MHz (30 iterations, x and y), goal >= 20x real time")
    print("(a) run_msl_ilc(rate, 30): simulated = 30 recorded periods")
    print(head)
    for rate in (100, 200, 400):
        sim_s, wall = bench_run_msl_ilc(rate)
        print(f"  {rate:>8} f/s {sim_s:12.3f} {wall:8.3f} {sim_s / wall:12.1f}")
    print("(b) machine.run + FrequencyILC.update: simulated = every period played")
    print(head)
    for rate in (100, 200, 400):
        sim_s, wall = bench_ilc(rate)
        print(f"  {rate:>8} f/s {sim_s:12.3f} {wall:8.3f} {sim_s / wall:12.1f}")
    bench_per_sample()
    bench_paths()


if __name__ == "__main__":
    main()
