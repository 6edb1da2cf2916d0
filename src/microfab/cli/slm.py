"""``microfab identify chirp``, ``microfab shaper design``, ``microfab slm scan-time``.

Seed 003 part 2 (Buls et al.) on measured data and on the SLM galvo twin:

* ``identify chirp FILE``: FRF of a recorded chirp experiment (per-period FFT ratio or
  H1) and a ZOH-aware transfer-function fit (`microfab.identify`); writes the model JSON.
* ``shaper design [MODEL]``: the seed's model-inverse shaper from a model JSON, or a
  classic impulse shaper (ZV ... 3-hump EI) for a given mode or auto-fitted to a measured
  FRF or PSD (`microfab.control.shaper_fit`); writes a shaper JSON
  (`microfab.control.shaper_io`).
* ``slm scan-time SOURCE``: a lattice layer or a drawing as a scan program
  (`microfab.process.slm.source`), its naive, fixed-delay and dynamics-aware scan times on
  the twin, with and without a shaper (`microfab.process.slm.estimate`).

Every refusal is one ``error:`` line, exit code 2, and nothing is written.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer

from microfab.cli._kit import check_option, console, fail, print_table
from microfab.process.slm.timing import RTCDelays
from microfab.report.tables import Table

if TYPE_CHECKING:
    from microfab.control.shaper_io import Shaper
    from microfab.identify.model import TFModel
    from microfab.process.slm.estimate import ScanTimeComparison

__all__ = ["identify_app", "shaper_app", "slm_app"]

identify_app = typer.Typer(
    no_args_is_help=True, help="System identification from measured traces (seed 003 part 2)."
)
shaper_app = typer.Typer(
    no_args_is_help=True,
    help="Input shapers: the seed 003 model inverse and classic impulse shapers.",
)
slm_app = typer.Typer(
    no_args_is_help=True, help="SLM scanning on the galvo twin (seed 003 part 2)."
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
_INVERSE_NAMES = {"pole_hz": "--poles-hz", "order": "--order", "dt =": "--dt ="}
_MAX_DELAY_US = 1e6  # a delay of more than 1 s is a typo (and overflows the tick counts)
_AMPLITUDE_TOL = 0.1  # --amplitude: the recorded input's half range within 10 % of it


def _renamed(msg: str, names: dict[str, str]) -> str:
    for lib, cli in names.items():
        msg = msg.replace(lib, cli)
    return msg


def _range(option: str, text: str, unit: str = "Hz") -> tuple[float, float]:
    """``"low:high"`` as two finite numbers with ``0 <= low < high``."""
    lo, sep, hi = text.partition(":")
    try:
        a, b = float(lo), float(hi)
    except ValueError:
        a = b = math.nan
    if not sep or not (math.isfinite(a) and math.isfinite(b) and 0 <= a < b):
        fail(f"{option} must look like LOW:HIGH in {unit} with 0 <= LOW < HIGH, got {text!r}")
    return a, b


def _read_trace(path: Path) -> Any:
    from microfab.io.trace import read_trace

    try:
        return read_trace(path)
    except (OSError, ValueError) as exc:
        msg = str(exc)
        fail(msg if str(path) in msg else f"{path}: {msg}")


def _columns(trace: Any, path: Path, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """The ``input_<axis>`` and ``output_<axis>`` columns of a trace (exits 2 if missing)."""
    names = (f"input_{axis}", f"output_{axis}")
    for name in names:
        if name not in trace.axes:
            fail(
                f"{path}: no column {name!r} (columns: time, {', '.join(trace.axes)}); the "
                "file needs time, input_<a> and output_<a>, --axis picks <a>"
            )
    i, o = (trace.axes.index(n) for n in names)
    return trace.values[:, i], trace.values[:, o]


# ---------------------------------------------------------------- identify chirp
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

    lo, hi = _range("--band", band)
    check_option("--min-coherence", min_coherence, "", low=0.0, high=1.0, low_closed=True)
    if method not in ("periodic", "h1"):
        fail(f"--method must be periodic or h1, got {method!r}")
    check_option("--period", period, "s")
    tr = _read_trace(trace)
    u, y = _columns(tr, trace, axis)
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
        fail(f"chirp design for {trace}: {_renamed(str(exc), _CHIRP_NAMES)}")
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


# ---------------------------------------------------------------- shaper design
def _read_model(path: Path) -> TFModel:
    from microfab.identify.model import TFModel

    try:
        return TFModel.from_dict(json.loads(path.read_text(encoding="utf-8")))
    except FileNotFoundError:
        fail(f"model file not found: {path}")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        fail(f"{path}: not a model JSON file ({exc})")
    except ValueError as exc:
        fail(f"{path}: {exc}")


def _frf_of_file(path: Path, axis: str | None, dt: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``(freq_hz, response, dt)`` of an FRF file (``freq_hz`` column) or of a trace.

    A trace (time, input_<a>, output_<a>) gives H1 on segments of the largest power of two
    up to a quarter of the record, Hann window, half overlap, on the excited band.
    """
    from microfab.identify.frf import FRF, frf_h1
    from microfab.io.frf import read_frf
    from microfab.io.trace import read_columns

    try:
        cols = read_columns(path)
    except (OSError, ValueError) as exc:
        fail(f"{path}: {exc}" if str(path) not in str(exc) else str(exc))
    if "freq_hz" in cols:
        try:
            frf = FRF.from_table(read_frf(path), axis)
        except (OSError, ValueError) as exc:
            fail(f"{path}: {exc}" if str(path) not in str(exc) else str(exc))
        return frf.freq_hz, frf.response, dt
    tr = _read_trace(path)
    u, y = _columns(tr, path, axis or "x")
    nseg = 2 ** int(math.log2(max(u.size // 4, 2)))
    try:
        frf = frf_h1(u, y, dt=float(tr.dt), nperseg=nseg)
    except ValueError as exc:
        fail(f"{path}: {exc}")
    return frf.freq_hz, frf.response, float(tr.dt)


def _read_psd(path: Path) -> tuple[np.ndarray, np.ndarray]:
    from microfab.io.trace import read_columns

    try:
        cols = read_columns(path)
    except (OSError, ValueError) as exc:
        fail(f"{path}: {exc}" if str(path) not in str(exc) else str(exc))
    for name in ("freq_hz", "psd"):
        if name not in cols:
            fail(f"{path}: no column {name!r} (columns: {', '.join(cols)}); a PSD file holds "
                 "freq_hz [Hz] and psd [unit²/Hz]")  # fmt: skip
    return cols["freq_hz"], cols["psd"]


def _design_inverse(
    model_path: Path | None, poles_hz: float, order: int, dt: float, discretization: str
) -> Any:
    from microfab.control.shaping import InverseShaperConfig, design_inverse_shaper

    if model_path is None:
        fail("--kind inverse needs MODEL, a model JSON (microfab identify chirp --json)")
    model = _read_model(model_path)
    try:
        cfg = InverseShaperConfig(
            pole_hz=poles_hz,
            order=order,
            dt=dt,
            discretization=discretization,  # type: ignore[arg-type]
        )
        return design_inverse_shaper((model.num, model.den), cfg)
    except ValueError as exc:
        fail(f"{model_path}: {_renamed(str(exc), _INVERSE_NAMES)}")


def _inverse_table(s: Any, model: TFModel) -> Table:
    gain, at = s.gain_peak()
    gain_d, at_d = s.gain_peak(discrete=True)
    rows = [
        ("continuous numerator", ", ".join(f"{c:.4g}" for c in s.num)),
        ("continuous denominator", ", ".join(f"{c:.4g}" for c in s.den)),
        (f"discrete numerator (z⁻¹, dt {s.dt:g} s)", ", ".join(f"{c:.6g}" for c in s.num_d)),
        ("discrete denominator (z⁻¹)", ", ".join(f"{c:.6g}" for c in s.den_d)),
        ("preview [samples]", str(s.preview)),
        ("added delay (ramp lag) [µs], continuous / discrete",
         f"{s.lag() * 1e6:.1f} / {s.lag(discrete=True) * 1e6:.1f}"),
        ("gain peak, continuous", f"{gain:.4g} at {at:.5g} Hz"),
        ("gain peak, discrete", f"{gain_d:.4g} at {at_d:.5g} Hz"),
        ("command peak of a unit step, continuous / discrete",
         f"{s.step_peak():.4g} / {s.step_peak(discrete=True):.4g}"),
    ]  # fmt: skip
    for k in model.complex_modes:
        v = float(s.vibration(k.frequency_hz, k.damping, discrete=True)[0])
        rows.append((f"V at the mode {k.frequency_hz:.5g} Hz, ζ {k.damping:.3g}", f"{v:.4g}"))
    return Table(
        title=f"Inverse shaper: poles {s.config.order} × {s.config.pole_hz:g} Hz, "
        f"{s.config.discretization}",
        columns=("quantity", "value"),
        rows=rows,
    )


def _impulse_table(s: Any, dt: float, fit: Any = None) -> Table:
    rows = [
        (f"impulse {i}: amplitude, time [µs]", f"{a:.6g}, {t * 1e6:.3f}")
        for i, (a, t) in enumerate(zip(s.amplitudes, s.times, strict=True))
    ]
    v = float(s.vibration(s.freq_hz)[0])
    v_d = float(s.sampled_vibration(dt, s.freq_hz)[0])
    rows += [
        ("design mode", f"{s.freq_hz:.5g} Hz, ζ {s.damping:.4g}"),
        ("added delay (centroid) [µs]", f"{s.delay * 1e6:.2f}"),
        ("duration [µs]", f"{s.duration * 1e6:.2f}"),
        ("command peak of a unit step", f"{s.command_peak:.4g}"),
        ("V at the mode, exact / sampled at dt", f"{v:.4g} / {v_d:.4g} (dt {dt:g} s)"),
        ("design", "solved numerically" if s.numeric else "closed form"),
    ]
    if fit is not None:
        rows.append(("remaining vibration of the fit", f"{100 * fit.best.vibrations:.3g} %"))
    return Table(title=f"{s.name} shaper", columns=("quantity", "value"), rows=rows)


@shaper_app.command("design")
def design_cmd(
    out: Annotated[Path, typer.Option(help="Write the shaper (JSON) here.")],
    model: Annotated[
        Path | None,
        typer.Argument(
            help="Model JSON (identify chirp --json): inverted by --kind inverse; the "
            "baseline of an --frf auto-fit otherwise."
        ),
    ] = None,
    kind: Annotated[
        str, typer.Option(help="inverse, zv, zvd, mzv, ei, 2hump_ei or 3hump_ei.")
    ] = "inverse",
    poles_hz: Annotated[float, typer.Option(help="Inverse: added real poles [Hz].")] = 4000.0,
    order: Annotated[int, typer.Option(help="Inverse: number of added poles.")] = 4,
    dt: Annotated[float, typer.Option(help="Sample time of the command [s].")] = 1e-5,
    discretization: Annotated[
        str, typer.Option(help="Inverse: zoh (the seed's) or zpetc (sampled-axis inverse).")
    ] = "zoh",
    freq_hz: Annotated[
        float | None, typer.Option(help="Classic: the mode's natural frequency [Hz].")
    ] = None,
    damping: Annotated[
        float | None,
        typer.Option(help="Classic: the mode's damping ratio (default 0.1, Klipper's)."),
    ] = None,
    frf: Annotated[
        Path | None,
        typer.Option(help="Classic: auto-fit to an FRF file (freq_hz, re_<a>/im_<a>) or trace."),
    ] = None,
    psd: Annotated[
        Path | None, typer.Option(help="Classic: auto-fit to a PSD file (freq_hz, psd).")
    ] = None,
    axis: Annotated[
        str | None, typer.Option(help="Axis of the --frf file (default its first, or x).")
    ] = None,
    freq_range: Annotated[
        str | None,
        typer.Option(help="Auto-fit: design frequencies scanned, LOW:HIGH [Hz] (default all)."),
    ] = None,
) -> None:
    """Design an input shaper and write it as JSON (slm scan-time --shaper reads it).

    --kind inverse: the seed 003 §2 model inverse S = [G/G(0)]⁻¹ pⁿ/(s+p)ⁿ of MODEL,
    discretised at --dt. A classic kind: for the mode --freq-hz, --damping, or the
    type's best design fitted to the vibration in --frf (weights |H|², divided by
    |MODEL|² when MODEL is given: what the model does not explain) or --psd (columns
    freq_hz [Hz] and psd), as Klipper's calibrate_shaper, scored by added delay.
    """
    from microfab.control.shaper_io import shaper_to_dict
    from microfab.control.shapers import SHAPER_NAMES
    from microfab.io.atomic import atomic_write_json

    kinds = ("inverse", *SHAPER_NAMES)
    if kind not in kinds:
        fail(f"--kind must be one of {', '.join(kinds)}, got {kind!r}")
    check_option("--dt", dt, "s")
    classic = (
        ("--freq-hz", freq_hz),
        ("--damping", damping),
        ("--frf", frf),
        ("--psd", psd),
        ("--freq-range", freq_range),
    )
    classic_given = [n for n, v in classic if v is not None]
    if kind == "inverse":
        if classic_given:
            fail(f"{classic_given[0]} applies to the classic kinds, not to --kind inverse")
        shaper = _design_inverse(model, poles_hz, order, dt, discretization)
        table = _inverse_table(shaper, _read_model(model))  # type: ignore[arg-type]
    else:
        shaper, table = _design_classic(kind, model, dt, freq_hz, damping, frf, psd, axis,
                                        freq_range)  # fmt: skip
    print_table(table)
    atomic_write_json(out, shaper_to_dict(shaper))
    console.print(f"wrote {out}", highlight=False)


def _design_classic(
    kind: str,
    model: Path | None,
    dt: float,
    freq_hz: float | None,
    damping: float | None,
    frf: Path | None,
    psd: Path | None,
    axis: str | None,
    freq_range: str | None,
) -> tuple[Shaper, Table]:
    from microfab.control.shaper_fit import ShaperFitConfig, fit_shaper
    from microfab.control.shapers import design_shaper

    sources = [n for n, v in (("--freq-hz", freq_hz), ("--frf", frf), ("--psd", psd)) if v]
    if len(sources) != 1:
        what = "none" if not sources else " and ".join(sources)
        fail(f"--kind {kind} needs one of --freq-hz, --frf or --psd, got {what}")
    if model is not None and frf is None:
        fail("MODEL serves a classic kind only as the baseline of --frf: leave it out")
    if damping is not None:
        check_option("--damping", damping, "", low=0.0, high=0.99, low_closed=True)
    nyquist = 0.5 / dt
    fit = None
    if freq_hz is not None:
        if freq_range is not None:
            fail("--freq-range applies to an auto-fit (--frf or --psd), not to --freq-hz")
        check_option("--freq-hz", freq_hz, "Hz")
        if freq_hz >= nyquist:
            fail(
                f"--freq-hz {freq_hz:g} Hz lies at or above the Nyquist frequency {nyquist:g} "
                f"Hz of --dt {dt:g} s: the shaper's impulses would fall within one sample"
            )
        try:
            shaper = design_shaper(kind, freq_hz, 0.1 if damping is None else damping)  # type: ignore[arg-type]
        except ValueError as exc:
            fail(str(exc))
    else:
        if frf is not None:
            f, resp, f_dt = _frf_of_file(frf, axis, dt)
            baseline = None
            if model is not None:
                m = _read_model(model)
                baseline = np.abs(m.frequency_response(f, sampling="zoh", dt=f_dt))
            data: tuple[Any, ...] = (f, resp, "frf", baseline)
        else:
            f, resp = _read_psd(psd)  # type: ignore[arg-type]
            data = (f, resp, "psd", None)
        rng = None if freq_range is None else _range("--freq-range", freq_range)
        zs = {} if damping is None else {"design_dampings": (damping,), "test_dampings": (damping,)}
        try:
            cfg = ShaperFitConfig(names=(kind,), freq_range_hz=rng, **zs)  # type: ignore[arg-type]
            fit = fit_shaper(data[0], data[1], kind=data[2], baseline=data[3], config=cfg)
        except ValueError as exc:
            fail(f"{frf or psd}: {exc}")
        shaper = fit.best.shaper
    if shaper.freq_hz >= nyquist:
        fail(
            f"the {kind} shaper's mode {shaper.freq_hz:g} Hz lies at or above the Nyquist "
            f"frequency {nyquist:g} Hz of --dt {dt:g} s: its impulses fall within one sample"
        )
    return shaper, _impulse_table(shaper, dt, fit)


# ---------------------------------------------------------------- slm scan-time
_D = RTCDelays()  # the library's defaults are the options' defaults


@slm_app.command("scan-time")
def scan_time_cmd(
    source: Annotated[
        str,
        typer.Argument(
            help="lattice:key=value,... (z, radius, strut, fraction, hatch, sides; m) or a "
            "drawing (DXF/SVG file, or a shape such as circle:radius=5e-3)."
        ),
    ],
    shaper: Annotated[
        Path | None, typer.Option(help="Shaper JSON (shaper design): also estimate with it.")
    ] = None,
    mark_speed: Annotated[float, typer.Option(help="Mark speed [m/s].")] = 0.6,
    jump_speed: Annotated[float, typer.Option(help="Jump speed [m/s].")] = 5.0,
    jump_delay_us: Annotated[
        float, typer.Option(help="Fixed jump delay without the shaper [µs] (seed: 750).")
    ] = _D.jump_s * 1e6,
    shaped_jump_delay_us: Annotated[
        float, typer.Option(help="Fixed jump delay with the shaper [µs] (seed: 250).")
    ] = 250.0,
    mark_delay_us: Annotated[float, typer.Option(help="Mark delay [µs].")] = _D.mark_s * 1e6,
    polygon_delay_us: Annotated[float, typer.Option(help="Polygon delay [µs].")] = _D.polygon_s
    * 1e6,
    laser_on_delay_us: Annotated[float, typer.Option(help="Laser on delay [µs].")] = _D.laser_on_s
    * 1e6,
    laser_off_delay_us: Annotated[
        float, typer.Option(help="Laser off delay [µs].")
    ] = _D.laser_off_s * 1e6,
    variable_polygon: Annotated[
        bool, typer.Option(help="Scale the polygon delay by the corner's angle.")
    ] = False,
    sky_writing: Annotated[int, typer.Option(help="Sky-writing mode 0-3.")] = 0,
    sky_prev: Annotated[int, typer.Option(help="Sky-writing run-in [ticks].")] = 0,
    sky_post: Annotated[int, typer.Option(help="Sky-writing run-out [ticks].")] = 0,
    tolerance_pct: Annotated[
        float, typer.Option(help="Settled: within this % of the jump length (at least 1 bit).")
    ] = 2.0,
    hatch_um: Annotated[float, typer.Option(help="Hatch spacing [µm].")] = 100.0,
    hatch_angle_deg: Annotated[float, typer.Option(help="Hatch direction [deg].")] = 0.0,
    contours: Annotated[
        bool, typer.Option(help="Mark a drawing's contours before hatching it.")
    ] = True,
    naive_jump_delay: Annotated[
        bool, typer.Option(help="Add the fixed jump delay to the naive estimate (PySLM).")
    ] = False,
    mirror_mode: Annotated[
        bool, typer.Option(help="Twin with the extra mirror mode (3 kHz, ζ 0.02, assumed).")
    ] = False,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the estimates (JSON) here.")
    ] = None,
) -> None:
    """Scan time of one layer three ways: naive Σ L/v, fixed RTC delays, dynamics-aware.

    The dynamics-aware estimate waits after each jump only until the twin's position
    stays within the tolerance (exact propagation of the axis model); with --shaper the
    twin is driven through the shaper (a ZPETC shaper's look-ahead counts as delay) and
    the fixed estimate uses --shaped-jump-delay-us.
    """
    from microfab.control.shaper_io import read_shaper, shaper_lti, shaper_to_dict
    from microfab.plants.galvo_slm import galvo_slm_twin
    from microfab.process.slm.estimate import SettleTolerance, estimate_scan_time, series
    from microfab.process.slm.source import parse_lattice_source, scan_program
    from microfab.process.slm.timing import (
        TICK_S,
        RTCSettings,
        ScanSpeeds,
        SkyWriting,
        ticks,
    )

    check_option("--mark-speed", mark_speed, "m/s")
    check_option("--jump-speed", jump_speed, "m/s")
    check_option("--tolerance-pct", tolerance_pct, "%", high=100.0)
    check_option("--hatch-um", hatch_um, "µm")
    delays = {
        "jump_s": ("--jump-delay-us", jump_delay_us),
        "mark_s": ("--mark-delay-us", mark_delay_us),
        "polygon_s": ("--polygon-delay-us", polygon_delay_us),
        "laser_on_s": ("--laser-on-delay-us", laser_on_delay_us),
        "laser_off_s": ("--laser-off-delay-us", laser_off_delay_us),
        "shaped": ("--shaped-jump-delay-us", shaped_jump_delay_us),
    }
    for option, value in delays.values():
        check_option(option, value, "µs", high=_MAX_DELAY_US, low_closed=True)
        try:
            ticks(option, value * 1e-6)
        except ValueError as exc:
            fail(str(exc))
    try:
        sky = SkyWriting(mode=sky_writing, n_prev=sky_prev, n_post=sky_post)
    except ValueError as exc:
        fail(f"--sky-writing: {exc}")
    settings = RTCSettings(
        speeds=ScanSpeeds(mark_m_s=mark_speed, jump_m_s=jump_speed),
        delays=RTCDelays(
            **{k: v * 1e-6 for k, (_, v) in delays.items() if k != "shaped"},
            variable_polygon=variable_polygon,
        ),
        sky_writing=sky,
    )
    shaped_settings = settings.with_delays(jump_s=shaped_jump_delay_us * 1e-6)
    tol = SettleTolerance(relative=tolerance_pct / 100.0)
    the_shaper = None
    if shaper is not None:
        try:
            the_shaper = read_shaper(shaper)
            prefilter = shaper_lti(the_shaper, TICK_S)
        except (OSError, ValueError) as exc:
            fail(str(exc) if str(shaper) in str(exc) else f"{shaper}: {exc}")
    twin = galvo_slm_twin(mirror_mode=mirror_mode)
    field_m = twin.config.field_bit * twin.config.bit_size_m
    if source.strip().lower().startswith("lattice:"):  # refused before it is built
        try:
            spec = parse_lattice_source(source)[1]
        except ValueError as exc:
            fail(str(exc))
        if spec.outline_radius_m > field_m:
            fail(f"{source}: the outline radius {spec.outline_radius_m * 1e3:.4g} mm reaches "
                 f"outside the scanner's field of ±{field_m * 1e3:.4g} mm")  # fmt: skip
    try:
        path = scan_program(
            source, hatch_spacing_m=hatch_um * 1e-6, hatch_angle_deg=hatch_angle_deg,
            contours=contours,
        )  # fmt: skip
    except (OSError, ValueError) as exc:
        fail(str(exc))
    if len(path) == 0:
        fail(f"{source}: nothing to scan (narrower than the hatch spacing, contours off)")
    reach = float(np.max(np.abs(path.points)))
    if reach > field_m:
        fail(f"{source}: the program reaches {reach * 1e3:.4g} mm from the field's centre, "
             f"outside the scanner's field of ±{field_m * 1e3:.4g} mm")  # fmt: skip
    runs = {"unshaped": estimate_scan_time(path, twin, settings, tolerance=tol,
                                           naive_jump_delay=naive_jump_delay)}  # fmt: skip
    if the_shaper is not None:
        model = series(prefilter, twin.axis_model)
        runs["shaped"] = estimate_scan_time(
            path, model, shaped_settings, tolerance=tol, naive_jump_delay=naive_jump_delay
        )
    print_table(_scan_table(source, runs))
    _print_scan_summary(path, runs)
    if json_path is not None:
        from microfab.io.atomic import atomic_write_json

        data: dict[str, Any] = {
            "source": source,
            "program": path.summary(),
            "mirror_mode": mirror_mode,
            "tolerance_relative": tol.relative,
            "delays_us": {opt.lstrip("-"): v for opt, v in delays.values()},
            "speeds_m_s": {"mark": mark_speed, "jump": jump_speed},
        }
        for name, c in runs.items():
            data[name] = {e.method: e.summary() for e in (c.naive, c.fixed, c.dynamics)}
        if the_shaper is not None:
            data["shaper"] = shaper_to_dict(the_shaper)
        atomic_write_json(json_path, data)
        console.print(f"wrote {json_path}", highlight=False)


def _scan_table(source: str, runs: dict[str, ScanTimeComparison]) -> Table:
    from microfab.process.slm.timing import CATEGORIES

    cols = ["category"]
    ests = []
    for name, c in runs.items():
        tag = "" if name == "unshaped" else ", shaped"
        for e in (c.naive, c.fixed, c.dynamics):
            cols.append(f"{e.method}{tag} [s]")
            ests.append(e)

    def cell(e: Any, cat: str) -> str:
        sec = e.total_s if cat == "total" else e.breakdown_s[cat]
        share = 1.0 if cat == "total" else e.share(cat)
        return f"{sec:.5g} ({100 * share:.1f} %)"

    rows = [[cat, *(cell(e, cat) for e in ests)] for cat in (*CATEGORIES, "total")]
    return Table(title=f"Scan time of {source}", columns=cols, rows=rows)


def _print_scan_summary(path: Any, runs: dict[str, ScanTimeComparison]) -> None:
    s = path.summary()
    console.print(
        f"program: {s['n_marks']} marks ({s['mark_length_m'] * 1e3:.4g} mm), {s['n_jumps']} "
        f"jumps ({s['jump_length_m'] * 1e3:.4g} mm)",
        highlight=False,
    )
    for name, c in runs.items():
        d = c.dynamics.summary()
        err = max(d.get("max_laser_on_error_bit", 0.0), d.get("max_laser_off_error_bit", 0.0))
        mean = d.get("mean_jump_delay_s")
        jd = f"mean jump delay {mean * 1e6:.1f} µs, " if mean is not None else ""
        console.print(
            f"{name}, dynamics-aware: {jd}largest laser on/off position error {err:.3g} bit",
            highlight=False,
        )
    if "shaped" in runs:
        a, b = runs["unshaped"], runs["shaped"]
        console.print(
            f"with the shaper: fixed delays {_cut(a.fixed.total_s, b.fixed.total_s)}, "
            f"dynamics-aware {_cut(a.dynamics.total_s, b.dynamics.total_s)}",
            highlight=False,
        )


def _cut(before: float, after: float) -> str:
    return f"{before:.5g} → {after:.5g} s ({100 * (after / before - 1):+.1f} %)"
