"""The networks' generations on the twin (seed 002 §III-C.2, Fig. 7), on a small setting.

Tiny networks (`tiny_models`, trained on another plant: poor models of the twin), 10 s of
generation-1 data, two small shapes at one a_max, two stage-2 iterations, two epochs per
retraining: the loop's mechanics, not the seed's numbers.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("casadi")
torch = pytest.importorskip("torch")

from microfab.identify import stage_ann  # noqa: E402
from microfab.identify.ann_data import data_digest  # noqa: E402
from microfab.identify.ann_train import init_digest  # noqa: E402
from microfab.identify.stage_ann import read_ann_stage_model, runs_of  # noqa: E402
from microfab.identify.stage_data import StageRecord  # noqa: E402
from microfab.io.runstore import RunRefusedError  # noqa: E402
from microfab.machines.xy_stage import generations as gen  # noqa: E402
from microfab.machines.xy_stage.ann import AnnSettings, ann_records  # noqa: E402


def small_settings(models_dir, **kw) -> gen.GenerationSettings:
    base = dict(models_dir=str(models_dir), ann=AnnSettings(total_s=10.0),
                shapes=("circle", "square"), size_m=3e-3, a_max=(2.0,), tolerance_m=100e-6,
                stage2_max_iter=2, retrain_epochs=2, count=2)  # fmt: skip
    return gen.GenerationSettings(**{**base, **kw})


@pytest.fixture(scope="module")
def done(tiny_models, tmp_path_factory):
    d, _ = tiny_models
    folder = tmp_path_factory.mktemp("gens")
    st = small_settings(d)
    return st, folder, gen.run_generations(st, folder)


def test_each_generation_is_optimised_played_and_scored(done):
    _, folder, res = done
    assert [g.index for g in res.generations] == [1, 2]
    for g in res.generations:
        assert all("error" not in p for p in g.points), g.points
        assert [(p["shape"], p["a_max"]) for p in g.points] == [("circle", 2.0), ("square", 2.0)]
        for p in g.points:
            assert 0 < p["twin"]["l2"] <= p["twin"]["linf"]
            assert p["network_error"]["x"]["sigma_um"] > 0
        assert set(g.network_error) == {"x", "y"}
        assert g.network_error["y"]["n"] == sum(p["network_error"]["y"]["n"] for p in g.points)
        assert 0 < g.twin["l2_m"] <= g.twin["linf_m"]
        assert g.twin["linf_m"] == max(p["twin"]["linf"] for p in g.points)
        assert (folder / f"gen{g.index}" / "generation.json").is_file()
    g1, g2 = res.generations
    assert g1.training is None and g2.training["epochs"] == {"x": 2, "y": 2}
    assert g2.models_dir == str(folder / "gen2" / "models")
    assert (folder / "gen2" / "models" / "linear_model.json").is_file()
    # the networks' error is measured: it changes when the networks do
    assert g1.network_error["x"]["sigma_um"] != g2.network_error["x"]["sigma_um"]


def test_second_generation_trains_on_the_first_data_and_the_new_runs(done, tiny_models):
    st, folder, res = done
    _, first = tiny_models
    g1 = res.generations[0]
    train0, val0 = ann_records(st.ann)
    with np.load(folder / "gen1" / "runs.npz") as z:
        runs = {f"gen1_{s}_a2": StageRecord(name="", u=z[f"u_{k}"], y=z[f"y_{k}"])
                for k, s in enumerate(("circle", "square"))}  # fmt: skip
    assert len(g1.split["train"]) == 1 and len(g1.split["validation"]) == 1  # 80/20 of two
    train = train0.records + [runs[n] for n in g1.split["train"]]
    val = val0.records + [runs[n] for n in g1.split["validation"]]
    model = read_ann_stage_model(folder / "gen2" / "models" / "ann" / "model").model
    assert model.info["train_digest"] == data_digest(runs_of(train))
    assert model.info["val_digest"] == data_digest(runs_of(val))
    assert model.info["init_digest"] == init_digest(first)  # warm: from generation 1
    # the rate continues where generation 1's training ended (4 epochs in tiny_models)
    c = first.config
    assert gen.continued_rate(first) == pytest.approx(c.learning_rate * c.lr_decay**4)
    assert model.config.learning_rate == pytest.approx(gen.continued_rate(first))
    assert model.config.learning_rate < c.learning_rate
    t = res.generations[1].training
    assert (t["train_runs"], t["validation_runs"]) == (len(train), len(val))
    assert t["start_data_matches"] is False  # tiny_models never saw the twin


def test_a_rerun_skips_finished_generations(done, monkeypatch):
    st, folder, res = done

    def boom(*a, **k):
        raise AssertionError("a finished generation was run again")

    monkeypatch.setattr(gen.xy_stage_reference, "run_point", boom)
    monkeypatch.setattr(stage_ann, "train_stage_ann", boom)
    again = gen.run_generations(st, folder)
    for a, b in zip(again.generations, res.generations, strict=True):
        assert a.points == b.points and a.network_error == b.network_error
        assert a.training == b.training
    # one more generation runs only what is new: the third's retraining comes first
    with pytest.raises(AssertionError, match="run again"):
        gen.run_generations(small_settings(st.models_dir, count=3), folder)


def test_an_interrupted_retraining_resumes_from_its_checkpoints(done, tmp_path, monkeypatch):
    st, folder, _ = done
    copy = tmp_path / "gens"
    shutil.copytree(folder, copy)
    w = (copy / "gen2" / "models" / "ann" / "model" / "weights.npz").read_bytes()
    (copy / "gen2" / "training.json").unlink()  # as if stopped before the models were saved
    shutil.rmtree(copy / "gen2" / "models")
    epochs = []
    real = stage_ann.train_stage_ann

    def counted(*a, **k):
        k["progress"] = epochs.append
        return real(*a, **k)

    monkeypatch.setattr(stage_ann, "train_stage_ann", counted)
    again = gen.run_generations(st, copy)
    assert epochs == []  # both axes were finished in the checkpoints: no epoch rerun
    assert (copy / "gen2" / "models" / "ann" / "model" / "weights.npz").read_bytes() == w
    assert again.generations[1].training["epochs"] == {"x": 2, "y": 2}


def test_other_settings_in_the_same_folder_refused(done):
    st, folder, _ = done
    before = {p: p.read_bytes() for p in folder.rglob("*.json")}
    with pytest.raises(RunRefusedError, match=r"a_max \[2\.0\] -> \[1\.0\]"):
        gen.run_generations(small_settings(st.models_dir, a_max=(1.0,)), folder)
    with pytest.raises(RunRefusedError, match="retrain_epochs 2 -> 3"):
        gen.run_generations(small_settings(st.models_dir, retrain_epochs=3), folder)
    assert {p: p.read_bytes() for p in folder.rglob("*.json")} == before


def test_settings_refused():
    with pytest.raises(ValueError, match="shapes must be"):
        gen.GenerationSettings(shapes=("letter",))
    with pytest.raises(ValueError, match="size must lie"):
        gen.GenerationSettings(size_m=0.5)
    with pytest.raises(ValueError, match="count"):
        gen.GenerationSettings(count=0)
    shapes = gen.regular_shapes(gen.DEFAULT_SHAPES, 20e-3)
    for p in shapes.values():  # inside Table I's workspace, about the origin
        assert max(abs(v) for v in p.bbox) <= 20e-3 + 1e-9
