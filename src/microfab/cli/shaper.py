"""``microfab shaper design|compare``: an input shaper written as JSON; shapers compared.

Seed 003 part 2 (Buls et al.) §2: the seed's model-inverse shaper from a model JSON
(``identify chirp --json``, `cli/identify.py`), or a classic impulse shaper (ZV ... 3-hump
EI) for a given mode or auto-fitted to a measured FRF, trace or PSD
(`microfab.control.shaper_fit`); writes a shaper JSON (`microfab.control.shaper_io`) that
``slm scan-time --shaper`` (`cli/slm.py`) reads. ``shaper compare`` puts the inverse and
the classic shapers side by side on the SLM galvo twin (`microfab.machines.slm_galvo.shapers`).

Every number is declared with its unit and range (`microfab.cli._options`), sharing the
``slm-shaping`` job's key where one sets the same quantity
(`microfab.experiments.seed003_slm.keys`); an option the chosen mode does not use is
refused, not ignored. Every refusal is one ``error:`` line, exit code 2, and nothing is
written.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

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
from microfab.cli._options import choice, integer, number, refuse_unused
from microfab.experiments.seed003_slm import keys
from microfab.report.tables import Table

if TYPE_CHECKING:
    from microfab.control.shaper_io import Shaper
    from microfab.identify.model import TFModel

__all__ = ["shaper_app"]

shaper_app = typer.Typer(
    no_args_is_help=True,
    help="Input shapers: the seed 003 model inverse and classic impulse shapers.",
)

#: How a library message names a value and how the command line does.
_INVERSE_NAMES = {"pole_hz": "--poles-hz", "order": "--order", "dt =": "--dt ="}
#: Shortest --dt, s (assumed 0.1 µs: a hundred times the RTC's 100 kHz rate; below it a
#: shaper's coefficients lose their precision and its taps run into the millions).
_MIN_DT_S = 1e-7
#: Longest --dt, s (assumed 10 ms: a 100 Hz command rate, slower than any motion
#: controller's; its Nyquist frequency, 50 Hz, lies below the modes a shaper is for).
_MAX_DT_S = 1e-2
#: A classic shaper's mode, Hz (assumed 1 Hz to 1 MHz: a positioning machine's structural
#: modes lie between tens of Hz (a gantry) and tens of kHz (a piezo stage); outside, the
#: unit slipped). A mode at or above the Nyquist frequency of --dt is refused with --dt.
_FREQ_RANGE_HZ = (1.0, 1e6)
#: A mode's damping ratio: at 1 or more nothing rings (0.99: the largest damping of the
#: exact forms ZV, ZVD, MZV, ``max_damping`` in control/shaper_forms.py).
_MAX_DAMPING = 0.99
#: Settling band of the comparison, % of the jump: more than 0, at most 50 % (assumed, as
#: the ``slm-shaping`` job's ``settle_band`` <= 0.5: within half the jump is no settling).
_MAX_BAND_PCT = 50.0
#: Vibration tolerance of the EI-family shapers, fraction: (0, 0.25], the range
#: `microfab.control.shapers.design_shaper` accepts.
_MAX_V_TOL = 0.25


def _read_model(path: Path) -> TFModel:
    from microfab.identify.model import read_tf_model

    try:
        return read_tf_model(path)
    except FileNotFoundError:
        fail(f"model file not found: {path}")
    except OSError as exc:
        fail(f"{path}: cannot read it ({exc.strerror or exc})")
    except ValueError as exc:  # the schema's line names the file
        fail(str(exc))


#: Fewest frequencies a shaper is designed from. Assumed: a mode's frequency and damping
#: need points on both flanks of its peak and at it, a few each; with 3 rows the "mode" is
#: whichever row is largest.
MIN_FRF_POINTS = 16


def _frf_of_file(path: Path, axis: str | None, dt: float) -> tuple[np.ndarray, np.ndarray, float]:
    """``(freq_hz, response, dt)`` of an FRF file (``freq_hz`` column) or of a trace.

    A trace (time, input_<a>, output_<a>) gives H1 on segments of the largest power of two
    up to a quarter of the record, Hann window, half overlap, on the excited band. Either
    must give at least `MIN_FRF_POINTS` frequencies.
    """
    f, resp, f_dt = _frf_or_trace(path, axis, dt)
    if f.size < MIN_FRF_POINTS:
        fail(
            f"{path}: an FRF of {f.size} frequencies; a shaper is designed from at least "
            f"{MIN_FRF_POINTS} (points on both flanks of the mode and at its peak)"
        )
    return f, resp, f_dt


def _frf_or_trace(path: Path, axis: str | None, dt: float) -> tuple[np.ndarray, np.ndarray, float]:
    """`_frf_of_file` before its size check."""
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
    tr = read_trace_file(path)
    u, y = input_output(tr, path, axis or "x")
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
        shaper = design_inverse_shaper((model.num, model.den), cfg)
        shaper.tail_samples()  # refuses a filter whose rounded coefficients never settle
        return shaper
    except ValueError as exc:
        fail(f"{model_path}: {renamed(str(exc), _INVERSE_NAMES)}")


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


def _kinds() -> tuple[str, ...]:
    """``inverse`` and the classic shapers (`microfab.control.shapers.SHAPER_NAMES`)."""
    from microfab.control.shapers import SHAPER_NAMES

    return ("inverse", *SHAPER_NAMES)


def _discretizations() -> object:
    """The inverse's discretisations (`microfab.control.shaping.Discretization`)."""
    from microfab.control.shaping import Discretization

    return Discretization


def _twin_discretizations() -> tuple[str, ...]:
    """The twin's inverse discretisations (`microfab.machines.slm_galvo.shaping`)."""
    from microfab.machines.slm_galvo.shaping import DISCRETIZATIONS

    return DISCRETIZATIONS


def _twins() -> object:
    """The SLM galvo twins (`microfab.machines.slm_galvo.shapers.TwinName`)."""
    from microfab.machines.slm_galvo.shapers import TwinName

    return TwinName


@shaper_app.command("design")
def design_cmd(
    ctx: typer.Context,
    out: Annotated[Path, typer.Option(help="Write the shaper (JSON) here.")],
    model: Annotated[
        Path | None,
        typer.Argument(
            help="Model JSON (identify chirp --json): inverted by --kind inverse; the "
            "baseline of an --frf auto-fit otherwise."
        ),
    ] = None,
    kind: Annotated[
        str, choice(choices=_kinds, help="Shaper: the seed's model inverse or a classic one.")
    ] = "inverse",
    poles_hz: Annotated[
        float, number(help="Inverse: added real poles.", key=keys.POLE_HZ)
    ] = 4000.0,
    order: Annotated[
        int, integer(help="Inverse: number of added poles.", key=keys.SHAPER_ORDER)
    ] = 4,
    dt: Annotated[
        float,
        number(help="Sample time of the command.", unit="s", low=_MIN_DT_S, high=_MAX_DT_S),
    ] = 1e-5,
    discretization: Annotated[
        str,
        choice(
            choices=_discretizations,
            help="Inverse: zoh (the seed's) or zpetc (sampled-axis inverse).",
        ),
    ] = "zoh",
    freq_hz: Annotated[
        float | None,
        number(
            help="Classic: the mode's natural frequency.",
            unit="Hz",
            low=_FREQ_RANGE_HZ[0],
            high=_FREQ_RANGE_HZ[1],
        ),
    ] = None,
    damping: Annotated[
        float | None,
        number(
            help="Classic: the mode's damping ratio (default 0.1, Klipper's).",
            low=0.0,
            high=_MAX_DAMPING,
        ),
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
    check_outputs(files={"--out": out}, inputs={"MODEL": model, "--frf": frf, "--psd": psd})
    from microfab.control.shaper_io import shaper_to_dict
    from microfab.io.atomic import atomic_write_json

    _refuse_unused_design_options(ctx, kind, freq_hz is not None, psd is not None)
    if kind == "inverse":
        shaper = _design_inverse(model, poles_hz, order, dt, discretization)
        table = _inverse_table(shaper, _read_model(model))  # type: ignore[arg-type]
    else:
        shaper, table = _design_classic(kind, model, dt, freq_hz, damping, frf, psd, axis,
                                        freq_range)  # fmt: skip
    print_table(table)
    atomic_write_json(out, shaper_to_dict(shaper))
    console.print(f"wrote {out}", highlight=False)


def _refuse_unused_design_options(
    ctx: typer.Context, kind: str, from_mode: bool, from_psd: bool
) -> None:
    """Refuse the ``shaper design`` options the chosen kind and source do not use.

    --kind inverse uses MODEL, --poles-hz, --order, --dt and --discretization; a classic
    kind uses --dt, --damping and one of --freq-hz (a given mode) or --frf / --psd (an
    auto-fit, over --freq-range; --axis picks the column of an --frf file).
    """
    if kind == "inverse":
        refuse_unused(ctx, ["freq_hz", "damping", "frf", "psd", "freq_range", "axis"],
                      "with --kind inverse (it serves the classic kinds)")  # fmt: skip
        return
    refuse_unused(ctx, ["poles_hz", "order", "discretization"],
                  f"with --kind {kind} (it serves --kind inverse)")  # fmt: skip
    if from_mode:
        refuse_unused(ctx, ["freq_range", "axis"],
                      "with --freq-hz (it serves an auto-fit to --frf or --psd)")  # fmt: skip
    elif from_psd:
        refuse_unused(ctx, ["axis"], "with --psd (it names a column of an --frf file)")


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
    nyquist = 0.5 / dt
    fit = None
    if freq_hz is not None:
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
                try:  # a model of absurd coefficients: refused below, without warnings
                    with np.errstate(all="ignore"), warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        baseline = np.abs(m.frequency_response(f, sampling="zoh", dt=f_dt))
                except (ValueError, np.linalg.LinAlgError) as exc:
                    fail(f"{model}: no finite response over the FRF's band ({exc})")
                if not np.all(np.isfinite(baseline)):
                    fail(f"{model}: no finite response over the FRF's band (its coefficients?)")
            data: tuple[Any, ...] = (f, resp, "frf", baseline)
        else:
            f, resp = _read_psd(psd)  # type: ignore[arg-type]
            data = (f, resp, "psd", None)
        rng = None if freq_range is None else parse_range("--freq-range", freq_range)
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
    try:
        shaper.taps(dt)  # refuses a shaper of more taps than `MAX_TAPS`
    except ValueError as exc:
        fail(renamed(str(exc), {"dt =": "--dt ="}))
    return shaper, _impulse_table(shaper, dt, fit)


@shaper_app.command("compare")
def compare_cmd(
    ctx: typer.Context,
    twin: Annotated[
        str,
        choice(
            choices=_twins, help="seed (the seed's 3rd-order twin) or mirror (3 kHz mode added)."
        ),
    ] = "seed",
    jump_bit: Annotated[
        float,
        number(
            help="Step of the settling test (at most the field's width).",
            unit="bit",
            low=1.0,  # the scanner's resolution: a step under one bit is none
            high=2.0 * keys.FIELD_BIT,
        ),
    ] = 1000.0,
    start_bit: Annotated[
        float,
        number(
            help="Position before the step (inside the field).",
            unit="bit",
            low=-keys.FIELD_BIT,
            high=keys.FIELD_BIT,
        ),
    ] = 0.0,
    band_pct: Annotated[
        float,
        number(
            help="Settling band, of the jump.", unit="%", low=0.0, low_open=True, high=_MAX_BAND_PCT
        ),
    ] = 2.0,
    v_tol: Annotated[
        float | None,
        number(
            help="Vibration tolerance of the EI-family shapers (default 0.05).",
            low=0.0,
            low_open=True,
            high=_MAX_V_TOL,
        ),
    ] = None,
    inverse: Annotated[
        str,
        choice(
            choices=_twin_discretizations,
            help="Inverse shaper's discretisation: zoh (the seed's) or zpetc.",
        ),
    ] = "zpetc",
    shapers: Annotated[
        str | None,
        typer.Option(help="Classic shapers, comma-separated (default: all of --kind's)."),
    ] = None,
    true_mode: Annotated[
        bool,
        typer.Option(help="Design the classic shapers at the twin's true mode, not its chirp FRF."),
    ] = False,
    seed: Annotated[
        int, integer(help="Noise seed of the chirp identification.", key=keys.TWIN_SEED)
    ] = 0,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the comparison (JSON) here.")
    ] = None,
) -> None:
    """Shapers side by side on the SLM galvo twin: vibration, delay, settling, ramp lag.

    Rows: unshaped, the seed 003 §2 model inverse, each classic shaper designed for the
    mode identified from the twin's noisy chirp FRF (or its true mode), and inverse+ZV.
    A shaped step that leaves the scanner's field is reported as refused.
    """
    from microfab.control.shaper_forms import SHAPERS
    from microfab.control.shapers import DEFAULT_V_TOL, SHAPER_NAMES

    names = SHAPER_NAMES if shapers is None else tuple(n.strip() for n in shapers.split(","))
    if true_mode:
        refuse_unused(ctx, ["seed"], "with --true-mode (no noisy chirp is identified)")
    if all(n in SHAPERS and SHAPERS[n].exact for n in names):
        refuse_unused(ctx, ["v_tol"], f"with --shapers {shapers} (ZV, ZVD and MZV have no "
                      "vibration tolerance; the EI family has)")  # fmt: skip
    end = start_bit + jump_bit
    if abs(end) > keys.FIELD_BIT:
        fail(f"--start-bit {start_bit:g} bit + --jump-bit {jump_bit:g} bit ends at {end:g} "
             f"bit, outside the twin's field ±{keys.FIELD_BIT} bit")  # fmt: skip
    check_outputs(files={"--json": json_path})
    from microfab.machines.slm_galvo.shapers import CompareSettings, compare_shapers
    from microfab.report.slm_tables import comparison_table

    try:
        settings = CompareSettings(
            jump_bit=jump_bit,
            start_bit=start_bit,
            band=band_pct / 100.0,
            v_tol=DEFAULT_V_TOL if v_tol is None else v_tol,
            inverse=inverse,  # type: ignore[arg-type]  # checked by CompareSettings
            shapers=names,
            frf_noise=not true_mode,
        )
        result = compare_shapers(twin, settings, seed=seed)  # type: ignore[arg-type]
    except ValueError as exc:
        fail(str(exc))
    print_table(comparison_table(result))
    if json_path is not None:
        from microfab.io.atomic import atomic_write_json

        atomic_write_json(json_path, result.summary())
        console.print(f"wrote {json_path}", highlight=False)
