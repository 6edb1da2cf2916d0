"""The models shipped for the built-in XY stage twin: made as recorded, scoring as recorded.

No training here: the networks' data are made again from the recorded settings and must
match the record's summary of them within a tolerance measured across BLAS kernels (their
bytes differ from CPU to CPU, so no digest of them is compared); the shipped networks
are scored on the validation runs and on the letters (Table II), and the paper's network
cells are checked per cell.
"""

from __future__ import annotations

import pytest

pytest.importorskip("torch")

from microfab.experiments.seed002_stage import paper
from microfab.experiments.seed002_stage.shipped import RECORD, recheck
from microfab.identify.ann_data import summary_deviation
from microfab.optimize.models import builtin_models_dir, load_models

FOLDER = builtin_models_dir()


@pytest.fixture(scope="module")
def again():
    return recheck(FOLDER)


def test_the_shipped_folder_holds_models_and_their_record():
    for name in (RECORD, "linear_model.json", "ann/model/model.json", "ann/model/weights.npz"):
        assert (FOLDER / name).is_file(), name
    size = sum(f.stat().st_size for f in FOLDER.rglob("*") if f.is_file())
    assert size < 4e6  # "a few MB at most" (issue 34)


#: Largest difference allowed between the networks' data made again and the record's
#: summary, relative to each signal's RMS over the runs (`summary_deviation`). Measured
#: spread on the twin calibrated on the core (issue 46; `recheck` with this machine's
#: OpenBLAS kernels, which made the record: 0; SandyBridge with one thread and PyTorch's
#: default kernels): 8.5e-7 on the training runs, 9.3e-7 on the validation runs (the
#: earlier twin, with 20x the friction, spread 1.02e-5 / 2.0e-6 over four kernel setups).
#: Ten times the spread (two kernel families measured, not four): far below the 2 µm
#: encoder noise on the positions' scale (seed 002 Table I; 3.4e-5 of their 58 mm RMS).
DATA_TOL = 1e-5
#: Validation and letter cells, µm: σ relative, μ absolute. Measured spread across the
#: same kernels: σ 3.0e-6 relative, μ 0.0038 µm (μ is a mean of errors of σ ≈ 6-40 µm,
#: so it moves in absolute terms, not relative to its near-zero value); ten times σ's,
#: five times μ's (as before, where the earlier twin's spread was 0.0036 µm).
SIGMA_REL = 3e-5
MU_ABS_UM = 0.02


def test_the_training_data_are_made_again_from_the_recorded_settings(again):
    rec = again["recorded"]["data"]
    info = again["model"].model.info
    # the record and the model agree on what the training saw (bytes: the same file set)
    assert rec["train_digest"] == info["train_digest"] and rec["val_digest"] == info["val_digest"]
    # the data made again are those data, to the tolerance above (not to the bit)
    for part in ("train", "val"):
        dev = summary_deviation(again[f"{part}_summary"], rec[f"{part}_summary"])
        assert dev <= DATA_TOL, f"{part}: data differ from the record by {dev:.3g} of scale"


def _close(got: float, want: float, key: str) -> bool:
    if key.startswith("mu"):
        return abs(got - want) <= MU_ABS_UM
    return abs(got - want) <= SIGMA_REL * abs(want)


def test_the_shipped_networks_score_as_recorded_on_the_validation_runs(again):
    for a in ("x", "y"):
        got, want = again["validation"][a], again["recorded"]["validation"][a]
        for key in ("mu_um", "sigma_um"):
            assert _close(got[key], want[key], key), (a, key, got[key], want[key])


def test_the_letter_cells_score_as_recorded(again):
    for a, cells in again["letters"].items():
        want = again["recorded"]["letters"][a]["ann"]
        for key, value in cells.items():
            assert _close(value, want[key], key), (a, key, value, want[key])


def test_the_models_load_as_the_builtin_default():
    m = load_models("")
    assert m.source == "builtin" and m.networks is not None
    assert load_models("builtin").source == "builtin"


def _cell(again, axis: str, column: str) -> tuple[float, float]:
    if column == "training":
        ours = again["validation"][axis]["sigma_um"]
    else:
        ours = again["letters"][column.split("_")[1]][f"sigma_{axis}_um"]
    return ours, paper.TABLE_II["ann"][axis][column].sigma_m * 1e6


CELLS = [(a, c) for a in ("x", "y") for c in ("training", "letters_1", "letters_3")]


#: Measured on the shipped models (trained.json, trained on the twin calibrated on the core,
#: issue 46), σ µm, ours / seed, of the cells that miss twice the seed's.
MEASURED = {
    ("x", "training"): "10.6 / 3.2", ("y", "training"): "20.6 / 6.0",
    ("y", "letters_3"): "39.8 / 18.7",
}  # fmt: skip
CAUSE = (
    "the networks do not learn what their window predicts: a fixed random-feature ridge "
    "regression on the same windows and data (xy_stage.proxy) reaches 4.9 / 6.6 um on the "
    "validation runs, so the twin's unpredictable part is within 2x of the seed's; the "
    "networks' 60-epoch schedule stops 2-3x above it (the seed trains about 24 h per axis)"
)


def _marks(a: str, c: str) -> tuple[pytest.MarkDecorator, ...]:
    if (a, c) not in MEASURED:
        return ()
    return (
        pytest.mark.xfail(
            raises=AssertionError, strict=True, reason=f"{MEASURED[a, c]} um; {CAUSE}"
        ),
    )


@pytest.mark.parametrize(
    ("axis", "column"), [pytest.param(a, c, marks=_marks(a, c)) for a, c in CELLS]
)
def test_table_ii_network_cell_within_twice_the_paper(again, axis, column):
    ours, seed = _cell(again, axis, column)
    assert ours <= 2 * seed, f"{axis} {column}: ours {ours:.1f} um, seed {seed:.1f} um"
