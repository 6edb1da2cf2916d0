"""``microfab identify ann``: the per-axis networks of seed 002 (eq. 7) on measured runs.

The runs are read and checked as ``identify linear`` reads them (`cli/identify_stage.py`), split
80/20 by whole runs (seeded), and the networks trained by
`microfab.identify.ann_train.train_ann` with their checkpoints in ``DIR/checkpoints``: an
interrupted training resumes when the same command is run again, ``--restart`` starts
over. The model is saved to ``DIR`` (`microfab.identify.stage_ann.save_ann_model`) and
its validation μ, σ per axis are printed beside seed 002 Table II's ANN column;
``identify validate DIR RUN...`` reads it.

Every refusal is one ``error:`` line, exit code 2, and nothing is written; an
interrupted training leaves only its checkpoints.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import (
    check_outputs,
    console,
    fail,
    print_table,
    progress,
    renamed,
)
from microfab.cli._options import choice, integer, number, refuse_unused
from microfab.cli.identify import _RUN_HELP, ANN_COMPARED, _error_table, _read_runs, identify_app
from microfab.experiments.seed002_stage.keys import (
    ANN_EPOCH_WINDOWS,
    ANN_MAX_EPOCHS,
    ANN_SEED,
    ANN_THREADS,
    ANN_VALIDATION,
    ANN_WHITEN,
    ANN_WORKERS,
    WHITEN,
    check_whiten_key,
)
from microfab.io.lock import hold_for_command
from microfab.report.tables import Table

__all__ = ["ann_cmd"]

_AXES = {"x": ("x",), "y": ("y",), "both": ("x", "y")}
_CHECKPOINTS = "checkpoints"  # DIR/checkpoints: train_ann's ann_<axis>.ckpt.npz
#: Devices `microfab.identify.ann.AnnConfig` takes (``device``).
_DEVICES = ("auto", "cpu", "cuda")


def _features() -> tuple[str, ...]:
    """The input feature sets (`microfab.identify.ann_data.FEATURES`), imported when needed."""
    from microfab.identify.ann_data import FEATURES

    return FEATURES


@identify_app.command("ann")
def ann_cmd(
    ctx: typer.Context,
    runs: Annotated[list[Path], typer.Argument(help=_RUN_HELP + " At least two.")],
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            help="Model directory (model.json, weights.npz; checkpoints/ while training); "
            "`optimize --model DIR` reads DIR/ann/model.",
        ),
    ],
    axis: Annotated[str, choice(choices=_AXES, help="Axes trained, one network each.")] = "both",
    epochs: Annotated[
        int,
        integer(
            "--epochs",
            key=ANN_MAX_EPOCHS,
            help="Most epochs per axis (early stopping may end sooner; seed 002: 200).",
        ),
    ] = 200,
    device: Annotated[
        str, choice(choices=_DEVICES, help="Training device; auto: CUDA if present, else CPU.")
    ] = "auto",
    restart: Annotated[
        bool, typer.Option("--restart", help="Discard the checkpoints and train from scratch.")
    ] = False,
    threads: Annotated[
        int,
        integer(
            "--threads",
            key=ANN_THREADS,
            help="CPU threads of PyTorch (1: best on a shared 2-core box).",
        ),
    ] = 1,
    workers: Annotated[
        int,
        integer(
            "--workers",
            key=ANN_WORKERS,
            help="Axes trained at once, each in its own process (2: x and y "
            "side by side, half the time on 2 cores; same networks).",
        ),
    ] = 1,
    epoch_windows: Annotated[
        int,
        integer(
            "--epoch-windows",
            key=ANN_EPOCH_WINDOWS,
            help="Training windows per epoch, a fresh random draw each "
            "epoch (0: all windows every epoch).",
        ),
    ] = 0,
    validation: Annotated[
        float,
        number(
            "--validation",
            key=ANN_VALIDATION,
            help="Share of the runs kept for validation (seed 002: 0.2).",
        ),
    ] = 0.2,
    seed: Annotated[
        int,
        integer("--seed", key=ANN_SEED, help="Seeds the split, the initial weights, the shuffles."),
    ] = 0,
    features: Annotated[
        str,
        choice(
            choices=_features,
            help="position: also sin/cos of the last 40 ms of absolute positions at 13 "
            "wavelengths (1-251 mm) as inputs, so position-periodic forces (cogging) are "
            "learnt (better on runs like the training runs, worse on new shapes on the "
            "twin); none: the seed's 200 inputs only.",
        ),
    ] = "none",
    whiten: Annotated[
        float,
        number(
            "--whiten",
            key=ANN_WHITEN,
            help="Shrinkage of the whitened inputs the training feeds the networks, a share "
            "of their mean eigenvalue (the whitening is folded into the first layer, so the "
            "saved networks are the seed's); 0: the scaled inputs as they are.",
        ),
    ] = WHITEN,
) -> None:
    """Train seed 002's per-axis networks (eq. 7, Fig. 5) on measured runs of the stage.

    Each axis's network reads the last 500 ms of that axis's command at 400 Hz (h = 200)
    and predicts its measured position. The runs are split 80/20 by whole runs; training
    (MSE, Adam, batches of 16 384, early stopping on the validation runs) checkpoints
    every epoch to DIR/checkpoints, so running the same command again resumes it. Prints
    μ, σ per axis on the validation runs at every run sample, beside seed 002 Table II.
    """
    check_outputs(folders={"--out": out}, inputs={"RUNS": runs})
    hold_for_command(out, "--out", on_refused=fail)
    if axis != "both":
        refuse_unused(ctx, ["workers"], f"with --axis {axis} (one network, one process)")
    if out.exists() and not out.is_dir():
        fail(f"--out {out} is a file: the model is a directory (model.json, weights.npz)")
    try:
        shrink = check_whiten_key(whiten, "--whiten")
    except ValueError as exc:
        fail(str(exc))
    try:
        import torch

        from microfab.identify.ann_train import CheckpointMismatchError
        from microfab.identify.stage_ann import (
            ann_config,
            save_ann_model,
            split_records,
            train_stage_ann,
        )
    except ImportError as exc:
        fail(f"identify ann needs PyTorch (extra 'ann'): {exc}")
    if device == "cuda" and not torch.cuda.is_available():
        fail("--device cuda: no CUDA device is available to PyTorch here; use --device cpu")
    records, dt = _read_runs(runs)
    try:
        train, val = split_records(records, validation, seed)
        config = ann_config(
            1.0 / dt,
            _AXES[axis],
            features=features,
            max_epochs=epochs,
            seed=seed,
            device=device,
            threads=threads,
            workers=workers,
            epoch_windows=epoch_windows or None,
            whiten=shrink,
        )
    except ValueError as exc:
        fail(renamed(str(exc), {"validation must": "--validation must"}))
    ckdir = out / _CHECKPOINTS
    if restart and ckdir.is_dir():
        for f in ckdir.glob("ann_*.ckpt.npz"):
            f.unlink()
    trained: dict[str, list[int]] = {a: [] for a in config.axes}
    try:
        with progress() as prog:
            tasks: dict[str, Any] = {}  # a bar once an axis trains (none for a refusal)

            def report(rec: Any) -> None:
                trained[rec.axis].append(rec.epoch)
                if rec.axis not in tasks:
                    tasks[rec.axis] = prog.add_task(f"axis {rec.axis}", total=epochs)
                prog.update(
                    tasks[rec.axis],
                    completed=rec.epoch,
                    description=f"axis {rec.axis}: loss {rec.train_loss:.3g} / val "
                    f"{rec.val_loss:.3g}",
                )

            fit = train_stage_ann(
                train, val, config, checkpoint_dir=ckdir, progress=report, restart=restart
            )
    except CheckpointMismatchError as exc:
        fail(renamed(str(exc), {"pass restart=True": "pass --restart"}))
    except ValueError as exc:
        fail(f"training on {len(train)} run(s): {exc}")
    model, errors = fit.model, fit.errors
    model.info["runs"] = {"training": [r.name for r in train], "validation": [r.name for r in val]}
    print_table(_training_table(model.info, trained, train, val))
    title = "Prediction error on the validation runs"
    compared = ANN_COMPARED.format(rate=errors.rate_hz)
    print_table(_error_table(title, errors, "ann", "Non-linear", compared))
    save_ann_model(model, out)
    console.print(f"wrote {out}", highlight=False)


def _training_table(
    info: dict[str, Any], trained: dict[str, list[int]], train: list[Any], val: list[Any]
) -> Table:
    rows = [
        ("training runs", ", ".join(r.name for r in train)),
        ("validation runs", ", ".join(r.name for r in val)),
        ("windows (training, validation)", f"{info['train_windows']}, {info['val_windows']}"),
    ]
    for a, s in info["axes"].items():
        done = trained[a]
        now = f"{done[0]}-{done[-1]}" if done else "none (finished before)"
        rows.append(
            (
                f"axis {a}: epochs (this run), best, stopped early",
                f"{s['epochs']} ({now}), {s['best_epoch'] + 1}, {s['stopped_early']}",
            )
        )
    return Table(
        title="Networks of seed 002 eq. (7), one per axis (Fig. 5)",
        columns=("quantity", "value"),
        rows=rows,
        note="epochs counted from 1; best: the epoch whose weights are kept",
    )
