"""Speed of the closed-loop simulators and of the ILC run on the galvo twin.

Prints, in one run on this machine:

1. ILC run at 1 MHz (30 trials, both axes) at 100, 200 and 400 features/s, in multiples
   of real time. Goal: >= 20x. Real time is what the machine itself would take: every
   period it plays, settling period included (2 a trial); the ``rec`` columns count the
   30 recorded periods only (half of that, the stricter figure).
   (a) ``run_msl_ilc`` as a user calls it (twin built, eq. (5) checked, learning loop,
   result with eq. (5) per harmonic), without and with a state directory (the learning
   state written atomically after every trial, a checkpoint: fsync and rename);
   (b) the learning loop alone, `learn` on a built twin (trial checks, digests, limit
   check, record), beside its baseline in the same run: the bare loop ``machine.run`` +
   ``FrequencyILC.update`` (no checks, digests or record);
   (c) the checkpoint per trial, beside its floor in the same run: an atomic write of one
   byte to the same disk (the fsyncs and the rename, no data).
2. Per-sample simulator (numba) steps/s against a pure-Python loop of the same plant and
   controller, and the vectorised lifted LTI path, on one galvo axis; the twin's seeded
   noise, compiled against NumPy's draw (the same numbers).
3. The galvo twin (`SimulatedMachine`, both axes) forced down each of its three paths,
   the same plant and controller: samples/s of `run` and the compiled-over-Python ratio.

Timings are the best of a few repeats (the machine may be shared).

Run: ``make bench`` or ``python benchmarks/bench_sim.py``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import best

from microfab.control.base import LTIController
from microfab.control.ilc import FrequencyILC, Trial
from microfab.io.atomic import atomic_write_bytes
from microfab.machines.galvo.ilc import run_msl_ilc
from microfab.machines.galvo.machine import discrete_controller, galvo_twin
from microfab.machines.learning import learn
from microfab.machines.simulated import SimPath
from microfab.plants.base import LTIPlant
from microfab.plants.galvo import default_galvo_axes
from microfab.sim.loop import simulate, simulate_python
from microfab.sim.lti_fast import LTILoop
from microfab.sim.noise import scaled_normal
from microfab.trajectory.periodic import square_scan

RATES = (100, 200, 400)
TRIALS = 30


def played_s(rate: int, trials: int = TRIALS) -> float:
    """Time the machine plays for ``trials`` trials at ``rate``: settle + recorded period."""
    return 2 * trials / rate


def bench_run_msl_ilc(rate: int, state: bool, repeats: int) -> float:
    """Wall time of ``run_msl_ilc(rate, 30)`` (best of ``repeats``), fresh state each call."""
    axes = default_galvo_axes()

    def call() -> None:
        if not state:
            run_msl_ilc(rate, TRIALS, axes=axes)
            return
        with tempfile.TemporaryDirectory() as d:
            run_msl_ilc(rate, TRIALS, axes=axes, state_dir=d)

    wall, _ = best(call, repeats)
    return wall


def bench_learn(rate: int, repeats: int = 5) -> tuple[float, float]:
    """Best wall time of `learn` and of the bare loop, 30 trials each on a built twin."""
    axes = default_galvo_axes()
    ref = square_scan(rate, (1.0, 1.44), 1e6)

    def loop() -> None:
        machine = galvo_twin(axes, seed=0)
        learn(machine, FrequencyILC(ref, machine.dt, machine.axes), iterations=TRIALS)

    def bare() -> None:
        machine = galvo_twin(axes, seed=0)
        ilc = FrequencyILC(ref, machine.dt, machine.axes)
        u = ilc.initial_input()
        for _ in range(TRIALS):
            y = machine.run(u).output
            u = ilc.update(
                Trial(dt=machine.dt, reference=ref, input=u, output=y, axes=machine.axes)
            )

    t_learn, _ = best(loop, repeats)
    t_bare, _ = best(bare, repeats)
    return t_learn, t_bare


def bench_checkpoint_floor(writes: int = TRIALS, repeats: int = 2) -> float:
    """Time of one atomic write of one byte in the temporary folder, s.

    Measured as the checkpoints of (a) are: ``writes`` in a row, best of ``repeats``.
    """
    with tempfile.TemporaryDirectory() as d:
        target = Path(d) / "probe.bin"

        def row() -> None:
            for _ in range(writes):
                atomic_write_bytes(target, b"x")

        wall, _ = best(row, repeats)
    return wall / writes


def bench_ilc() -> None:
    """Section 1: the ILC run in multiples of real time (see the module docstring)."""
    run_msl_ilc(400, 2, axes=default_galvo_axes())  # warm-up (numba, caches)
    print(f"ILC run on the galvo twin at 1 MHz ({TRIALS} trials, x and y), goal >= 20x real time")
    print("  x: simulated time / wall time; played = every period the machine plays")
    print("  (settle + recorded, 2 a trial), rec = the recorded periods only")
    print("(a) run_msl_ilc(rate, 30), without and with a state directory")
    print(
        f"  {'rate':>8} | {'no state: wall s':>16} {'x played':>8} {'x rec':>6}"
        f" | {'state: wall s':>13} {'x played':>8} {'x rec':>6} | {'state/none':>10}"
    )
    saved: dict[int, tuple[float, float]] = {}
    for rate in RATES:
        t_none = bench_run_msl_ilc(rate, state=False, repeats=3)
        t_state = bench_run_msl_ilc(rate, state=True, repeats=2)
        saved[rate] = (t_none, t_state)
        p = played_s(rate)
        print(
            f"  {rate:>4} f/s | {t_none:16.4f} {p / t_none:8.1f} {p / 2 / t_none:6.1f}"
            f" | {t_state:13.4f} {p / t_state:8.1f} {p / 2 / t_state:6.1f}"
            f" | {t_state / t_none:9.1f}x"
        )
    print("(b) the learning loop alone: learn() on a built twin, beside the bare loop")
    print("    (machine.run + FrequencyILC.update: no trial checks, digests or record)")
    print(
        f"  {'rate':>8} | {'learn: wall s':>13} {'x played':>8} {'x rec':>6}"
        f" | {'bare: wall s':>12} {'x played':>8} | {'learn/bare':>10}"
    )
    for rate in RATES:
        t_learn, t_bare = bench_learn(rate)
        p = played_s(rate)
        print(
            f"  {rate:>4} f/s | {t_learn:13.4f} {p / t_learn:8.1f} {p / 2 / t_learn:6.1f}"
            f" | {t_bare:12.4f} {p / t_bare:8.1f} | {t_learn / t_bare:9.2f}x"
        )
    floor = bench_checkpoint_floor()
    print("(c) checkpoint per trial (state - no state, from (a)), beside its floor: an atomic")
    print(f"    write of 1 byte to the same disk (fsync, rename, fsync dir): {1e3 * floor:.2f} ms")
    for rate in RATES:
        t_none, t_state = saved[rate]
        per = (t_state - t_none) / TRIALS
        print(f"  {rate:>4} f/s: {1e3 * per:6.2f} ms a trial, {per / floor:5.1f}x the floor")


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
    bench_noise()


def bench_noise(n: int = 10_000) -> None:
    """The twin's seeded noise, both axes: compiled draw against NumPy's (same numbers)."""
    scale = np.array([1e-3, 1e-3])
    ours, numpys = np.random.default_rng(0), np.random.default_rng(0)
    scaled_normal(ours, 10, scale)  # compile (or load the cache)
    numpys.standard_normal((10, 2))
    t_np, _ = best(lambda: numpys.standard_normal((n, 2)) * scale[None, :], 50)
    t_nb, _ = best(lambda: scaled_normal(ours, n, scale), 50)
    print(f"seeded noise, {n} samples x 2 axes (one period at 100 f/s), normals/s")
    print(f"  NumPy standard_normal     {2 * n / t_np:12.3g}   (baseline)")
    print(f"  compiled (same numbers)   {2 * n / t_nb:12.3g}   {t_np / t_nb:8.1f}x NumPy")


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
    bench_ilc()
    bench_per_sample()
    bench_paths()


if __name__ == "__main__":
    main()
