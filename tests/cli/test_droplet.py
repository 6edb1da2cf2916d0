from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app

runner = CliRunner()


def test_simulate_writes_report_and_json(tmp_path: Path) -> None:
    out = tmp_path / "rep"
    js = tmp_path / "d.json"
    res = runner.invoke(
        app,
        [
            "droplet",
            "simulate",
            "--concentration",
            "0.15",
            "--duration",
            "70",
            "--out",
            str(out),
            "--json",
            str(js),
        ],
    )
    assert res.exit_code == 0, res.output
    data = json.loads(js.read_text())
    for key in ("breakup_time_s", "breakup_mode", "breakup_z_m", "satellites", "head_speed_m_s"):
        assert key in data
    assert (out / "nozzle_flow.png").stat().st_size > 0
    assert (out / "silhouettes.png").stat().st_size > 0


def test_simulate_refuses_bad_input() -> None:
    res = runner.invoke(app, ["droplet", "simulate", "--concentration", "-1"])
    assert res.exit_code == 2 and "outside the allowed range [0, 2] % w/v" in res.output
    res = runner.invoke(app, ["droplet", "simulate", "--voltage", "90"])
    assert res.exit_code == 2 and "[40, 70] V" in res.output


@pytest.mark.parametrize(
    "argv, says",
    [
        (["--after-breakup", "inf"], "allowed: [1, 5000] µs"),
        (["--duration", "1e308"], "outside the allowed range [1, 5000] µs"),
        (["--duration", "1e-300"], "outside the allowed range [1, 5000] µs"),
        (["--duration", "1e9"], "--duration"),  # was a MemoryError (149 GiB)
        (["--duration", "5e-324"], "--duration"),  # 0 s once in seconds: a ValueError
        (["--duration", "nan"], "--duration"),
        (["--after-breakup", "-1"], "--after-breakup"),
        (["--concentration", "nan"], "--concentration"),
        (["--voltage", "nan"], "--voltage"),
    ],
)
def test_simulate_refuses_out_of_range_parameters_on_one_line(
    tmp_path: Path, argv: list[str], says: str
) -> None:
    # issue 13: --after-breakup inf was a ValueError and --duration 1e308 an OverflowError
    out = tmp_path / "rep"
    base = [] if "--duration" in argv else ["--duration", "1"]  # an option is given once
    res = runner.invoke(app, ["droplet", "simulate", *base, *argv, "--out", str(out)])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], res.output
    assert not out.exists()


def test_analyze_errors(tmp_path: Path) -> None:
    from microfab.measure.shadowgraph import Camera, write_frames

    res = runner.invoke(app, ["droplet", "analyze", str(tmp_path)])
    assert res.exit_code == 2
    cam = Camera(width_px=40, height_px=60)
    frames = np.full((2, 60, 40), 0.85)
    frames[:, :20, 10:30] = 0.1
    write_frames(frames, tmp_path / "f", camera=cam, frame_interval_s=1e-5)
    (tmp_path / "f" / "frames.json").unlink()
    # issue 13: the hints speak the CLI's option names and units, not Python's
    res = runner.invoke(app, ["droplet", "analyze", str(tmp_path / "f")])
    assert res.exit_code == 2 and "error: --pixel-size is required (µm)" in res.output
    assert "pixel_size_m=" not in res.output
    res = runner.invoke(app, ["droplet", "analyze", str(tmp_path / "f"), "--pixel-size", "2"])
    assert res.exit_code == 2 and "error: --frame-interval is required (µs)" in res.output
    for opt, value, says in (
        ("--pixel-size", "-1", "outside the allowed range [0.1, 100] µm"),
        ("--frame-interval", "-1", "outside the allowed range [0.1, 1000] µs"),
        # issue 32: an OverflowError traceback, and a negative row recorded as given
        ("--pixel-size", "1e308", "outside the allowed range [0.1, 100] µm"),
        ("--frame-interval", "1e-300", "outside the allowed range [0.1, 1000] µs"),
        ("--nozzle-row", "-1", "outside the allowed range [0, 100000] px"),
    ):
        res = runner.invoke(app, ["droplet", "analyze", str(tmp_path / "f"), opt, value])
        assert res.exit_code == 2 and f"'{opt}'" in res.output and says in res.output, res.output


def test_sweep_writes_figure_and_resumable_results(tmp_path: Path) -> None:
    out = tmp_path / "sw"
    args = ["droplet", "sweep", "--concentrations", "0.15", "--voltages", "", "--duration", "60"]
    res = runner.invoke(app, [*args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    saved = json.loads((out / "sweep.json").read_text())
    assert [r["concentration_pct"] for r in saved["rows"]] == [0.15]
    assert (out / "breakup_time.png").stat().st_size > 0
    res = runner.invoke(app, [*args[:-1], "80", "--out", str(out)])
    assert res.exit_code == 2 and "settings" in res.output


def test_sweep_refuses_bad_input(tmp_path: Path) -> None:
    for extra in (
        ["--voltages", "30"],
        ["--concentrations", "-1"],
        ["--concentrations", "a"],
        ["--jobs", "0"],
    ):
        res = runner.invoke(app, ["droplet", "sweep", *extra, "--out", str(tmp_path)])
        assert res.exit_code == 2, (extra, res.output)


@pytest.mark.parametrize(
    "model",
    [
        "lagrangian",
        pytest.param(
            "eulerian",
            marks=pytest.mark.xfail(
                raises=AssertionError,
                strict=True,
                reason="by design: the Eulerian 0.15 % thread breaks at the retracted meniscus, "
                "90 µm inside the bore, where the camera outside the nozzle cannot see it",
            ),
        ),
    ],
)
def test_render_writes_frames_that_analyze_reads(tmp_path: Path, model: str) -> None:
    frames = tmp_path / "frames"
    res = runner.invoke(
        app,
        ["droplet", "render", str(frames), "--concentration", "0.15", "--model", model,
         "--duration", "150"],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert (frames / "frames.json").is_file()
    res = runner.invoke(
        app, ["droplet", "analyze", str(frames), "--json", str(tmp_path / "a.json")]
    )
    assert res.exit_code == 0, res.output
    measured = json.loads((tmp_path / "a.json").read_text())
    # both models break 0.15 % at the exit at 95-98 µs; frames every 10 µs see it by 100
    assert measured["breakup_mode"] == "exit"
    assert 90e-6 <= measured["breakup_time_s"] <= 110e-6
    for bad in (["--voltage", "30"], ["--frame-interval", "0"], ["--duration", "inf"],
                ["--model", "smooth"]):  # fmt: skip
        res = runner.invoke(app, ["droplet", "render", str(tmp_path / "x"), *bad])
        assert res.exit_code == 2, (bad, res.output)
        assert not (tmp_path / "x").exists()


def test_simulate_prints_its_summary_with_json_too(tmp_path: Path) -> None:
    res = runner.invoke(
        app,
        [
            "droplet",
            "simulate",
            "--concentration",
            "0.15",
            "--duration",
            "120",
            "--out",
            str(tmp_path / "r"),
            "--json",
            str(tmp_path / "d.json"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert '"breakup_time_s"' in res.output and (tmp_path / "d.json").is_file()
    # issue 19: one point, one answer, whichever command runs it
    from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point

    row = run_point(SweepPoint(0.15, 50.0), DropletSettings(duration_s=120e-6)).to_dict()
    data = json.loads((tmp_path / "d.json").read_text())
    assert data == json.loads(json.dumps(row, default=float))


def test_analyze_of_noise_says_no_jet_found(tmp_path: Path) -> None:
    # issue 13: exit 0 with breakup_time_s 0.0
    from microfab.measure.shadowgraph import Camera, write_frames

    noise = np.random.default_rng(0).random((6, 120, 80))
    write_frames(
        noise, tmp_path / "f", camera=Camera(width_px=80, height_px=120), frame_interval_s=1e-5
    )
    res = runner.invoke(app, ["droplet", "analyze", str(tmp_path / "f")])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: no jet found"), res.output


def test_calibrate_refuses_a_missing_table_before_running(tmp_path: Path) -> None:
    res = runner.invoke(
        app, ["droplet", "calibrate", "--model", "eulerian", "--write", str(tmp_path / "no.toml")]
    )
    assert res.exit_code == 2
    assert res.output.strip().startswith("error: --write") and not (tmp_path / "no.toml").exists()
    res = runner.invoke(app, ["droplet", "calibrate", "--model", "smooth"])
    assert res.exit_code == 2 and "is not one of lagrangian, eulerian" in res.output


def test_calibrate_refusals_leave_the_table(tmp_path: Path) -> None:
    """Refused on one line before any run (a run on the core is tested on the library:
    tests/machines/printhead/test_calibration.py; one through the CLI costs 15 s more)."""
    from importlib import resources

    table = tmp_path / "naalg.toml"
    text = (resources.files("microfab.data") / "naalg.toml").read_text(encoding="utf-8")
    table.write_text(text.replace("exponent_source", "exponent_note"), encoding="utf-8")
    for argv, msg in (
        (["--write", str(table)], "error: --write"),  # no sourced exponent to update
        (["--mode-fit", "--write", str(table)], "error: --mode-fit is a diagnostic"),
        (["--budget", "5"], "error: budget 5 is below one population"),
        (["--duration", "5"], "error: Invalid value for '--duration'"),
    ):
        res = runner.invoke(app, ["droplet", "calibrate", *argv])
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert res.exit_code == 2 and len(lines) == 1, res.output
        assert lines[0].startswith(msg), res.output
    assert "exponent_note" in table.read_text(encoding="utf-8")


def test_every_model_option_defaults_to_the_one_constant() -> None:
    import typer.main

    from microfab.cli.droplet import droplet_app
    from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL

    group = typer.main.get_command(droplet_app)
    with_model = {
        name: param
        for name, cmd in group.commands.items()  # type: ignore[attr-defined]
        for param in cmd.params
        if param.name == "model"
    }
    # the commands that run the jet model (guards against a command dropping out unseen)
    assert {"simulate", "render", "sweep"} <= set(with_model)
    for name, param in with_model.items():
        assert param.default == DEFAULT_JET_MODEL, name
        assert f"(default: {DEFAULT_JET_MODEL})" in (param.help or ""), name
