"""Option rules of ``droplet``, ``nanomanipulator analyze`` and ``laser analyze`` (issue 44).

Causes C and D: every number is declared with its unit and range and refused while the
command line is parsed; an option the chosen mode does not use is refused, not ignored;
options that contradict each other or the input are refused naming both, before any
work. Each refusal is one ``error:`` line, exit code 2, and nothing is written. The shared
declarations are the job keys of `microfab.experiments.seed003_inkjet.keys`,
`microfab.experiments.seed001_nanomanipulator.keys` and
`microfab.experiments.seed004_laser.keys`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli._options import declared
from microfab.experiments.seed001_nanomanipulator import keys as nano_keys
from microfab.experiments.seed003_inkjet import keys as ink_keys
from microfab.experiments.seed004_laser import keys as laser_keys

runner = CliRunner()

SIM = ("droplet", "simulate")
RENDER = ("droplet", "render")
ANALYZE = ("droplet", "analyze")
SWEEP = ("droplet", "sweep", "--concentrations", "0.15", "--voltages", "50")
SENS = ("droplet", "sensitivity", "--concentrations", "0.15")
NANO = ("nanomanipulator", "analyze")
LASER = ("laser", "analyze", "--drawing", "circle:radius=30e-6")

Refused = Callable[..., None]


@pytest.fixture
def refused(tmp_path: Path, one_error_line: Callable[[Any, str], None]) -> Refused:
    """Run a command line with its outputs and inputs in ``tmp_path``; check the refusal.

    Every command gets its output options pointed into ``tmp_path`` and, where it reads a
    file, a junk input there (an option refused first never reads it); afterwards the
    folder must hold exactly what it held before.
    """
    trace = tmp_path / "t.csv"
    trace.write_text("junk\n")
    (tmp_path / "frames").mkdir()

    def run(argv: tuple[str, ...], says: str, *more: str) -> None:
        words = list(argv)
        head = tuple(words[:2])
        if head == SIM:
            words += ["--out", str(tmp_path / "o"), "--json", str(tmp_path / "o.json")]
        elif head == RENDER:
            words.insert(2, str(tmp_path / "rendered"))
        elif head == ANALYZE:
            words.insert(2, str(tmp_path / "frames"))
            words += ["--json", str(tmp_path / "o.json")]
        elif head in (SWEEP[:2], SENS[:2]):
            words += ["--out", str(tmp_path / "o")]
        elif head in (NANO, LASER[:2]):
            words.insert(2, str(trace))
            words += ["--out", str(tmp_path / "o"), "--json", str(tmp_path / "o.json")]
        before = sorted((p, p.stat().st_mtime_ns) for p in tmp_path.rglob("*"))
        res = runner.invoke(app, words)
        one_error_line(res, says)
        assert all(m in res.output for m in more), res.output
        assert sorted((p, p.stat().st_mtime_ns) for p in tmp_path.rglob("*")) == before

    return run


# ------------------------------------------------------------------ ranges, at parse time
@pytest.mark.parametrize(
    "argv, says",
    [
        # seed 003: the NaAlg table ends at 2 %, the model is calibrated for 40-70 V
        ((*SIM, "--concentration", "2.5"), "2.5 % w/v is outside the allowed range [0, 2]"),
        ((*SIM, "--voltage", "39"), "39 V is outside the allowed range [40, 70] V"),
        ((*SIM, "--duration", "0.5"), "0.5 µs is outside the allowed range [1, 5000] µs"),
        # was accepted: 0.5 µs after breakup is less than one frame of any camera here
        ((*SIM, "--after-breakup", "0.5"), "0.5 µs is outside the allowed range [1, 5000]"),
        ((*SIM, "--after-breakup", "6000"), "--after-breakup"),
        ((*RENDER, "--concentration", "-0.1"), "--concentration"),
        ((*RENDER, "--duration", "6000"), "6000 µs is outside the allowed range [10, 5000] µs"),
        ((*RENDER, "--frame-interval", "2000"), "--frame-interval"),
        ((*RENDER, "--pixel-size", "0.05"), "0.05 µm is outside the allowed range [0.1, 100]"),
        ((*RENDER, "--seed", "-1"), "--seed"),
        ((*RENDER, "--voltage", "nan"), "nan is not a finite number"),
        ((*ANALYZE, "--pixel-size", "200"), "--pixel-size"),
        ((*ANALYZE, "--frame-interval", "0.01"), "--frame-interval"),
        ((*ANALYZE, "--nozzle-row", "100001"), "100001 px is outside the allowed range"),
        ((*SWEEP, "--duration", "5"), "5 µs is outside the allowed range [10, 5000] µs"),
        ((*SWEEP, "--voltage-concentration", "2.5"), "--voltage-concentration"),
        ((*SWEEP, "--jobs", "0"), "--jobs"),
        ((*SWEEP, "--workers", "257"), "'--jobs' / '--workers': 257 is outside"),
        ((*SENS, "--jobs", "0"), "0 is outside the allowed range [1, 256]"),
        # seed 001: the pattern's keys; ±1.5 mm of travel, times and counts assumed
        ((*NANO, "--circles", "101"), "101 circles is outside the allowed range [1, 100]"),
        ((*NANO, "--period", "0"), "0 s is outside the allowed range (0, 60] s"),
        ((*NANO, "--period", "61"), "--period"),
        ((*NANO, "--diameter-mm", "4"), "4 mm is outside the allowed range (0, 3] mm"),
        ((*NANO, "--field-mm", "0"), "--field-mm"),
        ((*NANO, "--periods", "1001"), "--periods"),
        ((*NANO, "--pause-s", "0"), "--pause-s"),
        ((*NANO, "--move-s", "61"), "--move-s"),
        ((*NANO, "--ramp-s", "-1"), "--ramp-s"),
        ((*NANO, "--sample-rate-hz", "50"), "50 Hz is outside the allowed range [100, 1e+06]"),
        ((*NANO, "--sample-rate-hz", "2e6"), "--sample-rate-hz"),
        # seed 004: contours count from 0; a tolerance below the 10 nm resolution or of mm
        ((*LASER, "--contour", "-1"), "-1 is outside the allowed range [0, inf)"),
        ((*LASER, "--reference-tol-um", "0.001"), "outside the allowed range [0.01, 1000] µm"),
        ((*LASER, "--reference-tol-um", "2000"), "--reference-tol-um"),
    ],
)
def test_a_number_outside_its_range_is_refused_at_parse_time(
    refused: Refused, argv: tuple[str, ...], says: str
) -> None:
    # the option's name and its declared range (click's own min/max said neither unit nor
    # "allowed", check_option in the body said "must be")
    refused(argv, says, f"'{argv[-2]}'", "allowed")


# --------------------------------------------------------------- options the mode ignores
@pytest.mark.parametrize(
    "argv, says",
    [
        # no voltage series: its concentration would be parsed and dropped
        (
            ("droplet", "sweep", "--voltages", "", "--voltage-concentration", "0.5"),
            "--voltage-concentration has no effect with --voltages ''",
        ),
        # on a scheduler its workers run the points; --jobs sized a local cluster
        (
            (*SWEEP, "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"),
            "--jobs has no effect with --scheduler",
        ),
    ],
)
def test_an_option_the_mode_does_not_use_is_refused(
    refused: Refused, argv: tuple[str, ...], says: str
) -> None:
    refused(argv, says)


def test_pattern_options_beside_a_job_are_refused(refused: Refused, tmp_path: Path) -> None:
    job = tmp_path / "job.toml"
    job.write_text('[job]\nkind = "nanomanipulator-msl"\n[pattern]\nperiods = 4\n')
    refused((*NANO, "--job", str(job), "--ramp-s", "0.1"), "--ramp-s has no effect with --job")


# ------------------------------------------------------------- options against each other
@pytest.mark.parametrize(
    "argv, says",
    [
        # the bodies cannot be followed 20 µs after a breakup in a 10 µs simulation
        ((*SIM, "--duration", "10", "--after-breakup", "20"), "--after-breakup 20 µs is not"),
        # one frame at most: no speed to measure
        ((*RENDER, "--duration", "100", "--frame-interval", "500"), "--frame-interval 500 µs"),
        # 2000 frames of float64, past what one render writes
        ((*RENDER, "--duration", "200", "--frame-interval", "0.1"), "2000 frames"),
        # circles of 0.15 mm (the default) do not fit a 0.1 mm field
        ((*NANO, "--field-mm", "0.1"), "--field-mm 0.1 mm is smaller than --diameter-mm 0.15"),
        # 500.5 samples per period at 10 kHz (was read first, then refused after the trace)
        (
            (*NANO, "--period", "0.05005", "--sample-rate-hz", "10000"),
            "--period 0.05005 s is 500.5 samples at --sample-rate-hz 10000 Hz",
        ),
        # the drawing has one contour: refused before the trace is read
        ((*LASER, "--contour", "3"), "contour = 3 does not exist"),
    ],
)
def test_options_that_contradict_each_other_are_refused_naming_both(
    refused: Refused, argv: tuple[str, ...], says: str
) -> None:
    refused(argv, says)


def test_the_period_of_a_job_that_is_not_whole_samples_names_the_job(
    refused: Refused, tmp_path: Path
) -> None:
    job = tmp_path / "job.toml"
    job.write_text('[job]\nkind = "nanomanipulator-msl"\n[pattern]\nperiod_s = 0.05005\n')
    refused((*NANO, "--job", str(job), "--sample-rate-hz", "10000"), "[pattern] period_s 0.05005")


def test_a_render_larger_than_the_memory_budget_is_refused_before_rendering(
    tmp_path: Path, one_error_line: Callable[[Any, str], None], monkeypatch: pytest.MonkeyPatch
) -> None:
    from microfab.cli import droplet

    # the fuzz recipe's cheap render (a few frames) against a 1 kB budget
    monkeypatch.setattr(droplet, "MAX_RENDER_BYTES", 1e3)
    out = tmp_path / "r"
    res = runner.invoke(
        app, [*RENDER, str(out), "--duration", "100", "--frame-interval", "25", "--model",
              "eulerian"],
    )  # fmt: skip
    one_error_line(res, "would take")
    assert "--pixel-size" in res.output and not (out / "frames.json").exists()


# -------------------------------------------------------------- options against the input
@pytest.fixture
def frames(tmp_path: Path) -> Path:
    """Two small frames whose frames.json says 2 µm pixels and 10 µs between frames."""
    from microfab.measure.shadowgraph import Camera, write_frames

    frames = np.full((2, 60, 40), 0.85)
    frames[:, :20, 10:30] = 0.1
    folder = tmp_path / "f"
    write_frames(frames, folder, camera=Camera(width_px=40, height_px=60), frame_interval_s=1e-5)
    return folder


@pytest.mark.parametrize(
    "option, value, says",
    [
        ("--pixel-size", "5", "--pixel-size 5 µm, but"),
        ("--frame-interval", "20", "--frame-interval 20 µs, but"),
    ],
)
def test_a_camera_option_that_contradicts_frames_json_is_refused(
    frames: Path,
    tmp_path: Path,
    one_error_line: Callable[[Any, str], None],
    option: str,
    value: str,
    says: str,
) -> None:
    out = tmp_path / "a.json"
    res = runner.invoke(app, [*ANALYZE, str(frames), option, value, "--json", str(out)])
    one_error_line(res, says)
    assert "frames.json" in res.output and not out.exists()
    # the value the file states is no contradiction
    same = "2" if option == "--pixel-size" else "10"
    res = runner.invoke(app, [*ANALYZE, str(frames), option, same, "--json", str(out)])
    assert ", but" not in res.output, res.output


# ------------------------------------------------------------------ shared declarations
def _params(*words: str) -> dict[str, Any]:
    cmd: Any = typer.main.get_command(app)
    for w in words:
        cmd = cmd.commands[w]
    return {p.name: p for p in cmd.params}


def test_options_share_the_job_keys() -> None:
    from microfab.experiments.seed001_nanomanipulator.job import SCHEMA as NANO_SCHEMA
    from microfab.experiments.seed003_inkjet.job import SCHEMA as INK_SCHEMA
    from microfab.experiments.seed004_laser.job import SCHEMA as LASER_SCHEMA

    pairs = [
        (("droplet", "sweep"), "duration", ink_keys.DURATION, INK_SCHEMA["sweep"]),
        (("droplet", "render"), "duration", ink_keys.DURATION, INK_SCHEMA["sweep"]),
        (("droplet", "simulate"), "after_breakup", ink_keys.AFTER_BREAKUP, INK_SCHEMA["sweep"]),
        (("droplet", "sweep"), "voltage_concentration", ink_keys.VOLTAGE_CONCENTRATION,
         INK_SCHEMA["sweep"]),
        (("droplet", "sweep"), "jobs", ink_keys.WORKERS, INK_SCHEMA["run"]),
        (("droplet", "sensitivity"), "jobs", ink_keys.WORKERS, INK_SCHEMA["run"]),
        (("laser", "analyze"), "contour", laser_keys.CONTOUR, LASER_SCHEMA["drawing"]),
        *(
            (("nanomanipulator", "analyze"), name, key, NANO_SCHEMA["pattern"])
            for name, key in (
                ("period", nano_keys.PATTERN_PERIOD_S),
                ("circles", nano_keys.PATTERN_N_CIRCLES),
                ("diameter_mm", nano_keys.PATTERN_DIAMETER_MM),
                ("field_mm", nano_keys.PATTERN_FIELD_MM),
                ("periods", nano_keys.PATTERN_PERIODS),
                ("pause_s", nano_keys.PATTERN_PAUSE_S),
                ("move_s", nano_keys.PATTERN_MOVE_S),
                ("ramp_s", nano_keys.PATTERN_RAMP_S),
            )
        ),
    ]  # fmt: skip
    for words, name, key, section in pairs:
        assert declared(_params(*words)[name]) is key, (words, name)
        assert any(k is key for k in section), (words, name, key.name)
    # the same quantity, range and unit as a job key, element by element
    for words, name, key, like in [
        (("droplet", "simulate"), "concentration", ink_keys.CONCENTRATION, "concentrations_pct"),
        (("droplet", "render"), "voltage", ink_keys.VOLTAGE, "voltages_v"),
    ]:
        assert declared(_params(*words)[name]) is key
        job_key = next(k for k in INK_SCHEMA["sweep"] if k.name == like)
        assert (job_key.low, job_key.high, job_key.unit) == (key.low, key.high, key.unit)


def test_restated_bounds_agree_with_their_sources() -> None:
    from microfab.cli import droplet
    from microfab.machines.printhead.machine import limits
    from microfab.measure import frames
    from microfab.trajectory import circle_pattern
    from microfab.trajectory.circle_pattern import PatternConfig

    assert ink_keys.VOLTAGE_RANGE_V == limits().voltage_v
    # µm and µs against m and s: the conversion of a decimal changes the last bits only
    np.testing.assert_allclose(np.array(droplet._PIXEL_RANGE_UM) * 1e-6,
                               frames.PIXEL_SIZE_RANGE_M, rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(np.array(droplet._INTERVAL_RANGE_US) * 1e-6,
                               frames.FRAME_INTERVAL_RANGE_S, rtol=1e-12)  # fmt: skip
    for name in ("N_CIRCLES", "CIRCLE_DIAMETER_MM", "FIELD_MM", "TRAVEL_MM"):
        assert getattr(nano_keys, name) == getattr(circle_pattern, name), name
    defaults = {k.name: k.default for k in nano_keys.PATTERN_KEYS}
    assert defaults == dataclasses.asdict(PatternConfig())
