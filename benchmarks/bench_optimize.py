"""Reference optimisation of seed 002 (issue 18): both stages against their baselines.

Prints, in one run on this machine:

* **Stage 1** (eqs. 8-12) on letter "r" (sized as the job sizes it: stage 1 gives 0.807 s
  at 1 m/s²), N = 1000, a_max = 1 m/s², μ = 20 µm: our block-structured IPOPT problem
  warm-started from `time_optimal` (goal: ≤ 10 s converged) against the plain Opti
  transcription started at constant speed, the seed's start (goal: ≥ 5x faster; the
  plain one is stopped after ``--plain-cpu`` s of IPOPT time); and T for N and 2N.
* **Stage 2** (eqs. 13-14) at M = 1002 (letter "u" at a_max = 0.21 m/s², T = 2.50 s):
  Gauss-Newton with the networks' Jacobians from PyTorch (goal: ≤ 60 s at M = 1000),
  today's setting (PIQP for the QPs and the start's projection, the networks on one torch
  thread) against the one before issue 34 (IPOPT for the QPs, HiGHS for the projection,
  torch's own thread count) on the same stage 1 and networks, alternated ``--repeat``
  times: time, iterations, Jacobian band, merit (goal: the same final merit ±1 %) and the
  time per phase. IPOPT with CasADi's exact Hessian through the network at M = 200
  (``--exact``; one evaluation of that Hessian takes minutes) is not run.
* For reference: `time_optimal` and TOPP-RA on the same path, kinematic bounds only.

The models: a ``stage-identify`` output (``--model DIR``); without one, the linear model
is identified on the twin here (600 s of random runs, about 15 s) and stage 2 runs on
networks trained for ``--epochs`` epochs on 60 s of twin data (about 90 s). Their
accuracy does not decide the timing, but their Jacobian's band does: after 3 epochs 99 %
of ``Σ|∂φ/∂r|`` lay in the last 2 of 200 inputs (the extrapolated window's base; the
networks had learnt little), after 20 in the last 37, as on the twin's trained networks
(~30), and the QP's cost grows with the band.

Run: ``python benchmarks/bench_optimize.py [--model DIR] [--plain-cpu 300] [--repeat 2]
[--no-stage2 | --stage2-only]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))

from _opti_plain import solve_plain

from microfab.machines.xy_stage.cases import CaseSizes, case_paths
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Settings, solve_stage1

R_HEIGHT_M = 18.95e-3  # the job's sizing step on the twin's model (stage 1: r = 0.807 s)


def _models(args: argparse.Namespace) -> tuple[Any, Any, str]:
    if args.model:
        from microfab.optimize.models import load_models

        m = load_models(args.model, networks=not args.no_stage2)
        return m.linear, m.networks, f"models of {args.model}"
    from microfab.machines.xy_stage.ann import AnnSettings, ann_records, train_networks
    from microfab.machines.xy_stage.identify import linear_study

    t0 = time.perf_counter()
    _, lin = linear_study()
    linear = lin.model.to_continuous()
    nets = None
    if not args.no_stage2:
        settings = AnnSettings(total_s=60.0, max_epochs=args.epochs, epoch_windows=65536)
        train, val = ann_records(settings)
        nets = train_networks(train, val, settings).model
    return linear, nets, f"identified here in {time.perf_counter() - t0:.0f} s (short training)"


def stage1_bench(linear: Any, plain_cpu: float) -> None:
    path = case_paths(CaseSizes(R_HEIGHT_M, 0.1), ["r"])["r"]
    problem = ContourProblem(path, a_max=1.0)
    print(f"stage 1: letter r, S = {path.length * 1e3:.2f} mm, a_max = 1 m/s², μ = 20 µm")
    ours = [solve_stage1(problem, linear, Stage1Settings(n=1000)) for _ in range(2)]
    best = min(ours, key=lambda r: r.wall_s)
    print(f"  ours (blocks, warm start time_optimal), N = 1000: {best.wall_s:.2f} s "
          f"(best of 2), {best.iterations} iterations, {best.status}, T = {best.duration:.4f} s"
          f"  [goal ≤ 10 s]")  # fmt: skip
    from microfab.optimize.stage1 import Stage1Error

    t0 = time.perf_counter()
    try:
        cold = solve_stage1(problem, linear, Stage1Settings(n=1000, warm="constant"))
        print(
            f"  ours from constant speed (the seed's start): {cold.wall_s:.2f} s, "
            f"{cold.iterations} iterations, T = {cold.duration:.4f} s"
        )
    except Stage1Error as exc:
        print(
            f"  ours from constant speed (the seed's start): failed after "
            f"{time.perf_counter() - t0:.1f} s: {exc}"
        )
    twice = solve_stage1(problem, linear, Stage1Settings(n=2000))
    change = 100 * (twice.duration / best.duration - 1)
    print(
        f"  N = 2000: T = {twice.duration:.4f} s ({change:+.2f} % against N = 1000), "
        f"{twice.wall_s:.1f} s  [goal: |change| < 1 %]"
    )
    plain = solve_plain(problem, linear, 1000, max_cpu_s=plain_cpu)
    ratio = plain["wall_s"] / best.wall_s
    bound = "" if plain["status"] == "Solve_Succeeded" else " at least (not converged)"
    print(
        f"  plain Opti transcription from constant speed: {plain['wall_s']:.1f} s, "
        f"{plain['iterations']} iterations, {plain['status']}, T = {plain['T']:.4f} s"
    )
    print(f"  ratio plain / ours: {ratio:.1f}x{bound}  [goal ≥ 5x]")


def kinematic_bench() -> None:
    from microfab.core.limits import MachineLimits
    from microfab.trajectory.optimal import time_optimal

    path = case_paths(CaseSizes(R_HEIGHT_M, 0.1), ["r"])["r"]
    lim = MachineLimits.seed002_stage()
    import dataclasses

    lim = dataclasses.replace(lim, acceleration=(1.0, 1.0))
    t0 = time.perf_counter()
    res = time_optimal(path, lim, n_grid=1000)
    t_ours = time.perf_counter() - t0
    print(
        f"kinematic only (1.5 m/s, 1 m/s² per axis, exact path, stops at corners): "
        f"time_optimal {t_ours:.2f} s, T = {res.duration:.4f} s"
    )
    try:
        import toppra  # noqa: F401
    except ImportError:
        print("  TOPP-RA not installed (pip install 'microfab[topp]')")
        return
    print("  TOPP-RA on the same grid: see benchmarks/bench_topp.py (same planner comparison)")


def _stage2_line(label: str, res: Any, m: int) -> str:
    st2 = res.stage2
    ph = st2.phase_s
    return (
        f"  {label}: {res.wall_s['stage2']:.1f} s, M = {m}, {st2.iterations} iterations, "
        f"band {st2.info['band']}, merit {st2.cost_history[0]:.6g} → {st2.cost_history[-1]:.6g} "
        f"(QPs {ph['qp_s']:.1f} s, networks {ph['networks_s']:.2f} s, "
        f"start projection {ph['project_s']:.2f} s)"
    )


def stage2_bench(linear: Any, nets: Any, exact: bool, repeat: int) -> None:
    """Stage 2 at M ≈ 1000: the solver before issue 34 and today's, in the same run."""
    import os

    from microfab.optimize.pipeline import optimize_reference
    from microfab.optimize.stage2 import Stage2Settings

    path = case_paths(CaseSizes(R_HEIGHT_M, 0.1), ["u"])["u"]
    a = 0.21  # a_max giving M = 1002 (T = 2.50 s) on the twin's linear model
    problem = ContourProblem(path, a_max=a)
    settings = {
        "old (IPOPT QPs, HiGHS projection, torch's threads)": Stage2Settings(
            qp="ipopt", threads=None
        ),
        "new (PIQP QPs and projection, one torch thread)": Stage2Settings(),
    }
    print(f"stage 2: letter u at a_max = {a:g} m/s², same stage 1 and networks for both; "
          f"load {os.getloadavg()[0]:.2f} (1-min) on {os.cpu_count()} cores")  # fmt: skip
    st1 = None
    runs: dict[str, list[Any]] = {k: [] for k in settings}
    for _ in range(repeat):
        for label, st in settings.items():
            res = optimize_reference(problem, linear, nets, stage1=st1, stage2=st)
            st1 = res.stage1
            runs[label].append(res)
            print(_stage2_line(label, res, res.m), flush=True)
    best = {k: min(v, key=lambda r: r.wall_s["stage2"]) for k, v in runs.items()}
    old, new = best.values()
    m_old, m_new = old.stage2.cost_history[-1], new.stage2.cost_history[-1]
    t_old, t_new = old.wall_s["stage2"], new.wall_s["stage2"]
    print(f"  best of {repeat}: old {t_old:.1f} s, new {t_new:.1f} s ({t_old / t_new:.1f}x) "
          f"at M = {new.m}  [goal ≤ 60 s at M = 1000]")  # fmt: skip
    print(f"  final merit: old {m_old:.6g}, new {m_new:.6g} ({100 * (m_new / m_old - 1):+.3f} %)"
          f"  [goal: within ±1 %]; load now {os.getloadavg()[0]:.2f}")  # fmt: skip
    if exact:
        print("  exact-Hessian CasADi at M = 200: not run here (see the closing note)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="", help="output folder of a stage-identify job")
    ap.add_argument("--plain-cpu", type=float, default=300.0,
                    help="IPOPT CPU seconds allowed to the plain transcription")  # fmt: skip
    ap.add_argument("--epochs", type=int, default=20, help="epochs of the short training")
    ap.add_argument("--repeat", type=int, default=2, help="stage-2 runs of each setting")
    ap.add_argument("--exact", action="store_true", help="also the exact-Hessian stage 2")
    ap.add_argument("--no-stage2", action="store_true", help="stage 1 only")
    ap.add_argument("--stage2-only", action="store_true", help="stage 2 only")
    args = ap.parse_args()
    linear, nets, where = _models(args)
    print(f"models: {where}")
    if not args.stage2_only:
        stage1_bench(linear, args.plain_cpu)
        kinematic_bench()
    if not args.no_stage2:
        stage2_bench(linear, nets, args.exact, args.repeat)


if __name__ == "__main__":
    main()
