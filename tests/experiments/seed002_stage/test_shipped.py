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
#: same kernels on the networks trained with whitened inputs (issue 46): σ 1.7e-5 relative
#: (y letters at 3 m/s²; 1e-6 on validation), μ 0.0038 µm (μ is a mean of errors of σ ≈
#: 4-14 µm, so it moves in absolute terms, not relative to its near-zero value). About ten
#: times σ's and five times μ's (as before, where the earlier networks spread 3.0e-6 and
#: 0.0038 µm): far below any cell's distance from twice the seed's.
SIGMA_REL = 2e-4
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


#: Measured on the shipped models (trained.json: trained on the twin calibrated on the core
#: with whitened inputs, issue 46), σ µm, ours / seed, validation x 5.2 / 3.2, y 7.9 / 6.0;
#: letters 1 m/s² x 3.6 / 8.2, y 10.7 / 13.4; 3 m/s² x 3.9 / 11.1, y 13.5 / 18.7: every
#: cell within twice the seed's (three missed before the whitening: 10.6, 20.6, 39.8 µm).


@pytest.mark.parametrize(("axis", "column"), CELLS)
def test_table_ii_network_cell_within_twice_the_paper(again, axis, column):
    ours, seed = _cell(again, axis, column)
    assert ours <= 2 * seed, f"{axis} {column}: ours {ours:.1f} um, seed {seed:.1f} um"


#: The issue's bound on the calibration's proxy against the full training (issue 46).
PROXY_BAND = 0.25


@pytest.mark.parametrize("axis", ["x", "y"])
def test_the_networks_lie_within_25_percent_of_the_calibration_proxy(again, axis):
    # the proxy the twin's calibration fits (xy_stage.proxy), recorded on the networks' own
    # data when the models were made; the networks' σ recomputed here
    proxy = again["recorded"]["proxy"][axis]["sigma_um"]
    nets = again["validation"][axis]["sigma_um"]
    assert abs(nets / proxy - 1.0) <= PROXY_BAND, (
        f"{axis}: networks {nets:.2f} um against the proxy's {proxy:.2f} um"
    )
