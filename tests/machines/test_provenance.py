"""Labels derived from the twins' data files and the calibrations' declared targets."""

from __future__ import annotations

import pytest

from microfab.core.provenance import Calibration, RowLabel, Shows, quantity
from microfab.machines import provenance
from microfab.machines.galvo.calibration import table1_quantity
from microfab.report.provenance import labelled
from microfab.report.tables import Table


def test_every_calibration_declares_targets_and_holds_on_the_shipped_data() -> None:
    cals = provenance.calibrations()
    assert len(cals) >= 5
    assert len({(c.command, c.marker) for c in cals}) == len(cals)
    for c in cals:
        assert c.targets and all(q.startswith("seed ") for q in c.targets)
    # one command may declare a retired fit and its successor (told apart by their
    # markers): exactly one of them holds on the shipped data
    for command in {c.command for c in cals}:
        held = [provenance.holds(c) for c in cals if c.command == command]
        assert held.count(True) == 1, f"{command}: {held.count(True)} of {len(held)} hold"


def test_a_target_is_fitted_the_rest_predicted_and_seed_values_are_inputs() -> None:
    fb, ilc = table1_quantity("x", "fb_rms", 100), table1_quantity("x", "ilc_rms", 400)
    assert provenance.label(Shows((fb,))).origin == "fitted"
    assert provenance.label(Shows((fb,))).text == "fitted (calibrate galvo)"
    assert provenance.label(Shows((ilc,))).origin == "predicted"
    mixed = provenance.label(Shows((fb, ilc)))
    assert mixed.origin == "mixed" and mixed.counts == {"fitted": 1, "predicted": 1}
    assert mixed.fitted == (fb,) and mixed.text == "1 fitted (calibrate galvo), 1 predicted"
    # a calibration the run did not use fits nothing
    off = provenance.label(Shows((fb,)), not_applied=("microfab calibrate galvo",))
    assert off.origin == "predicted"
    # values read from the data files: the seed's G(s) is an input, a calibrated noise fitted
    inp = provenance.label(Shows(parameters=[("galvo_slm.toml", "model.numerator")]))
    assert inp.origin == "input" and inp.inputs == ("galvo_slm.toml: model.numerator",)
    cal = provenance.label(Shows(parameters=[("lmw_stage.toml", "disturbance.disturbance_scale")]))
    assert cal.origin == "fitted"
    assert provenance.label(Shows(from_seed=("seed 003 §4",))).origin == "input"
    assert provenance.label(Shows()).origin == "predicted"


def test_an_assumed_value_is_not_a_number_to_compare() -> None:
    with pytest.raises(ValueError, match="assumed"):
        provenance.label(Shows(parameters=[("lmw_stage.toml", "axes.x.mass_kg")]))
    with pytest.raises(KeyError, match="no _source"):
        provenance.parameter_source("galvo_slm.toml", "model.nothing")


def test_a_data_file_reset_to_assumed_values_labels_nothing_fitted(monkeypatch) -> None:
    """The label follows the data file: without the calibration's command, no fit holds."""
    fb = table1_quantity("x", "fb_rms", 100)
    real = provenance._data_text

    def reset(name: str) -> str:
        text = real(name)
        return (
            text.replace("microfab calibrate galvo", "by hand")
            if name == "galvo_twin.toml"
            else text
        )

    monkeypatch.setattr(provenance, "_data_text", reset)
    assert provenance.label(Shows((fb,))).origin == "predicted"


def test_a_calibration_needs_targets_and_a_module_must_declare_one(monkeypatch) -> None:
    with pytest.raises(ValueError, match="at least one target"):
        Calibration(command="x", data_file="", targets=frozenset())
    with pytest.raises(ValueError, match="at least its figure"):
        quantity("001")
    provenance.calibrations.cache_clear()
    monkeypatch.setattr(provenance, "CALIBRATION_MODULES", ("microfab.core.provenance",))
    try:
        with pytest.raises(TypeError, match="declares no Calibration"):
            provenance.calibrations()
    finally:
        provenance.calibrations.cache_clear()


def test_a_labelled_table_carries_one_label_per_row_in_its_last_column() -> None:
    t = Table(title="t", columns=("a", "b"), rows=[("1", "2"), ("3", "4")])
    fb = table1_quantity("y", "fb_pp", 200)
    lab = labelled(t, [Shows((fb,)), Shows()])
    assert lab.columns[-1] == "ours is"
    assert [r[-1] for r in lab.rows] == ["fitted (calibrate galvo)", "predicted"]
    js = lab.labels_json()
    assert js[0]["row"] == ["1", "2"] and js[0]["quantities"] == [fb]
    with pytest.raises(ValueError, match="labelled already"):
        lab.with_labels(lab.labels)
    with pytest.raises(ValueError, match="2 rows"):
        t.with_labels([RowLabel(origin="predicted")])
    with pytest.raises(ValueError, match="label cell"):
        Table(title="t", columns=("a", "ours is"), rows=[("1", "input")],
              labels=[RowLabel(origin="predicted")])  # fmt: skip
