"""``microfab identify``: models fitted to measured traces.

Seed 003 part 2 (Buls et al.) §1 on measured data: ``identify chirp FILE`` estimates the
FRF of a recorded chirp experiment (per-period FFT ratio or H1) and fits a ZOH-aware
transfer function to it (`microfab.identify`); it writes the model JSON that ``shaper
design`` (`cli/shaper.py`) reads.

Seed 002 (the black-box XY stage) on measured runs: ``identify linear RUN...`` fits eq. (6)
after an anti-alias decimation and writes the model file; ``identify ann RUN...``
(`cli/identify_ann.py`, registered on this group) trains the per-axis networks of eq. (7);
``identify validate MODEL RUN...`` prints either model's error per axis in the layout of
Table II (`microfab.identify.stage_data`, `microfab.identify.stage_ann`). ``identify
linear`` and ``identify validate`` and the run readers they share with ``identify ann``
are in `cli/identify_stage.py`, registered here after ``identify chirp`` and re-exported.

Every refusal is one ``error:`` line, exit code 2, and nothing is written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from microfab.cli._kit import (
    check_outputs,
    console,
    fail,
    input_output,
    parse_range,
    print_table,
    read_trace_file,
    renamed,
)
from microfab.cli._options import choice, integer, number
from microfab.cli.identify_stage import _RUN_HELP as _RUN_HELP
from microfab.cli.identify_stage import ANN_COMPARED as ANN_COMPARED
from microfab.cli.identify_stage import MAX_BLOCK_ROWS as MAX_BLOCK_ROWS
from microfab.cli.identify_stage import _error_table as _error_table
from microfab.cli.identify_stage import _model_table as _model_table
from microfab.cli.identify_stage import _read_runs as _read_runs
from microfab.cli.identify_stage import _weightings as _weightings
from microfab.cli.identify_stage import linear_cmd, validate_cmd
from microfab.report.tables import Table

__all__ = ["identify_app"]

identify_app = typer.Typer(
    no_args_is_help=True,
    help="System identification from measured traces (seed 003 part 2: chirp; seed 002: the "
    "XY stage's linear model and per-axis networks).",
)

#: How a library message names a value and how the command line does.
_CHIRP_NAMES = {
    "f0_hz": "--f0",
    "f1_hz": "--f1",
    "period_s": "--period",
    "n_periods": "--periods",
    "n_dropped": "--drop",
    "amplitude": "--amplitude",
}
_AMPLITUDE_TOL = 0.1  # --amplitude: the recorded input's half range within 10 % of it
#: Most poles (and zeros) of a fitted model. Assumed: the seed's model has 3 (seed 003
#: part 2 §1); a rational fit of more than 20 to one FRF is ill-conditioned.
_MAX_POLES = 20
#: Highest chirp frequency, Hz. Assumed: half the 100 MHz that ``trajectory --rate`` takes
#: as its highest sample rate (`microfab.cli.geometry.MAX_RATE_HZ`); the file's own Nyquist
#: frequency is checked with the file.
_MAX_HZ = 5e7
#: Longest sweep, s. Assumed: an hour (the seed's is 1 s, seed 003 part 2 §1); longer is a
#: unit mistake.
_MAX_PERIOD_S = 3600.0
#: Most sweeps read or dropped. Assumed: averaging 10 000 sweeps already takes the noise
#: down 100-fold; more is a typo.
_MAX_SWEEPS = 10_000
#: Largest period-to-period mismatch of the input (`_mismatch`) for it to repeat every
#: --period. Assumed: a repeating input with white noise of rms a (relative to the
#: signal's rms) measures a / sqrt(1 + a^2): 0.29 at a = 0.3 (measured 0.285 on the test
#: chirp plus noise), so an input channel with noise up to 30 % of the chirp passes. A
#: wrong period measures about 1 (0.998-1.004 at 0.8x, 1.2x, 0.5x, 0.25x, 1.5x the test
#: chirp's 50 ms; 0.50 at 10 samples off in 5000, 0.052 at 1 sample off).
_REPEAT_TOL = 0.3


#: The FRF estimates of ``identify chirp --method`` (`microfab.identify.frf.frf_periodic`,
#: `frf_h1`).
FRF_METHODS = ("periodic", "h1")


def _sweeps() -> tuple[str, ...]:
    """The chirp laws (`microfab.identify.chirp.SWEEPS`), imported when needed."""
    from microfab.identify.chirp import SWEEPS

    return SWEEPS


@identify_app.command("chirp")
def chirp_cmd(
    trace: Annotated[
        Path,
        typer.Argument(
            help="Recorded chirp experiment (.csv, .mat, .h5): time [s], input_<a>, output_<a>."
        ),
    ],
    json_path: Annotated[Path, typer.Option("--json", help="Write the fitted model (JSON) here.")],
    band: Annotated[str, typer.Option(help="Band to fit, LOW:HIGH [Hz].")] = "10:2000",
    poles: Annotated[
        int, integer("--poles", help="Poles of the model.", low=1, high=_MAX_POLES)
    ] = 3,
    zeros: Annotated[
        int, integer("--zeros", help="Zeros of the model (<= poles).", low=0, high=_MAX_POLES)
    ] = 0,
    axis: Annotated[str, typer.Option(help="Axis <a> of the input_<a>, output_<a> columns.")] = "x",
    f0: Annotated[
        float,
        number(
            "--f0", help="Chirp start frequency.", unit="Hz", low=0.0, low_open=True, high=_MAX_HZ
        ),
    ] = 10.0,
    f1: Annotated[
        float,
        number(
            "--f1", help="Chirp stop frequency.", unit="Hz", low=0.0, low_open=True, high=_MAX_HZ
        ),
    ] = 2000.0,
    period: Annotated[
        float,
        number(
            "--period",
            help="Length of one sweep.",
            unit="s",
            low=0.0,
            low_open=True,
            high=_MAX_PERIOD_S,
        ),
    ] = 1.0,
    periods: Annotated[
        int | None,
        integer(
            "--periods",
            help="Sweeps to read, the dropped ones included (default: every whole one the "
            "file holds).",
            low=1,
            high=_MAX_SWEEPS,
        ),
    ] = None,
    drop: Annotated[
        int,
        integer("--drop", help="Leading sweeps left out (transient).", low=0, high=_MAX_SWEEPS),
    ] = 1,
    amplitude: Annotated[
        float | None,
        number(
            "--amplitude",
            help="Chirp amplitude, in the trace's unit; when given, the input column must "
            "match it (10 %).",
            low=0.0,
            low_open=True,
        ),
    ] = None,
    sweep: Annotated[str, choice(choices=_sweeps, help="Frequency law.")] = "linear",
    method: Annotated[
        str,
        choice(
            choices=FRF_METHODS,
            help="FRF estimate: periodic (FFT ratio per sweep) or h1 (P_yu / P_uu).",
        ),
    ] = "periodic",
    min_coherence: Annotated[
        float,
        number(
            "--min-coherence",
            help="Coherence the band must reach (0 checks nothing).",
            low=0.0,
            high=1.0,
        ),
    ] = 0.8,
    plot: Annotated[
        Path | None, typer.Option(help="Write the Bode plot of data and fit (PNG) here.")
    ] = None,
) -> None:
    """Fit a transfer function to a recorded chirp experiment (seed 003 part 2 §1).

    The FRF is the per-sweep FFT ratio (or H1) of output_<a> over input_<a> on the
    sweep's band, the fit non-linear least squares from a Sanathanan-Koerner start,
    comparing the ZOH discretisation of each candidate at the file's sample time with the
    data. Prints the coefficients, poles, bandwidth and fit error; writes the model JSON
    (``shaper design`` reads it).
    """
    check_outputs(files={"--json": json_path, "--plot": plot}, inputs={"TRACE": trace})
    from microfab.identify.chirp import ChirpDesign
    from microfab.identify.fit import fit_tf
    from microfab.identify.frf import frf_h1, frf_periodic
    from microfab.io.atomic import atomic_write_json

    lo, hi = parse_range("--band", band)
    if zeros > poles:
        fail(f"--zeros {zeros} is more than --poles {poles}: a model has at most as many zeros")
    if f1 <= f0:
        fail(f"--f1 {f1:g} Hz must be above --f0 {f0:g} Hz")
    if f0 * period < 1.0 - 1e-12:
        fail(
            f"--f0 {f0:g} Hz is below one FFT bin of --period {period:g} s ({1 / period:g} Hz): "
            "raise --f0 or lengthen --period"
        )
    if periods is not None and periods <= drop:
        fail(f"--periods {periods} must be more than --drop {drop}: at least one sweep is kept")
    tr = read_trace_file(trace)
    u, y = input_output(tr, trace, axis)
    dt = float(tr.dt)
    if period / dt > u.size:
        fail(
            f"{trace}: the record of {u.size} samples ({u.size * dt:g} s) is shorter than one "
            f"sweep of --period {period:g} s"
        )
    n_whole = u.size // max(round(period / dt), 1)
    if periods is not None and n_whole < periods:
        fail(
            f"{trace}: the record holds {n_whole} whole sweeps of {period:g} s, --periods "
            f"says {periods}"
        )
    if n_whole <= drop:
        fail(
            f"{trace}: the record holds {n_whole} whole sweeps of --period {period:g} s and "
            f"--drop {drop} leaves none: the chirp's period or a smaller --drop?"
        )
    try:
        design = ChirpDesign(
            f0_hz=f0,
            f1_hz=f1,
            amplitude=1.0 if amplitude is None else amplitude,
            period_s=period,
            n_periods=periods or max(n_whole, drop + 1),
            n_dropped=drop,
            dt=dt,
            sweep=sweep,  # type: ignore[arg-type]
        )
    except ValueError as exc:
        fail(f"chirp design for {trace}: {renamed(str(exc), _CHIRP_NAMES)}")
    n = design.samples_per_period
    if periods is not None:
        u, y = u[: periods * n], y[: periods * n]
    _check_repeats(u, n, dt, drop, f"{trace}: input_{axis}")
    if amplitude is not None:
        kept = u[drop * n :]
        half = 0.5 * float(kept.max() - kept.min()) if kept.size else 0.0
        if abs(half / amplitude - 1.0) > _AMPLITUDE_TOL:
            fail(
                f"{trace}: input_{axis} swings ±{half:.4g} about its centre, not the "
                f"--amplitude {amplitude:g}: another column or experiment?"
            )
    unit = f"{tr.unit}/{tr.unit}" if tr.unit else ""
    try:
        if method == "periodic":
            frf = frf_periodic(
                u, y, dt=dt, samples_per_period=n, n_dropped=drop, excited_hz=design.band_hz,
                unit=unit,
            )  # fmt: skip
        else:
            # whole sweeps, no window, no overlap: a periodic record has no leakage
            frf = frf_h1(
                u, y, dt=dt, nperseg=n, noverlap=0, window="boxcar",
                n_dropped_samples=drop * n, excited_hz=design.band_hz, unit=unit,
            )  # fmt: skip
        fit = fit_tf(
            frf, n_poles=poles, n_zeros=zeros, dt=dt, band_hz=(lo, hi),
            min_coherence=min_coherence,
        )  # fmt: skip
    except ValueError as exc:
        fail(f"{trace}: {exc}")
    print_table(_fit_table(fit, trace, axis))
    figure = fit.plot(title=f"{trace.name}: {fit.model.formula()}") if plot is not None else None
    atomic_write_json(json_path, fit.to_dict())
    console.print(f"wrote {json_path}", highlight=False)
    if figure is not None and plot is not None:
        from microfab.report.canvas import save_figure

        save_figure(figure, plot)
        console.print(f"wrote {plot}", highlight=False)


def _mismatch(u: np.ndarray, n: int, first: int) -> float | None:
    """Period-to-period mismatch of ``u`` at a period of ``n`` samples, from period ``first``.

    Parameters
    ----------
    u : numpy.ndarray
        Input samples, shape (N,).
    n : int
        Period, samples.
    first : int
        First period compared (earlier ones may hold a fade-in).

    Returns
    -------
    float or None
        ``rms(u_{k+1} - u_k) / (sqrt(2) rms(u - mean))`` over the whole periods from
        ``first`` on (0: repeats exactly; about 1: unrelated periods); ``None`` when fewer
        than two whole periods are left or the input is constant.
    """
    v = u[first * n : (u.size // n) * n]
    if v.size < 2 * n:
        return None
    spread = float(np.sqrt(np.mean((v - v.mean()) ** 2)))
    if spread == 0.0:
        return None
    d = v[n:] - v[:-n]
    return float(np.sqrt(np.mean(d**2))) / (np.sqrt(2.0) * spread)


def _check_repeats(u: np.ndarray, n: int, dt: float, drop: int, what: str) -> None:
    """Refuse an input that does not repeat every ``n`` samples, or repeats sooner.

    The sweeps from the last dropped one on are compared (`_mismatch`, ``_REPEAT_TOL``);
    an input that also repeats every half, third or fifth of the period was recorded
    with a shorter chirp than --period says.
    """
    first = max(drop - 1, 0)
    eps = _mismatch(u, n, first)
    if eps is not None and eps > _REPEAT_TOL:
        fail(
            f"{what} does not repeat every --period {n * dt:g} s (period-to-period mismatch "
            f"{eps:.2g} of its rms, at most {_REPEAT_TOL:g}): not the file's chirp period?"
        )
    for k, part in ((2, "half"), (3, "third"), (5, "fifth")):
        eps = _mismatch(u, n // k, first * k) if n % k == 0 else None
        if eps is not None and eps <= _REPEAT_TOL:
            fail(
                f"{what} repeats every {n * dt / k:g} s, a {part} of --period {n * dt:g} s: "
                "give the chirp's own period"
            )


def _fit_table(fit: Any, trace: Path, axis: str) -> Table:
    m = fit.model
    f = fit.frf.freq_hz
    modes = "; ".join(f"{k.frequency_hz:.5g} Hz, ζ {k.damping:.4g}" for k in m.complex_modes)
    try:
        bw = f"{m.bandwidth_hz():.5g}"
    except ValueError:
        bw = "—"
    rows = [
        ("model G(s)", m.formula()),
        ("numerator (highest power first)", ", ".join(f"{c:.6g}" for c in m.num)),
        ("denominator (monic)", ", ".join(f"{c:.6g}" for c in m.den)),
        ("poles [rad/s]", ", ".join(f"{p:.6g}" for p in m.poles)),
        ("real poles [Hz]", ", ".join(f"{p:.5g}" for p in m.real_poles_hz) or "—"),
        ("complex modes", modes or "—"),
        ("static gain G(0)", f"{m.static_gain:.6g}"),
        ("−3 dB bandwidth [Hz]", bw),
        ("band fitted [Hz]", f"{f[0]:g} – {f[-1]:g} ({f.size} frequencies)"),
        ("FRF", f"{fit.frf.method}, {fit.frf.n_averages} averages"),
        ("sampling of the fit", f"{fit.sampling}, dt {fit.dt:g} s" if fit.dt else fit.sampling),
        ("weighted residual rms", f"{fit.residual_rms:.3g}"),
        ("largest relative error [%]", f"{100 * fit.max_relative_error:.3g}"),
    ]
    return Table(
        title=f"Fit of {trace.name}: input_{axis} → output_{axis}",
        columns=("quantity", "value"),
        rows=rows,
    )


# seed 002 (`cli/identify_stage.py`), after chirp: the group lists chirp, linear, validate, ann
identify_app.command("linear")(linear_cmd)
identify_app.command("validate")(validate_cmd)
