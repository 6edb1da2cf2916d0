"""The calibration core's search against a multi-start `least_squares` baseline.

A toy problem of the shape a machine's calibration has (issue 45): 4 free parameters, 2 of
them log-scaled over 3 decades (a stiffness and a damping), 5 fit targets from a smooth but
non-convex model (a resonance, its damping ratio, its quality factor, a settling time and
a ripple term that oscillates with the phase and the stiffness's logarithm, which gives
the landscape many local minima). The targets are the model's values at a known
parameter set, with tolerances of 1 % (so an answer meeting every target exists).

The ripple is run twice: as written (``x1``) and with its frequencies tripled (``x3``,
more local minima). For each of ``SEEDS`` seeds and the same evaluation budget:

* ours: `calibrate` (differential evolution on the normalised box, then `least_squares`),
  conflict sweep off, counting the points the search asked for;
* baseline: `least_squares` (TRF, bounds [0, 1], forward differences) from random starts
  drawn uniformly in the normalised box, each start capped at ``PER_START`` model
  evaluations (Jacobian points included), until the budget is spent.

Printed: per method, the share of seeds that met every target, the median evaluations
until every target was first met (over the seeds that met them), and the median final
worst ``|r|`` (median over the seeds); then ours as ratios against the baseline measured in
the same run (a worst ``|r|`` near 1e-13 is round-off: its ratio says nothing). No asserts.
About 5 s on the 2-core project machine.

With ``--twin laser`` the same two methods run on a real twin instead of the toy: the
seed 004 stage calibration (`microfab.machines.laser_stage.calibration.problem`: 5 free
parameters, the Fig. 3 peak and the per-axis shares within ±0.5 µm as fit targets, about
0.2-0.5 s a run), at ``--budget`` evaluations (default 120) for ``--seeds`` seeds (default
2); printed per seed and method: evaluations to first met (every fit target) and the final
worst fit ``|r|``. About 2-4 min on one core.

Run: ``python benchmarks/bench_calibration.py [--twin laser] [--budget N] [--seeds N]``.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Mapping
from functools import partial

import numpy as np
from scipy.optimize import least_squares

from microfab.calibrate import CalibrationProblem, FreeParameter, Target, calibrate

BUDGET = 400  # evaluations per method and seed (assumed: a few hours of a 30 s twin)
PER_START = 40  # baseline: evaluations per start (about 8 TRF iterations at n = 4)
SEEDS = range(10)
RUGGED = (1.0, 3.0)  # the ripple's frequency factor: the landscape mild, then rugged
TRUE = {"k": 0.02, "c": 0.3, "m": 1.3, "phi": 2.2}  # the toy's answer (assumed)


def model(p: Mapping[str, float], rugged: float = 1.0) -> dict[str, float]:
    """A damped resonance and a ripple: smooth, non-convex in ``phi`` and ``log k``.

    ``rugged`` multiplies the ripple's frequencies (more local minima).
    """
    k, c, m, phi = p["k"], p["c"], p["m"], p["phi"]
    wn = math.sqrt(k / m)
    zeta = c / (2.0 * math.sqrt(k * m))
    return {
        "f_n": wn / (2.0 * math.pi),
        "zeta": zeta,
        "q": 1.0 / (2.0 * zeta),
        "settle": 4.0 / (zeta * wn),
        "ripple": 1.5 + math.sin(rugged * (3.0 * phi + 2.0 * math.log(k))) * math.cos(phi),
    }


def problem(rugged: float) -> CalibrationProblem:
    truth = model(TRUE, rugged)
    targets = [
        Target(name, v, 0.01 * abs(v), "1", "toy: the model at TRUE, 1 % tolerance")
        for name, v in truth.items()
    ]
    params = [
        FreeParameter("k", 1e-3, 1.0, "N/m", "assumed: toy, 3 decades", log=True),
        FreeParameter("c", 1e-2, 10.0, "N s/m", "assumed: toy, 3 decades", log=True),
        FreeParameter("m", 0.5, 2.0, "kg", "assumed: toy"),
        FreeParameter("phi", 0.0, 2.0 * math.pi, "rad", "assumed: toy, one turn"),
    ]
    return CalibrationProblem(targets, params, partial(model, rugged=rugged))


def ours(prob: CalibrationProblem, seed: int, budget: int = BUDGET) -> tuple[int | None, float]:
    res = calibrate(prob, budget=budget, seed=seed, conflict_budget=0)
    return res.first_met, res.worst_fit


def baseline(prob: CalibrationProblem, seed: int, budget: int = BUDGET) -> tuple[int | None, float]:
    rng = np.random.default_rng(seed)
    count = 0
    first_met: int | None = None
    best = math.inf

    class SpentError(Exception):
        pass

    def fun(u: np.ndarray) -> np.ndarray:
        nonlocal count, first_met, best
        if count >= budget:
            raise SpentError
        count += 1
        r = prob.residuals(prob.model_vector(prob.evaluate(prob.values(np.clip(u, 0.0, 1.0)))))
        r = r[list(prob.fit_index)]
        worst = float(np.max(np.abs(r)))
        best = min(best, worst)
        if worst <= 1.0 and first_met is None:
            first_met = count
        return r

    try:
        while count < budget:
            u0 = rng.uniform(0.0, 1.0, len(prob.parameters))
            least_squares(fun, u0, bounds=(0.0, 1.0), method="trf", max_nfev=PER_START)
    except SpentError:
        pass
    return first_met, best


def summary(runs: list[tuple[int | None, float]]) -> tuple[float, float, float]:
    met = [n for n, _ in runs if n is not None]
    share = len(met) / len(runs)
    evals = float(np.median(met)) if met else math.nan
    return share, evals, float(np.median([w for _, w in runs]))


def laser(budget: int, seeds: int) -> None:
    """Both methods on the seed 004 stage twin's calibration (module notes)."""
    from microfab.machines.laser_stage.calibration import problem as laser_problem

    prob = laser_problem()
    print(
        f"laser twin: budget {budget} evaluations, {seeds} seeds, "
        f"{len(prob.parameters)} parameters, {len(prob.fit_index)} fit targets"
    )
    print(f"  {'method':28s} {'seed':>4s} {'evals to met':>12s} {'worst |r|':>10s} {'wall s':>7s}")
    for seed in range(seeds):
        for name, method in (("DE + polish (ours)", ours), ("multi-start least_squares", baseline)):
            t0 = time.perf_counter()
            met, worst = method(prob, seed, budget)
            wall = time.perf_counter() - t0
            shown = "-" if met is None else str(met)
            print(f"  {name:28s} {seed:4d} {shown:>12s} {worst:10.3g} {wall:7.1f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--twin", choices=("laser",), help="run on a real twin, not the toy")
    parser.add_argument("--budget", type=int, default=120, help="evaluations (--twin only)")
    parser.add_argument("--seeds", type=int, default=2, help="seeds (--twin only)")
    args = parser.parse_args()
    if args.twin == "laser":
        laser(args.budget, args.seeds)
        return
    for rugged in RUGGED:
        prob = problem(rugged)
        rows = {
            "DE + polish (ours)": summary([ours(prob, s) for s in SEEDS]),
            "multi-start least_squares": summary([baseline(prob, s) for s in SEEDS]),
        }
        print(
            f"ripple x{rugged:g}: budget {BUDGET} evaluations, {len(SEEDS)} seeds, "
            "4 parameters, 5 fit targets"
        )
        print(f"  {'method':28s} {'met':>5s} {'evals to met (median)':>22s} {'worst |r|':>10s}")
        for name, (share, evals, worst) in rows.items():
            print(f"  {name:28s} {share:5.0%} {evals:22.0f} {worst:10.3g}")
        (s0, e0, w0), (s1, e1, w1) = rows.values()
        print(
            f"  ours / baseline: met share {s0 / s1 if s1 else math.inf:.2f}, "
            f"evaluations to met {e0 / e1:.2f}, final worst |r| {w0 / w1:.2g}"
        )


if __name__ == "__main__":
    main()
