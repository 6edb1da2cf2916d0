"""The models of a stage-identify output, as the optimisation reads them."""

from __future__ import annotations

import pytest

from microfab.optimize.models import load_models


def test_a_folder_without_a_linear_model_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"linear_model\.json: no linear model"):
        load_models(tmp_path)


def test_the_linear_model_alone_for_stage_1(tiny_models):
    m = load_models(tiny_models[0], networks=False)
    assert m.networks is None and m.linear is not None
    assert m.source == str(tiny_models[0])


def test_a_models_folder_is_checked_before_any_work(tmp_path) -> None:
    """Issue 32: `run --check` called a reference job valid although it had no models."""
    from microfab.optimize.models import check_models_dir

    with pytest.raises(ValueError, match="does not exist; run `microfab run"):
        check_models_dir(tmp_path / "none")
    with pytest.raises(ValueError, match=r"holds no linear_model\.json and no ann/model"):
        check_models_dir(tmp_path)
    (tmp_path / "linear_model.json").write_text("{}")
    check_models_dir(tmp_path, networks=False)
    with pytest.raises(ValueError, match=r"holds no ann/model/model\.json"):
        check_models_dir(tmp_path)
    (tmp_path / "ann" / "model").mkdir(parents=True)
    (tmp_path / "ann" / "model" / "model.json").write_text("{}")
    check_models_dir(tmp_path)


def test_the_recorded_validation_sigma_is_read(tmp_path):
    """Shipped models: trained.json (µm); a stage-identify output: summary.json (m)."""
    import json

    from microfab.optimize.models import builtin_models_dir, recorded_validation_sigma

    shipped = recorded_validation_sigma("builtin")
    record = json.loads((builtin_models_dir() / "trained.json").read_text(encoding="utf-8"))
    assert shipped is not None
    for a in ("x", "y"):  # the record's µm read as m (y: 7.9 µm)
        assert shipped[a] == pytest.approx(record["validation"][a]["sigma_um"] * 1e-6, rel=1e-12)
    assert recorded_validation_sigma(tmp_path) is None  # none recorded: no warning by σ
    (tmp_path / "summary.json").write_text(json.dumps(
        {"ann": {"validation": {"x": {"std_m": 3e-6}, "y": {"std_m": 4e-6}}}}))  # fmt: skip
    assert recorded_validation_sigma(tmp_path) == {"x": 3e-6, "y": 4e-6}
    (tmp_path / "trained.json").write_text("{not json")
    assert recorded_validation_sigma(tmp_path) == {"x": 3e-6, "y": 4e-6}
