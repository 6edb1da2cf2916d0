"""``microfab identify ann`` and ``identify validate`` on a network model (seed 002 eq. 7)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.trace import write_columns

torch = pytest.importorskip("torch")

runner = CliRunner()

DT = 1 / 2000  # tiny runs: 2 kHz (5 samples per 400 Hz step) keeps the windows few
N = 1400  # 0.7 s, above the 500 ms history


def _run(path: Path, seed: int, n: int = N, dt: float = DT, **kw) -> str:
    """A smooth set-point pair from rest and a lagged, noisy 'measurement' of it, m."""
    rng = np.random.default_rng(seed)
    u = 0.01 * np.cumsum(np.cumsum(rng.standard_normal((n, 2)), axis=0), axis=0) / n**1.5
    u -= u[0]
    y = np.vstack([u[:1], u[:-1]]) + 1e-6 * rng.standard_normal(u.shape)
    cols = {
        "time": np.arange(n) * dt,
        "input_x": u[:, 0], "input_y": u[:, 1], "output_x": y[:, 0], "output_y": y[:, 1],
    }  # fmt: skip
    cols.update(kw)
    write_columns(path, {k: v for k, v in cols.items() if v is not None}, unit="m")
    return str(path)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> list[str]:
    d = tmp_path_factory.mktemp("ann_runs")
    return [_run(d / f"r{i}.csv", i) for i in range(5)]


def _ann(runs: list[str], out: Path, *extra: str):
    device = [] if "--device" in extra else ["--device", "cpu"]
    return runner.invoke(app, ["identify", "ann", *runs, "--out", str(out), *device, *extra])


def _val_sigma(output: str) -> list[float]:
    """σ [µm] per axis of the 'Non-linear' rows (the plain tab-separated table)."""
    rows = re.findall(r"^Non-linear\t([xy])\t(\S+)\t(\S+)", output, flags=re.M)
    return [float(s) for _, _, s in rows]


def test_train_resume_restart_validate(runs, tmp_path):
    out = tmp_path / "model"
    res = _ann(runs, out, "--epochs", "2", "--axis", "both")
    assert res.exit_code == 0, res.output
    assert (out / "model.json").is_file() and (out / "weights.npz").is_file()
    ck = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert ck == ["ann_x.ckpt.npz", "ann_y.ckpt.npz"]
    assert not [p for p in out.iterdir() if p.name.startswith(".model-")]
    meta = json.loads((out / "model.json").read_text())
    assert meta["axes"] == ["x", "y"] and meta["window"]["run_rate_hz"] == pytest.approx(2000)
    assert {a: s["epochs"] for a, s in meta["info"]["axes"].items()} == {"x": 2, "y": 2}
    val_names = meta["info"]["runs"]["validation"]
    assert len(val_names) == 1 and len(meta["info"]["runs"]["training"]) == 4  # 80/20
    assert "2 (1-2)" in res.output
    # the seed's ANN column beside ours (Table II: x 3.2, y 6.0 µm on validation)
    assert "3.2" in res.output and "6.0" in res.output
    sigma = _val_sigma(res.output)
    assert len(sigma) == 2 and all(s > 0 for s in sigma)
    # validate reads the directory and gives the same numbers on the validation run
    vjson = tmp_path / "v.json"
    res_v = runner.invoke(app, ["identify", "validate", str(out), *val_names, "--json", str(vjson)])
    assert res_v.exit_code == 0, res_v.output
    got = json.loads(vjson.read_text())
    assert got["kind"] == "ann" and got["axes"] == ["x", "y"]
    assert got["compared_at_hz"] == pytest.approx(2000.0) and got["n_samples"] == N
    np.testing.assert_allclose(got["sigma_um"], sigma, atol=0.051)  # printed to 0.1 µm
    assert "every run sample" in res_v.output
    weights = (out / "weights.npz").read_bytes()
    # the same command again: finished, so no epoch is redone; the same model is saved
    res = _ann(runs, out, "--epochs", "2", "--axis", "both")
    assert res.exit_code == 0, res.output
    assert res.output.count("none (finished before)") == 2, res.output
    assert (out / "weights.npz").read_bytes() == weights
    # a larger --epochs extends the finished training by the missing epochs only
    res = _ann(runs, out, "--epochs", "3", "--axis", "both")
    assert res.exit_code == 0, res.output
    assert res.output.count("3 (3-3)") == 2, res.output
    extended = (out / "weights.npz").read_bytes()
    # --restart starts over: epochs 1..2 again, the 2-epoch model back bit for bit (CPU)
    res = _ann(runs, out, "--epochs", "2", "--axis", "both", "--restart")
    assert res.exit_code == 0, res.output
    assert res.output.count("2 (1-2)") == 2, res.output
    assert (out / "weights.npz").read_bytes() == weights != extended


def test_interrupted_training_resumes(runs, tmp_path):
    """A checkpoint without a model (an interruption) is resumed, and validate refuses it."""
    out = tmp_path / "m"
    res = _ann(runs, out, "--epochs", "1", "--axis", "x")
    assert res.exit_code == 0, res.output
    (out / "model.json").unlink()
    (out / "weights.npz").unlink()
    res = runner.invoke(app, ["identify", "validate", str(out), runs[0]])
    assert res.exit_code == 2 and "run the same command again" in res.output, res.output
    res = _ann(runs, out, "--epochs", "2", "--axis", "x")
    assert res.exit_code == 0, res.output
    assert "2 (2-2)" in res.output and (out / "model.json").is_file()
    assert len(_val_sigma(res.output)) == 1


def test_refusals_write_nothing(runs, tmp_path, one_error_line):
    out = tmp_path / "m"
    d = tmp_path / "bad"
    d.mkdir()
    cases = [
        ([runs[0]], [], "give at least two runs"),
        (runs, ["--axis", "z"], "Invalid value for '--axis': 'z' is not one of x, y, both"),
        (runs, ["--validation", "1"], "'--validation': 1 is outside the allowed range (0, 0.9]"),
        (runs, ["--validation", "0"], "'--validation': 0 is outside the allowed range (0, 0.9]"),
        (
            runs,
            ["--device", "tpu"],
            "Invalid value for '--device': 'tpu' is not one of auto, cpu, cuda",
        ),
        ([runs[0], _run(d / "short.csv", 9, n=800)], [], "shorter than 500 ms"),
        ([runs[0], _run(d / "rate.csv", 9, dt=1 / 1800)], [], "not a whole multiple of 400"),
        ([runs[0], _run(d / "k.csv", 9, dt=1 / 1600)], [], "sampled at 1600 Hz"),
        ([runs[0], _run(d / "miss.csv", 9, output_y=None)], [], "'output_y'"),
    ]
    if not torch.cuda.is_available():
        cases.append((runs, ["--device", "cuda"], "no CUDA device"))
    for files, extra, says in cases:
        res = _ann(files, out, "--epochs", "1", *extra)
        one_error_line(res, says)
        assert not out.exists(), says
    f = tmp_path / "file"
    f.write_text("x")
    one_error_line(_ann(runs, f, "--epochs", "1"), "is a file")
    # a checkpoint of another training (another seed: split and weights) is refused
    res = _ann(runs, out, "--epochs", "1", "--axis", "x")
    assert res.exit_code == 0, res.output
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    one_error_line(_ann(runs, out, "--epochs", "1", "--axis", "x", "--seed", "3"), "--restart")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_validate_refuses_another_version_rate_or_history(runs, tmp_path, one_error_line):
    out = tmp_path / "m"
    res = _ann(runs, out, "--epochs", "1", "--axis", "y")
    assert res.exit_code == 0, res.output
    meta = json.loads((out / "model.json").read_text())
    vjson = tmp_path / "v.json"
    for change, says in [
        ({"format_version": 99}, "version 99"),
        ({"window": {**meta["window"], "rate_hz": 500.0, "run_rate_hz": 2000.0}}, "model rate"),
        ({"window": {**meta["window"], "h": 100}}, "history h"),
        ({"layers": [1, 2]}, "layers"),
    ]:
        bad = tmp_path / "bad"
        bad.mkdir(exist_ok=True)
        (bad / "weights.npz").write_bytes((out / "weights.npz").read_bytes())
        (bad / "model.json").write_text(json.dumps({**meta, **change}))
        res = runner.invoke(app, ["identify", "validate", str(bad), runs[0], "--json", str(vjson)])
        one_error_line(res, says)
        assert not vjson.exists()
    # a run at another rate than the model's runs
    other = _run(tmp_path / "r4k.csv", 1, n=2 * N, dt=1 / 4000)
    res = runner.invoke(app, ["identify", "validate", str(out), other, "--json", str(vjson)])
    one_error_line(res, "fitted to 2000 Hz runs")
    # a one-axis model reports its axis only
    res = runner.invoke(app, ["identify", "validate", str(out), runs[0], "--json", str(vjson)])
    assert res.exit_code == 0, res.output
    assert json.loads(vjson.read_text())["axes"] == ["y"]
