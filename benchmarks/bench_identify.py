"""Speed and memory of the seed 002 linear identification, and the XY twin's speed.

Prints, in one run on this machine:

1. Subspace identification (`identify_subspace`) of the 2-in / 2-out XY stage from
   6e6 samples: 600 s of `random_runs` (seed 002 §III-C 1: 6×10⁶ points at 10 kHz) played
   through the compiled twin (`xy_stage_twin`, 2 µm output noise) from rest, 14 runs.

   a. Ours at 10 kHz, the default `SubspaceConfig()` (order 4, MOESP, D = 0) and
      ``SubspaceConfig(order=4, feedthrough=True)``; the latter also on the records
      decimated by 10 to 1 kHz (``scipy.signal.decimate``: its default 201-tap Hamming FIR
      low-pass at the new Nyquist frequency, 500 Hz, run forwards and backwards (zero
      phase) over input and output alike; assumed: the filter `identify` does not yet
      have). Wall time (best of 2 after a warm-up), and the peak memory of one call in a
      fresh process: resident (whole process, data included, and above the level after
      loading) and `tracemalloc` (NumPy buffers allocated during the call). Goals (issue
      17): <= 15 s and <= 1 GB at 6e6 samples.
   b. Baseline SIPPY (``sippy_unipi``) N4SID, order 4, its default horizon f = 20, D
      estimated, on the first 2e5 and 4e5 samples of the 10 kHz record (the runs joined:
      each starts and ends at rest at the origin), best of 2 fresh processes each. Its
      Hankel matrices and SVDs grow linearly with N: its time is extrapolated to 6e6
      samples in proportion to N at the lower of its two times per sample (a line through
      two points swung by a factor 3 between runs on the shared machine: its time varies
      by up to 2x from run to run), its memory (resident above the loaded data, which
      does not vary) along the line through the two points. Ours on
      the same two subsets with SIPPY's settings (block rows 20, D estimated, x0 = 0).
      SIPPY's time is one call of its ``system_identification`` (import excluded), which
      also simulates its model (a Python loop) and solves for its Kalman gain; ours
      likewise fits B, D, x0 and simulates (the error σ) within its call.
   c. Baseline ``nfoursid`` (PO-MOESP, 20 block rows, order 4) on 4000 and 8000 samples
      only, best of 2 fresh processes: it takes a full SVD of the (2 × 20) × N
      projection, whose N × N right factor makes memory and time grow with N²;
      extrapolated along a + c N² through the two points.
   d. Fits, ours against SIPPY's on the same data from rest: the largest relative
      difference of matched poles, and the simulated outputs' difference (RMS, per axis)
      relative to the output's RMS (issue 17: within 0.1 %) and to SIPPY's own error σ;
      on the 4e5-sample 10 kHz subset and on 1e5 samples (100 s) of the 1 kHz record.

2. The twin (`xy_stage_twin` through `sim.loop.simulate` with ``SetPoint(2)``) on 10 s of
   random runs: real-time factor, best of 5 after a warm-up (goal >= 50x).

A missing baseline package is skipped with a note (`pip install microfab[baselines]`).
numba compilation is excluded (every path runs once on a short piece first). No asserts:
the figures are printed next to their goals. About 5 min on the 2-core project machine.

Run: ``make bench`` or ``python benchmarks/bench_identify.py``.
"""

from __future__ import annotations

import importlib
import os
import tempfile
import time
import warnings
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import scipy.signal
from _timing import MB, ChildRun, best, in_child
from scipy.optimize import linear_sum_assignment

from microfab.control.setpoint import SetPoint
from microfab.identify.excitation import random_runs
from microfab.identify.subspace import IORun, SubspaceConfig, SubspaceModel, identify_subspace
from microfab.identify.subspace_fit import simulate_ss
from microfab.plants.xy_stage import XYStagePlant, xy_stage_twin
from microfab.sim.loop import LoopState, simulate

TOTAL_S = 600.0  # seed 002 §III-C 1: 6e6 samples at 10 kHz
DATA_SEED = 0
DECIMATE = 10  # 10 kHz -> 1 kHz (the lead's finding: order-4 fits need 1 kHz + D)
SIPPY_N = (200_000, 400_000)  # 10 kHz samples SIPPY is run on (20 s, 40 s)
SIPPY_N_1KHZ = 100_000  # 1 kHz samples of the fit comparison there (100 s)
NFOURSID_N = (4_000, 8_000)  # its N x N SVD factor: 0.13 and 0.5 GB
HORIZON = 20  # SIPPY's default SS_f; nfoursid and our comparison runs use it too
TWIN_S = 10.0  # twin speed: 10 s of random runs
SECONDS_GOAL = 15.0  # issue 17: subspace ID of 6e6 samples
MEMORY_GOAL = 1e9  # bytes, issue 17
FIT_GOAL = 1e-3  # issue 17: "fit within 0.1 % of SIPPY's"
RTF_GOAL = 50.0  # issue 17: twin >= 50x real time
GB = 1e9


# --- data ------------------------------------------------------------------------------------


def twin_state(twin: XYStagePlant, first: np.ndarray) -> LoopState:
    """Loop state at rest at the first command (SetPoint has no state)."""
    return LoopState(
        plant=twin.state_at((float(first[0]), float(first[1]))),
        controller=np.zeros(0),
        observer=np.zeros(0),
        command=np.array(first, dtype=float),
    )


def make_data() -> tuple[list[IORun], float, float]:
    """600 s of random runs through the twin with noise: the runs, build s, simulate s."""
    t0 = time.perf_counter()
    runs = random_runs(TOTAL_S, seed=DATA_SEED)
    t_runs = time.perf_counter() - t0
    twin = xy_stage_twin()
    first = runs[0].command
    simulate(twin, SetPoint(2), first[:200], twin.noise(200), twin_state(twin, first[0]))
    out = []
    t0 = time.perf_counter()
    for k, run in enumerate(runs):
        cmd = np.asarray(run.command)
        res = simulate(
            twin, SetPoint(2), cmd, twin.noise(run.n_samples, seed=k), twin_state(twin, cmd[0])
        )
        out.append(IORun(cmd, np.asarray(res.measured)))
    return out, t_runs, time.perf_counter() - t0


def decimate_runs(runs: list[IORun], q: int) -> list[IORun]:
    """Each run's input and output low-passed and decimated by ``q`` (module docstring)."""
    return [
        IORun(
            scipy.signal.decimate(r.u, q, ftype="fir", axis=0, zero_phase=True),
            scipy.signal.decimate(r.y, q, ftype="fir", axis=0, zero_phase=True),
        )
        for r in runs
    ]


def joined(runs: list[IORun]) -> tuple[np.ndarray, np.ndarray]:
    """The runs end to end (each from rest at the origin to rest there): one record."""
    return np.concatenate([r.u for r in runs]), np.concatenate([r.y for r in runs])


def save_runs(runs: list[IORun], path: Path) -> Path:
    np.savez(path, *[a for r in runs for a in (r.u, r.y)])
    return path


# --- work done in fresh processes (module level: spawn pickles them by name) -------------------


def load_runs(path: str, dt: float, cfg: SubspaceConfig) -> tuple[list[IORun], float, Any]:
    with np.load(path) as z:
        arrays = [z[f"arr_{k}"] for k in range(len(z.files))]
    return [IORun(arrays[k], arrays[k + 1]) for k in range(0, len(arrays), 2)], dt, cfg


def load_record(path: str, n: int, dt: float, extra: Any) -> tuple[Any, ...]:
    with np.load(path) as z:
        return np.array(z["u"][:n]), np.array(z["y"][:n]), dt, extra


def work_ours(data: tuple[Any, float, SubspaceConfig]) -> SubspaceModel:
    runs, dt, cfg = data
    return identify_subspace(runs, dt, cfg)


def load_sippy(path: str, n: int, dt: float, module: str) -> tuple[Any, ...]:
    """The record's first ``n`` samples, SIPPY imported first (its import is not timed)."""
    importlib.import_module(module)
    return load_record(path, n, dt, module)


def load_nfoursid(path: str, n: int, dt: float) -> tuple[Any, ...]:
    """The record's first ``n`` samples, pandas and nfoursid imported first (not timed)."""
    importlib.import_module("pandas")
    importlib.import_module("nfoursid.nfoursid")
    return load_record(path, n, dt, None)


def work_sippy(data: tuple[np.ndarray, np.ndarray, float, str]) -> tuple[np.ndarray, ...]:
    """SIPPY's N4SID (its ``system_identification``, which also simulates its model)."""
    u, y, dt, module = data
    sippy = importlib.import_module(module)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")  # an unstable model overflows in its own residual
        model = sippy.system_identification(
            y.T,
            u.T,
            "N4SID",
            SS_fixed_order=4,
            SS_f=HORIZON,
            SS_D_required=True,
            tsample=dt,
        )
    return tuple(np.array(m, dtype=float) for m in (model.A, model.B, model.C, model.D))


def work_nfoursid(data: tuple[np.ndarray, np.ndarray, float, Any]) -> tuple[np.ndarray, ...]:
    """nfoursid's PO-MOESP: its DataFrame, QR, order-4 state space."""
    import pandas as pd
    from nfoursid.nfoursid import NFourSID

    u, y, _, _ = data
    frame = pd.DataFrame(np.column_stack([u, y]), columns=["ux", "uy", "yx", "yy"])
    nf = NFourSID(
        frame, output_columns=["yx", "yy"], input_columns=["ux", "uy"], num_block_rows=HORIZON
    )
    nf.subspace_identification()
    ss, _ = nf.system_identification(rank=4)
    return tuple(np.array(m, dtype=float) for m in (ss.a, ss.b, ss.c, ss.d))


def warm_up() -> None:
    """Compile (or load from numba's cache, which fresh processes then share) the kernels."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal((4000, 2))
    y = scipy.signal.lfilter([0.0, 0.1], [1.0, -0.9], u, axis=0)
    for ft in (False, True):
        identify_subspace(IORun(u, y), 1e-3, SubspaceConfig(order=2, feedthrough=ft))


# --- baselines -------------------------------------------------------------------------------


def find_sippy() -> str | None:
    """Importable name of SIPPY (``sippy_unipi``, older releases ``sippy``), or None."""
    for name in ("sippy_unipi", "sippy"):
        try:
            mod: ModuleType = importlib.import_module(name)
        except ImportError:
            continue
        if hasattr(mod, "system_identification"):
            return name
    return None


def have_nfoursid() -> bool:
    try:
        importlib.import_module("pandas")
        importlib.import_module("nfoursid.nfoursid")
    except ImportError:
        return False
    return True


def extrapolate(ns: tuple[int, int], vs: tuple[float, float], n: float, power: int) -> float:
    """``a + c N^power`` through two points, at ``n`` (proportional if c comes out <= 0)."""
    x0, x1 = float(ns[0]) ** power, float(ns[1]) ** power
    c = (vs[1] - vs[0]) / (x1 - x0)
    if c <= 0.0:
        return vs[1] * float(n) ** power / x1
    return vs[0] + c * (float(n) ** power - x0)


# --- fits ------------------------------------------------------------------------------------


def cont_poles(a: np.ndarray, dt: float) -> np.ndarray:
    return np.log(np.linalg.eigvals(a).astype(complex)) / dt


def compare(
    ours: SubspaceModel, theirs: tuple[np.ndarray, ...], u: np.ndarray, y: np.ndarray, dt: float
) -> dict[str, Any]:
    """Poles and simulated outputs (from rest) of our model against a baseline's (A, B, C, D)."""
    po, pt = cont_poles(ours.a, dt), cont_poles(theirs[0], dt)
    rows, cols = linear_sum_assignment(np.abs(po[:, None] - pt[None, :]))
    pole_rel = float(np.max(np.abs(po[rows] - pt[cols]) / np.abs(pt[cols])))
    stable = bool(np.all(np.abs(np.linalg.eigvals(theirs[0])) < 1.0))
    out: dict[str, Any] = {
        "poles_ours": np.sort_complex(po),
        "poles_theirs": np.sort_complex(pt),
        "pole_rel": pole_rel,
        "stable_theirs": stable,
        "nyquist": float(np.pi / dt),
    }
    if not stable:  # its simulation diverges: no output comparison
        return out
    yo = simulate_ss(ours.a, ours.b, ours.c, ours.d, u, np.zeros(ours.order))
    yt = simulate_ss(*theirs, u, np.zeros(theirs[0].shape[0]))
    diff = np.sqrt(np.mean((yo - yt) ** 2, axis=0))
    sig_o, sig_t = np.std(y - yo, axis=0), np.std(y - yt, axis=0)
    out |= {
        "out_rel": diff / np.sqrt(np.mean(y**2, axis=0)),
        "vs_sigma": diff / sig_t,
        "sigma_ours": sig_o,
        "sigma_theirs": sig_t,
        "sigma_rel": sig_o / sig_t - 1.0,
    }
    return out


def fmt_poles(p: np.ndarray) -> str:
    return ", ".join(
        f"{z.real:.1f}{z.imag:+.1f}j" if abs(z.imag) > 1e-9 else f"{z.real:.1f}"
        for z in p
        if z.imag >= -1e-9
    )


def print_compare(label: str, c: dict[str, Any]) -> None:
    print(f"    {label}")
    print(f"      poles ours   (rad/s, upper half): {fmt_poles(c['poles_ours'])}")
    note = "" if c["stable_theirs"] else "   UNSTABLE"
    if np.any(np.isclose(np.abs(c["poles_theirs"].imag), c["nyquist"])):
        note += f"   (±{c['nyquist']:.1f}j = π/dt: a negative real discrete pole)"
    print(f"      poles SIPPY  (rad/s, upper half): {fmt_poles(c['poles_theirs'])}{note}")
    print(f"      largest relative difference of matched poles  {c['pole_rel']:.3g}")
    if not c["stable_theirs"]:
        print("      SIPPY's model is unstable: its simulation diverges, outputs not compared")
        return
    print(
        "      simulated outputs from rest, RMS(ours - SIPPY) x y: "
        + "  ".join(f"{v:.2e}" for v in c["out_rel"])
        + " of RMS(y), "
        + "  ".join(f"{v:.2f}" for v in c["vs_sigma"])
        + " of SIPPY's error σ"
    )
    print(
        "      error σ (µm) x y: ours "
        + " ".join(f"{v * 1e6:.2f}" for v in c["sigma_ours"])
        + ", SIPPY "
        + " ".join(f"{v * 1e6:.2f}" for v in c["sigma_theirs"])
        + ": ours/SIPPY - 1 "
        + " ".join(f"{v:+.2%}" for v in c["sigma_rel"])
    )


# --- benches ---------------------------------------------------------------------------------


def ours_child(path: Path, dt: float, cfg: SubspaceConfig) -> ChildRun:
    return in_child(load_runs, (str(path), dt, cfg), work_ours, trace=True)


def mem_line(c: ChildRun) -> str:
    return (
        f"peak RSS {c.peak_rss / MB:6.0f} MB (process, data in), "
        f"+{c.added_rss / MB:5.0f} MB over the loaded data, traced {c.traced / MB:5.0f} MB"
    )


def model_line(m: SubspaceModel) -> str:
    try:
        tau = f"{m.time_constants_s()[0] * 1e3:.1f} ms"
    except ValueError:
        tau = "n/a (a negative real pole)"
    sig = " ".join(f"{v * 1e6:.1f}" for v in m.fit_std)
    return f"fit σ x y {sig} µm, slowest time constant {tau}"


def bench_twin(repeats: int = 5) -> tuple[int, float]:
    """Samples and best wall time of the twin on ``TWIN_S`` of random runs."""
    twin = xy_stage_twin()
    runs = random_runs(TWIN_S, seed=1)
    cmds = [np.asarray(r.command) for r in runs]
    noises = [twin.noise(c.shape[0], seed=k) for k, c in enumerate(cmds)]
    simulate(twin, SetPoint(2), cmds[0][:200], noises[0][:200], twin_state(twin, cmds[0][0]))

    def play() -> None:
        for c, v in zip(cmds, noises, strict=True):
            simulate(twin, SetPoint(2), c, v, twin_state(twin, c[0]))

    t, _ = best(play, repeats)
    return sum(c.shape[0] for c in cmds), t


def main() -> None:
    t_start = time.perf_counter()
    rows: list[tuple[str, str, str, bool | None]] = []
    print("seed 002 linear identification: 2-in / 2-out XY stage twin, 10 kHz")
    print(f"(load average at the start {load_average()}: the timings share the machine)")
    runs, t_gen, t_sim = make_data()
    n_all = sum(r.n_samples for r in runs)
    dt = 1e-4  # seed 002 Table I: 10 kHz
    print(
        f"\n1. subspace ID of {n_all:.3g} samples ({len(runs)} random runs, {TOTAL_S:g} s; "
        f"built in {t_gen:.1f} s, through the twin in {t_sim:.1f} s)"
    )
    warm_up()
    t_dec, dec = best(lambda: decimate_runs(runs, DECIMATE), 1)
    n_dec = sum(r.n_samples for r in dec)
    sippy = find_sippy()
    nfs = have_nfoursid()

    with tempfile.TemporaryDirectory() as tmp:
        p_runs = save_runs(runs, Path(tmp) / "runs.npz")
        p_dec = save_runs(dec, Path(tmp) / "dec.npz")
        u10, y10 = joined(runs)
        np.savez(Path(tmp) / "rec10.npz", u=u10, y=y10)
        u1, y1 = joined(dec)
        np.savez(Path(tmp) / "rec1.npz", u=u1, y=y1)

        # a. ours
        print("\n  a. ours (identify_subspace), best of 2; memory of one call in a fresh process")
        cases = [
            (
                "10 kHz, default",
                "10 kHz, SubspaceConfig() (order 4, D = 0)",
                runs,
                p_runs,
                dt,
                SubspaceConfig(),
            ),
            (
                "10 kHz, order 4 + D",
                "10 kHz, order 4, feedthrough",
                runs,
                p_runs,
                dt,
                SubspaceConfig(order=4, feedthrough=True),
            ),
            (
                "1 kHz, order 4 + D",
                f"1 kHz (decimated by {DECIMATE}), order 4, feedthrough",
                dec,
                p_dec,
                dt * DECIMATE,
                SubspaceConfig(order=4, feedthrough=True),
            ),
        ]
        ours_6e6: dict[str, float] = {}
        for short, label, data, path, step, cfg in cases:
            t, model = best(lambda d=data, s=step, c=cfg: identify_subspace(d, s, c), 2)
            child = ours_child(path, step, cfg)
            n = sum(r.n_samples for r in data)
            print(f"    {label}: {n:.3g} samples")
            print(f"      {t:6.2f} s   {mem_line(child)}")
            print(f"      {model_line(model)}")
            ours_6e6[label] = t
            if step == dt:
                rows.append(
                    (f"ours {short}, s", f"<= {SECONDS_GOAL:g}", f"{t:.1f}", t <= SECONDS_GOAL)
                )
                rows.append(
                    (
                        f"ours {short}, GB",
                        f"<= {MEMORY_GOAL / GB:g}",
                        f"{child.peak_rss / GB:.2f}",
                        child.peak_rss <= MEMORY_GOAL,
                    )
                )
        print(
            f"    decimation of all {len(runs)} runs (u and y) {t_dec:.2f} s: "
            f"1 kHz path in all {t_dec + ours_6e6[cases[2][1]]:.2f} s for {n_dec:.3g} samples"
        )
        t_ours = ours_6e6[cases[1][1]]

        # b. SIPPY
        rec10 = str(Path(tmp) / "rec10.npz")
        cmp10 = None
        same = SubspaceConfig(order=4, block_rows=HORIZON, feedthrough=True, initial_state="zero")
        if sippy is None:
            print("\n  b. SIPPY: not installed, skipped (pip install 'microfab[baselines]')")
        else:
            print(
                f"\n  b. SIPPY ({sippy}) N4SID, order 4, f = {HORIZON}, D estimated; "
                "best of 2 fresh processes each"
            )
            s_t, s_m = [], []
            for n in SIPPY_N:
                c = in_child(load_sippy, (rec10, n, dt, sippy), work_sippy, repeats=2)
                u, y = u10[:n], y10[:n]
                t_o, m_o = best(lambda u=u, y=y: identify_subspace(IORun(u, y), dt, same), 2)
                s_t.append(c.wall_s)
                s_m.append(c.added_rss)
                print(
                    f"    {n:.3g} samples: SIPPY {c.wall_s:6.2f} s, +{c.added_rss / MB:5.0f} MB "
                    f"over the data (peak RSS {c.peak_rss / MB:.0f} MB); ours, same settings "
                    f"{t_o:5.2f} s: {c.wall_s / t_o:5.0f}x faster"
                )
                cmp10 = (m_o, c.result, u, y)
            per = min(t / n for t, n in zip(s_t, SIPPY_N, strict=True))
            t_ex = per * n_all  # the least disturbed time per sample (see the docstring)
            m_ex = extrapolate(SIPPY_N, (s_m[0], s_m[1]), n_all, 1)
            fits = "fits" if m_ex < _mem_total() else "does not fit"
            print(
                f"    extrapolated to {n_all:.3g} samples: {t_ex:.0f} s ({per * 1e6:.0f} µs a "
                f"sample, the lower of the two), {m_ex / GB:.1f} GB over the data (the line "
                f"through the two points; {fits} in this "
                f"machine's {_mem_total() / GB:.0f} GB; issue 17 quotes about 120 s, 7.5 GB)"
            )
            ratio = t_ex / t_ours
            print(
                f"    ours at {n_all:.3g} (order 4, feedthrough) {t_ours:.1f} s: "
                f"{ratio:.0f}x faster than SIPPY extrapolated"
            )
            rows.append(("SIPPY 6e6 (extrapolated) / ours", "> 1", f"{ratio:.0f}x", ratio > 1))

        # c. nfoursid
        if not nfs:
            print("\n  c. nfoursid: not installed (or pandas missing), skipped")
        else:
            print(f"\n  c. nfoursid, {HORIZON} block rows, order 4; best of 2 fresh processes each")
            n_t, n_m = [], []
            for n in NFOURSID_N:
                c = in_child(load_nfoursid, (rec10, n, dt), work_nfoursid, repeats=2)
                n_t.append(c.wall_s)
                n_m.append(c.added_rss)
                print(f"    {n:.3g} samples: {c.wall_s:6.2f} s, +{c.added_rss / MB:5.0f} MB")
            t_ex = extrapolate(NFOURSID_N, (n_t[0], n_t[1]), n_all, 2)
            m_ex = extrapolate(NFOURSID_N, (n_m[0], n_m[1]), n_all, 2)
            ram = _mem_total()
            c2 = (n_m[1] - n_m[0]) / (NFOURSID_N[1] ** 2 - NFOURSID_N[0] ** 2)
            n_fit = np.sqrt(max(ram - n_m[0], 0.0) / c2 + NFOURSID_N[0] ** 2) if c2 > 0 else 0
            print(
                f"    along a + c N² to {n_all:.3g} samples: {t_ex:.3g} s, {m_ex / GB:.3g} GB; "
                f"this machine's {ram / GB:.0f} GB hold N <= {n_fit:.3g}"
            )

        # d. fits
        if cmp10 is None:
            print("\n  d. fits against SIPPY: skipped (SIPPY not installed)")
        else:
            print("\n  d. fits against SIPPY (ours: order 4, block rows 20, D, x0 = 0)")
            m_o, theirs, u, y = cmp10
            print_compare(
                f"10 kHz, first {SIPPY_N[-1]:.3g} samples", compare(m_o, theirs, u, y, dt)
            )
            d1 = dt * DECIMATE
            c = in_child(
                load_sippy, (str(Path(tmp) / "rec1.npz"), SIPPY_N_1KHZ, d1, sippy), work_sippy
            )
            u, y = u1[:SIPPY_N_1KHZ], y1[:SIPPY_N_1KHZ]
            for w in ("moesp", "n4sid"):
                cfg = SubspaceConfig(
                    order=4, block_rows=HORIZON, feedthrough=True, initial_state="zero", weighting=w
                )
                cmp = compare(identify_subspace(IORun(u, y), d1, cfg), c.result, u, y, d1)
                print_compare(
                    f"1 kHz, first {SIPPY_N_1KHZ:.3g} samples (SIPPY {c.wall_s:.1f} s); "
                    f"ours weighting {w!r}",
                    cmp,
                )
                if not cmp["stable_theirs"]:
                    rows.append((f"1 kHz fit ({w}) vs SIPPY", "", "SIPPY unstable", None))
                    continue
                out_rel = float(np.max(cmp["out_rel"]))
                sig_rel = float(np.max(cmp["sigma_rel"]))
                rows.append(
                    (
                        f"1 kHz {w}: output diff / RMS(y)",
                        f"<= {FIT_GOAL:.1%}",
                        f"{out_rel:.1e}",
                        out_rel <= FIT_GOAL,
                    )
                )
                rows.append(
                    (
                        f"1 kHz {w}: σ ours/SIPPY - 1",
                        f"<= {FIT_GOAL:.1%}",
                        f"{sig_rel:+.2%}",
                        sig_rel <= FIT_GOAL,
                    )
                )

    # 2. twin
    n_tw, t_tw = bench_twin()
    rtf = n_tw * dt / t_tw
    print(f"\n2. twin (xy_stage_twin, SetPoint(2), noise) on {n_tw * dt:g} s of random runs")
    print(f"  {t_tw:.3f} s best of 5: {n_tw / t_tw:.3g} samples/s, {rtf:.0f}x real time")
    print(f"  (the 600 s data set above: {TOTAL_S / t_sim:.0f}x real time, one pass)")
    rows.append(("twin, x real time", f">= {RTF_GOAL:g}x", f"{rtf:.0f}x", rtf >= RTF_GOAL))

    print(f"\n{'figure':<40} {'goal':>10} {'measured':>14}  met")
    for name, goal, got, met in rows:
        mark = "-" if met is None else "yes" if met else "NO"
        print(f"  {name:<38} {goal:>10} {got:>14}  {mark}")
    print(
        f"\n(whole benchmark {time.perf_counter() - t_start:.0f} s; load average at the end "
        f"{load_average()})"
    )


def load_average() -> str:
    """The 1-minute load average and the core count (``?`` where unknown)."""
    try:
        one = f"{os.getloadavg()[0]:.1f}"
    except OSError:
        one = "?"
    return f"{one} on {os.cpu_count()} cores"


def _mem_total() -> float:
    """This machine's memory, bytes (``/proc/meminfo``; 16 GB assumed elsewhere)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return 1024.0 * float(line.split()[1])
    except OSError:
        pass
    return 16e9


if __name__ == "__main__":
    main()
