"""``microfab identify chirp``: a transfer function fitted to a recorded chirp.

Seed 003 part 2 (Buls et al.) §1 on measured data: ``identify chirp FILE`` estimates the
FRF of a recorded chirp experiment (per-period FFT ratio or H1) and fits a ZOH-aware
transfer function to it (`microfab.identify`); it writes the model JSON that ``shaper
design`` (`cli/shaper.py`) reads.

Every refusal is one ``error:`` line, exit code 2, and nothing is written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import (
    check_option,
    console,
    fail,
    input_output,
    parse_range,
    print_table,
    read_trace_file,
    renamed,
)
from microfab.report.tables import Table

__all__ = ["identify_app"]

identify_app = typer.Typer(
    no_args_is_help=True, help="System identification from measured traces (seed 003 part 2)."
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
    poles: Annotated[int, typer.Option(min=1, help="Poles of the model.")] = 3,
    zeros: Annotated[int, typer.Option(min=0, help="Zeros of the model (<= poles).")] = 0,
    axis: Annotated[str, typer.Option(help="Axis <a> of the input_<a>, output_<a> columns.")] = "x",
    f0: Annotated[float, typer.Option(help="Chirp start frequency [Hz].")] = 10.0,
    f1: Annotated[float, typer.Option(help="Chirp stop frequency [Hz].")] = 2000.0,
    period: Annotated[float, typer.Option(help="Length of one sweep [s].")] = 1.0,
    periods: Annotated[
        int | None,
        typer.Option(min=1, help="Sweeps to read (default: every whole one the file holds)."),
    ] = None,
    drop: Annotated[int, typer.Option(min=0, help="Leading sweeps left out (transient).")] = 1,
    amplitude: Annotated[
        float | None,
        typer.Option(help="Chirp amplitude; when given, the input column must match it (10 %)."),
    ] = None,
    sweep: Annotated[str, typer.Option(help="Frequency law: linear or log.")] = "linear",
    method: Annotated[
        str,
        typer.Option(help="FRF estimate: periodic (FFT ratio per sweep) or h1 (P_yu / P_uu)."),
    ] = "periodic",
    min_coherence: Annotated[
        float, typer.Option(help="Coherence the band must reach (0 checks nothing).")
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
    from microfab.identify.chirp import ChirpDesign
    from microfab.identify.fit import fit_tf
    from microfab.identify.frf import frf_h1, frf_periodic
    from microfab.io.atomic import atomic_write_json

    lo, hi = parse_range("--band", band)
    check_option("--min-coherence", min_coherence, "", low=0.0, high=1.0, low_closed=True)
    if method not in ("periodic", "h1"):
        fail(f"--method must be periodic or h1, got {method!r}")
    check_option("--period", period, "s")
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
