"""Training speed and accuracy of the per-axis networks of seed 002 (eq. 7, Fig. 5).

Prints, in one run on this machine:

1. Throughput of one training step (batch gather from the 400 Hz series, encoding and
   scaling, forward, backward, Adam) for the seed's network (h = 200, 117 322 weights,
   batches of 16 384) on ``--threads`` CPU threads: windows/s and the time of one epoch of
   4e6 windows (issue 17: about 34 windows per weight).
2. Real runs, the ``stage-identify`` job's training: ``--total-s`` (525 s) of the
   networks' data (`ann_records`: about 60 % random runs, the rest shapes at constant
   speeds, split 80/20 by whole runs, seed 002 §III-C) played on the calibrated twin
   with 2 µm noise, one network per axis trained with epochs of 262 144 random windows,
   the axes side by side in ``--workers`` processes (2), with the job's schedule once on
   the scaled inputs as they are (the training before issue 46) and once whitened (the
   job's now, `microfab.identify.ann_whiten`; `schedules`), on the same data. Prints each
   training's wall time against the 5 min goal (issue 34), the ratio, and the validation
   μ, σ per axis at every 10 kHz sample beside the seed's Table II (ANN on validation
   data: x 3.2, y 6.0 µm) and beside the calibration's proxy σ on the same data
   (`microfab.machines.xy_stage.proxy`; issue 46 asks the two within 25 %).

Run: ``python benchmarks/bench_ann.py [--quick] [--job-only] [--total-s 60]`` (the
comparison takes about 10 min on an idle 2-core machine, the job's schedule alone about 5).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from microfab.identify.ann import build_network, n_weights
from microfab.identify.ann_data import WindowSet, WindowSpec

FS = 10_000.0  # seed 002 Table I
SEED_SIGMA_UM = {"x": 3.2, "y": 6.0}  # seed 002 Table II, non-linear model, validation


def smooth_random_command(
    duration_s: float, seed: int, *, a_range=(1.0, 5.0), limit_m: float = 0.17
) -> np.ndarray:
    """A smooth random (n, 2) command from rest at the origin, m, at 10 kHz.

    Per axis: 8 sinusoids (frequencies log-uniform in 0.3-5 Hz, amplitudes ~ f^-1.5,
    random phases) minus their start value, faded in over 0.5 s (smoothstep); scaled so
    the peak acceleration is a draw from ``a_range`` (m/s², the seed's data reach 5),
    or less when the position would leave ``±limit_m`` or the speed exceed 1.5 m/s.
    """
    rng = np.random.default_rng(seed)
    n = round(duration_s * FS)
    t = np.arange(n) / FS
    ramp = np.clip(t / 0.5, 0.0, 1.0)
    env = ramp**2 * (3 - 2 * ramp)
    out = np.empty((n, 2))
    for a in range(2):
        f = np.exp(rng.uniform(math.log(0.3), math.log(5.0), 8))
        amp = rng.uniform(0.2, 1.0, 8) * f**-1.5
        ph = rng.uniform(0, 2 * np.pi, 8)
        s = (amp * np.sin(2 * np.pi * f * t[:, None] + ph)).sum(axis=1)
        x = env * (s - s[0])
        acc = np.abs(np.diff(x, 2)).max() * FS**2
        vel = np.abs(np.diff(x)).max() * FS
        k = min(rng.uniform(*a_range) / acc, limit_m / np.abs(x).max(), 1.4 / vel)
        out[:, a] = k * x
    return out


def throughput(threads: int, n_steps: int) -> None:
    torch.set_num_threads(threads)
    spec = WindowSpec()
    u = smooth_random_command(60.0, 1)
    ws = WindowSet([(u, u)], spec)
    scal = ws.fit_scaling(0)
    net = build_network(spec.n_inputs, seed=0)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    rng = np.random.default_rng(0)
    times = []
    for k in range(n_steps + 1):
        idx = rng.integers(0, len(ws), 16_384)
        t0 = time.perf_counter()
        x, t = ws.batch(idx, 0)
        xb, tb = torch.from_numpy(scal.scale_inputs(x)), torch.from_numpy(scal.scale_target(t))
        opt.zero_grad()
        loss = torch.nn.functional.mse_loss(net(xb)[:, 0], tb)
        loss.backward()
        opt.step()
        if k:  # the first step warms up
            times.append(time.perf_counter() - t0)
    best = min(times)
    med = float(np.median(times))
    print(f"training step, {n_weights(200)} weights, batch 16384, {threads} threads:")
    print(f"  best {16_384 / best:,.0f} windows/s, median {16_384 / med:,.0f} windows/s")
    print(
        f"  one epoch of 4e6 windows: {4e6 / (16_384 / best):.0f} s (best), "
        f"{4e6 / (16_384 / med):.0f} s (median)"
    )


#: The trainings compared by `real_run`: (name, max epochs, learning-rate decay per epoch,
#: whitening shrinkage or None). Both the job's schedule (`SCHEMA` defaults): "unwhitened"
#: as before issue 46, "job" with the whitened inputs it trains on now.
def schedules() -> list[tuple[str, int, float, float | None]]:
    from microfab.experiments.seed002_stage.job import SCHEMA
    from microfab.identify.ann import AnnConfig

    ann = {k.name: k.default for k in SCHEMA["ann"]}
    return [
        ("unwhitened", ann["max_epochs"], ann["lr_decay"], None),
        ("job", ann["max_epochs"], ann["lr_decay"], AnnConfig().whiten),
    ]


def real_run(
    total_s: float, threads: int, workers: int, which: list[tuple[str, int, float, float | None]]
) -> None:
    """The ``stage-identify`` job's training (its data and epoch settings) on the twin.

    Each schedule of ``which`` trains on the same data, one after the other; prints the
    wall time and the validation σ of each, and the ratio of times.
    """
    from microfab.experiments.seed002_stage.job import EPOCH_WINDOWS, VAL_WINDOWS
    from microfab.identify.stage_ann import ann_config, train_stage_ann
    from microfab.machines.xy_stage.ann import AnnSettings, ann_records
    from microfab.machines.xy_stage.proxy import proxy_sigma

    settings = AnnSettings(total_s=total_s, epoch_windows=EPOCH_WINDOWS,
                           val_windows=VAL_WINDOWS, threads=threads, workers=workers)  # fmt: skip
    t0 = time.perf_counter()
    train, val = ann_records(settings)
    t_sim = time.perf_counter() - t0
    print(
        f"twin: {total_s:g} s of the networks' data ({len(train.records)} training and "
        f"{len(val.records)} validation runs) made and played in {t_sim:.1f} s; "
        f"{EPOCH_WINDOWS} windows per epoch, {workers} worker process(es) of {threads} "
        f"thread(s); goal: training <= 300 s on 2 cores (issue 34)",
        flush=True,
    )
    lin = linear_baseline([(r.u, r.y) for r in val.records])
    t1 = time.perf_counter()
    px = dict(zip(("x", "y"), proxy_sigma(train.records, val.records, train.dt), strict=True))
    print(f"proxy (xy_stage.proxy): sigma x {px['x'] * 1e6:.2f} um, y {px['y'] * 1e6:.2f} um "
          f"in {time.perf_counter() - t1:.1f} s", flush=True)  # fmt: skip
    times = {}
    for name, epochs, decay, whiten in which:
        config = ann_config(
            1.0 / train.dt, ("x", "y"), max_epochs=epochs, lr_decay=decay,
            epoch_windows=EPOCH_WINDOWS, val_windows=VAL_WINDOWS, seed=settings.seed,
            threads=threads, workers=workers, whiten=whiten,
        )  # fmt: skip
        t1 = time.perf_counter()
        fit = train_stage_ann(train.records, val.records, config)
        times[name] = time.perf_counter() - t1
        ep = ", ".join(f"{a} {fit.model.info['axes'][a]['epochs']}" for a in fit.model.axes)
        print(f"{name}: {epochs} epochs at most, decay {decay:g}/epoch, whiten {whiten}: "
              f"training "
              f"{times[name]:.0f} s (epochs run: {ep})", flush=True)  # fmt: skip
        for a in fit.model.axes:
            e = fit.validation[a]
            print(
                f"  {a}: validation mu {e.mu * 1e6:+.2f} um, sigma {e.sigma * 1e6:.2f} um "
                f"(seed Table II: {SEED_SIGMA_UM[a]} um; command as prediction "
                f"{lin[a]:.1f} um; networks / proxy {e.sigma / px[a]:.2f})",
                flush=True,
            )
    if len(times) == 2:
        (n0, t0_), (n1, t1_) = times.items()
        print(f"time {n1} / {n0}: {t1_ / t0_:.2f}")


def linear_baseline(val) -> dict[str, float]:
    """σ of ``measured - command`` on the validation runs (the error the ANN explains)."""
    e = np.concatenate([m - u for u, m in val])
    return {"x": float(e[:, 0].std() * 1e6), "y": float(e[:, 1].std() * 1e6)}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--threads", type=int, default=2, help="threads of the throughput test")
    p.add_argument("--train-threads", type=int, default=1, help="threads of the real run")
    p.add_argument("--workers", type=int, default=2, help="axes trained at once (processes)")
    p.add_argument("--total-s", type=float, default=525.0, help="data, s (the job's 525)")
    p.add_argument("--job-only", action="store_true", help="only the job's schedule")
    p.add_argument("--quick", action="store_true", help="20 s of data, 2 epochs")
    args = p.parse_args()
    for threads in sorted({1, args.threads}):
        throughput(threads, 3 if args.quick else 10)
    which = schedules()
    if args.quick:
        real_run(20.0, args.train_threads, args.workers, [(n, 2, d, w) for n, _, d, w in which])
    else:
        real_run(args.total_s, args.train_threads, args.workers,
                 which[1:] if args.job_only else which)  # fmt: skip


if __name__ == "__main__":
    main()
