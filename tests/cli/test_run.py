"""``microfab kinds`` and ``microfab run`` over the registry (the msl-ilc runs are in test_main)."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from microfab.cli import app

runner = CliRunner()


def test_kinds_lists_every_kind_and_reproduction() -> None:
    res = runner.invoke(app, ["kinds"])
    assert res.exit_code == 0, res.output
    for name in ("msl-ilc", "droplet-sweep", "droplet-fig4", "examples/droplet_sweep.toml"):
        assert name in res.output


def test_run_droplet_sweep_job(tmp_path: Path) -> None:
    job = tmp_path / "j.toml"
    job.write_text(
        '[job]\nkind = "droplet-sweep"\n[sweep]\nconcentrations_pct = [0.15]\n'
        "voltages_v = []\nduration_us = 120\n",
        encoding="utf-8",
    )
    res = runner.invoke(app, ["run", str(job), "--out", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output
    assert "First breakup at 50 V" in res.output
    assert (tmp_path / "r" / "report.html").exists()
    job.write_text(job.read_text().replace("120", "150"), encoding="utf-8")
    res = runner.invoke(app, ["run", str(job), "--out", str(tmp_path / "r")])
    assert res.exit_code == 2
    assert "other settings" in res.output and "Traceback" not in res.output


def test_run_check_reads_the_job_and_runs_nothing(tmp_path: Path) -> None:
    job = tmp_path / "j.toml"
    job.write_text('[job]\nkind = "msl-ilc"\nout = "rep"\n[scan]\niterations = 5\n')
    res = runner.invoke(app, ["run", str(job), "--check"])
    assert res.exit_code == 0, res.output
    assert "a valid msl-ilc job" in res.output and "rep" in res.output
    assert list(tmp_path.iterdir()) == [job]
    job.write_text("[scan]\niterations = 2.7\n")
    res = runner.invoke(app, ["run", str(job), "--check"])
    assert res.exit_code == 2 and "expected an integer" in res.output


def test_check_refuses_a_reference_job_without_its_models(tmp_path) -> None:
    """Issue 32: `run --check` called blackbox_stage_reference.toml valid, running it refused."""
    from pathlib import Path

    from typer.testing import CliRunner

    from microfab.cli import app

    example = Path(__file__).parents[2] / "examples" / "blackbox_stage_reference.toml"
    job = tmp_path / "j.toml"
    text = example.read_text(encoding="utf-8")
    job.write_text(text.replace('dir = "builtin"', f'dir = "{tmp_path / "none"}"', 1))
    assert str(tmp_path / "none") in job.read_text()
    for extra in (["--check"], []):
        res = CliRunner().invoke(app, ["run", str(job), *extra, "--out", str(tmp_path / "o")])
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert res.exit_code == 2 and len(lines) == 1, res.output
        assert "does not exist; run `microfab run examples/blackbox_stage_identify" in lines[0]
    assert not (tmp_path / "o").exists()


def _reproduce(tmp_path: Path, *args: str) -> tuple[int, str]:
    import os

    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        res = runner.invoke(app, ["reproduce", *args])
    finally:
        os.chdir(cwd)
    return res.exit_code, res.output


def test_reproduce_check_runs_nothing_and_writes_nothing(tmp_path: Path) -> None:
    code, out = _reproduce(tmp_path, "stage-models", "--set", "checkpoints=cp", "--check")
    assert code == 0, out
    assert "valid settings" in out and "cp" in out
    assert list(tmp_path.iterdir()) == []


def test_reproduce_check_refuses_what_a_run_would_refuse(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("kept\n")
    (tmp_path / "models").mkdir()
    cases = {
        ("reference-opt", "--set", "models=nowhere"): "does not exist",
        ("stage-models", "--set", "checkpoints=afile"): "is a file",
        ("stage-models", "--set", "magnitudes=foo"): "magnitudes",
        ("msl-ilc", "--set", "seed=-1"): "seed",
        ("reference-opt", "--set", "models=models", "--set", "checkpoints=models"): "input",
        # issue 44 D: a repeated key kept the last value silently
        ("msl-ilc", "--set", "iterations=3", "--set", "iterations=5"): "given twice",
    }
    for args, words in cases.items():
        for check in ((), ("--check",)):
            code, out = _reproduce(tmp_path, *args, *check)
            assert code == 2 and words in out and len(out.splitlines()) == 1, (args, out)
    assert (tmp_path / "afile").read_text() == "kept\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "models"]
