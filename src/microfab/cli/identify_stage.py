"""``microfab identify linear|validate``: seed 002's black-box XY stage on measured runs.

``identify linear RUN...`` fits eq. (6) after an anti-alias decimation and writes the
model file; ``identify validate MODEL RUN...`` prints a linear or a network model's error
per axis in the layout of Table II (`microfab.identify.stage_data`,
`microfab.identify.stage_ann`). What ``identify ann`` (`cli/identify_ann.py`) shares with
them is here too: the runs' reader and help (`_read_runs`, `_RUN_HELP`) and Table II's
layout (`_error_table`, `ANN_COMPARED`); `cli/identify.py` re-exports every name.

The commands are plain functions: `cli/identify.py` registers them on its group right
after ``identify chirp``, so that the group lists chirp, linear, validate and ann as
before. This module does not import the group; the group's module imports this one.

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
    print_table,
    read_trace_file,
    renamed,
)
from microfab.cli._options import choice, integer
from microfab.experiments.seed002_stage.keys import DECIMATE, ORDER
from microfab.report.tables import Table

__all__ = ["linear_cmd", "validate_cmd"]


def _weightings() -> tuple[str, ...]:
    """The subspace weightings (`microfab.identify.subspace.WEIGHTINGS`), imported when needed."""
    from microfab.identify.subspace import WEIGHTINGS

    return WEIGHTINGS


# --- seed 002: the black-box XY stage ------------------------------------------------------

_RUN_HELP = "Measured runs (.csv, .mat, .h5), each from rest: time [s], input_x, input_y, "
_RUN_HELP += "output_x, output_y [m], at a multiple of 400 Hz, at least 500 ms."


def _read_runs(paths: list[Path]) -> tuple[list[Any], float]:
    """The runs, checked (`stage_data.stage_record`), and their common sample time, s."""
    from microfab.identify.stage_data import stage_record

    records, dt = [], None
    for path in paths:
        tr = read_trace_file(path)
        try:
            records.append(stage_record(tr, str(path)))
        except ValueError as exc:
            fail(str(exc))
        if dt is None:
            dt = float(tr.dt)
        elif abs(tr.dt / dt - 1.0) > 1e-9:
            fail(f"{path}: sampled at {1 / tr.dt:.6g} Hz, {paths[0]} at {1 / dt:.6g} Hz")
    assert dt is not None  # typer requires at least one RUN
    return records, dt


def _error_table(
    title: str,
    errors: Any,
    seed: str | None = None,
    label: str = "Linear",
    compared: str | None = None,
) -> Table:
    """Seed 002 Table II's layout: model, axis, μ, σ in µm (and a seed column beside).

    ``seed`` names Table II's row (``"linear"``: its training data; ``"ann"``: its
    validation data) to print beside; ``compared`` says where the errors were taken
    (default: a linear model's rate, the runs decimated as for its fit).
    """
    from microfab.experiments.seed002_stage.paper import TABLE_II

    rows = []
    for a, axis in enumerate(errors.axes):
        row = [label, axis, f"{errors.mean[a] * 1e6:.1f}", f"{errors.std[a] * 1e6:.1f}"]
        if seed is not None:
            ref = TABLE_II[seed][axis]["training"]
            row += [f"{ref.mu_m * 1e6:.1f}", f"{ref.sigma_m * 1e6:.1f}"]
        rows.append(row)
    cols = ["model", "axis", "μ [µm]", "σ [µm]"]
    cols += ["seed μ [µm]", "seed σ [µm]"] if seed is not None else []
    if compared is None:
        compared = f"at the model's {errors.rate_hz:g} Hz (the runs decimated as for the fit)"
    note = f"y - y_model over {errors.n_samples} samples {compared}, each run simulated from rest"
    if seed == "linear":
        note += "; seed: Table II, linear model on its training data (the ETEL stage)"
    elif seed == "ann":
        note += "; seed: Table II, non-linear model (ANN) on its validation data (the ETEL stage)"
    return Table(title=title, columns=cols, rows=rows, note=note)


#: Most block rows of the subspace fit: `microfab.identify.subspace.MAX_BLOCK_ROWS` (its R
#: factor's memory bound), restated so that the CLI starts without SciPy; a test checks it.
MAX_BLOCK_ROWS = 256


#: Where a network model's errors are taken (`microfab.identify.stage_ann`).
ANN_COMPARED = (
    "at every run sample ({rate:g} Hz: the 400 Hz networks at each start offset, interleaved)"
)


def _model_table(m: Any, decimate: int, input_rate: float, n_runs: int) -> Table:
    rows = [
        ("runs", f"{n_runs}"),
        ("rate", f"{input_rate:g} Hz decimated by {decimate} to {1 / m.dt:g} Hz (FIR anti-alias)"),
        ("order, block rows, weighting", f"{m.order}, {m.block_rows}, {m.weighting}"),
        ("discrete poles |z|", ", ".join(f"{abs(z):.6g}" for z in m.poles)),
    ]
    try:
        s = m.continuous_poles()
    except ValueError as exc:
        rows.append(("continuous poles", str(exc)))
    else:
        rows += [
            ("continuous poles [rad/s]", ", ".join(f"{p:.5g}" for p in s)),
            ("natural frequency [Hz], ζ",
             "; ".join(f"{abs(p) / (2 * np.pi):.4g}, {-p.real / abs(p):.3g}" for p in s)),
            ("time constants [ms]", ", ".join(f"{1e3 * t:.4g}" for t in m.time_constants_s())),
        ]  # fmt: skip
    rows.append(("D (feed-through)", "; ".join(", ".join(f"{v:.4g}" for v in r) for r in m.d)))
    return Table(
        title="Linear model of the stage, seed 002 eq. (6)",
        columns=("quantity", "value"),
        rows=rows,
    )


def linear_cmd(
    runs: Annotated[list[Path], typer.Argument(help=_RUN_HELP)],
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            help="Write the model file (JSON) here; `optimize --model DIR` reads "
            "DIR/linear_model.json.",
        ),
    ],
    order: Annotated[int, integer("--order", key=ORDER, help="States n (seed 002 §III-A: 4).")] = 4,
    block_rows: Annotated[
        int | None,
        integer(
            "--block-rows",
            help="Block rows of past and future (default 2n + 2).",
            low=2,
            high=MAX_BLOCK_ROWS,
        ),
    ] = None,
    weighting: Annotated[
        str, choice(choices=_weightings, help="Subspace weighting of the fit.")
    ] = "moesp",
    feedthrough: Annotated[
        bool,
        typer.Option(
            help="Estimate D (eq. 6b writes it; MATLAB n4sid's default is D = 0, which on the "
            "twin misses by ~25x)."
        ),
    ] = True,
    decimate: Annotated[
        int | None,
        integer(
            "--decimate",
            key=DECIMATE,
            help="Decimate inputs and outputs alike first, FIR anti-alias filter (order 20q, "
            "Hamming, zero phase); default: to about 1 kHz, where the fit is well conditioned "
            "(10 for 10 kHz runs).",
        ),
    ] = None,
) -> None:
    """Fit seed 002 eq. (6), a linear state-space model of the XY stage, to measured runs.

    Inputs and outputs are decimated identically (anti-alias FIR), then N4SID-family
    subspace identification (MOESP by default) gives A, B, C, D; the model is converted
    to continuous time by the inverse ZOH when used. Prints the poles, time constants and
    μ, σ per axis on the training runs (Table II's layout); writes the model file that
    ``identify validate`` reads.
    """
    check_outputs(files={"--out": out}, inputs={"RUNS": runs})
    from microfab.identify.stage_data import (
        StageLinearModel,
        check_decimate,
        default_decimate,
        fit_linear,
        write_stage_model,
    )

    if block_rows is not None and order > block_rows:
        fail(f"--order {order} is above --block-rows {block_rows}: use --block-rows >= {order}")
    from microfab.identify.subspace import SubspaceConfig

    try:  # the options alone, before any run is read
        SubspaceConfig(order=order, block_rows=block_rows, weighting=weighting)
    except ValueError as exc:
        fail(renamed(str(exc), {"block_rows": "--block-rows", "order": "--order"}))
    records, dt = _read_runs(runs)
    if decimate is None:
        decimate = default_decimate(1.0 / dt)
    try:
        check_decimate(decimate, 1.0 / dt)
        model = fit_linear(
            records, dt, order=order, decimate=decimate, feedthrough=feedthrough,
            block_rows=block_rows, weighting=weighting,
        )  # fmt: skip
        stage = StageLinearModel(model=model, input_dt=dt, decimate=decimate)
        errors = stage.errors(records)
    except (ValueError, np.linalg.LinAlgError) as exc:
        msg = renamed(str(exc), {"block_rows": "--block-rows", "decimate": "--decimate"})
        fail(f"linear fit of {len(runs)} run(s): {msg}")
    print_table(_model_table(model, decimate, 1.0 / dt, len(records)))
    print_table(_error_table("Prediction error on the training runs", errors, seed="linear"))
    write_stage_model(out, stage)
    console.print(f"wrote {out}", highlight=False)


def validate_cmd(
    model: Annotated[
        Path,
        typer.Argument(
            help="Model file written by identify linear, or directory written by identify ann."
        ),
    ],
    runs: Annotated[list[Path], typer.Argument(help=_RUN_HELP)],
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write μ, σ per axis and per run (JSON) here.")
    ] = None,
) -> None:
    """Prediction error of a stage model on measured runs, per axis (seed 002 Table II).

    MODEL is a linear model's file (``identify linear``) or a network model's directory
    (``identify ann``). A linear model predicts at its own rate: the runs are decimated as
    for its fit and compared there, each simulated from rest at its first set-point. The
    networks predict every run sample (10 kHz for the seed's runs), each 400 Hz start
    offset in turn; a model of another format version, model rate or history is refused.
    """
    check_outputs(files={"--json": json_path}, inputs={"MODEL": model, "RUNS": runs})
    from microfab.identify.stage_data import read_stage_model

    try:
        stage = read_stage_model(model)
    except ValueError as exc:
        fail(str(exc))
    records, dt = _read_runs(runs)
    if abs(dt * stage.input_rate_hz - 1.0) > 1e-9:
        fail(
            f"{runs[0]} is sampled at {1 / dt:.6g} Hz, the model {model} was fitted to "
            f"{stage.input_rate_hz:.6g} Hz runs"
        )
    try:
        errors = stage.errors(records)
    except (ValueError, np.linalg.LinAlgError) as exc:
        fail(f"validation of {model}: {exc}")
    label = {"linear": "Linear", "ann": "Non-linear"}.get(stage.kind, stage.kind)
    compared = ANN_COMPARED.format(rate=errors.rate_hz) if stage.kind == "ann" else None
    print_table(_error_table(f"Prediction error of {model.name}", errors, None, label, compared))
    if json_path is not None:
        from microfab.io.atomic import atomic_write_json

        um = [1e6 * float(v) for v in errors.mean], [1e6 * float(v) for v in errors.std]
        atomic_write_json(
            json_path,
            {
                "model": str(model),
                "kind": stage.kind,
                "axes": list(errors.axes),
                "compared_at_hz": errors.rate_hz,
                "n_samples": errors.n_samples,
                "mu_um": um[0],
                "sigma_um": um[1],
                "runs": [
                    {"run": name, "mu_um": (1e6 * mu).tolist(), "sigma_um": (1e6 * sd).tolist()}
                    for name, mu, sd in errors.per_run
                ],
            },
        )
        console.print(f"wrote {json_path}", highlight=False)
