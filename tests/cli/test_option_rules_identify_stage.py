"""Option rules of ``identify``, ``stage`` and ``calibrate xy-stage`` (issue 44, causes C, D).

Every number these commands take is declared with its unit and range (`cli._options`), the
ones a ``stage-identify`` job key sets share that key, options that do nothing in the
chosen mode are refused, and rules between options (or between an option and the file)
are one ``error:`` line before any work. Each refusal: exit 2, one line, nothing written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli._options import declared
from microfab.experiments.seed002_stage import keys
from microfab.experiments.seed002_stage.job import SCHEMA
from microfab.identify.chirp import ChirpDesign
from microfab.io.trace import write_columns

runner = CliRunner()

# a short chirp, as tests/cli/test_identify.py: 20 Hz - 2 kHz in 50 ms at 100 kHz
DESIGN = ChirpDesign(f0_hz=20.0, f1_hz=2000.0, period_s=0.05, n_periods=3, n_dropped=1)
CHIRP = ["--f0", "20", "--f1", "2000", "--band", "20:2000"]


def _refused(argv: list[str], says: str, where: Path, one_error_line: Any) -> None:
    """``microfab argv`` is one ``error:`` line holding ``says`` and ``where`` stays as it was."""
    before = sorted(where.rglob("*"))
    res = runner.invoke(app, argv)
    one_error_line(res, says)
    assert sorted(where.rglob("*")) == before, argv


def _chirp_file(path: Path, n_periods: int = 3, noise: float = 0.0) -> Path:
    """A chirp record of ``n_periods`` sweeps of ``DESIGN`` (output: the input, delayed)."""
    u = np.tile(DESIGN.one_period(), n_periods)
    if noise:
        u = u + noise * u.std() * np.random.default_rng(1).standard_normal(u.size)
    cols = {"time": np.arange(u.size) * DESIGN.dt, "input_x": u, "output_x": np.roll(u, 3)}
    write_columns(path, cols, unit="bit")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    """Inputs the refusals name (read only after the refusals, so any content will do)."""
    d = tmp_path_factory.mktemp("inputs")
    runs = [d / "r0.csv", d / "r1.csv"]
    for r in runs:
        r.write_text("time,input_x\n0,0\n")
    return {
        "chirp": _chirp_file(d / "chirp.csv"),
        "chirp6": _chirp_file(d / "chirp6.csv", n_periods=6),
        "r0": runs[0],
        "r1": runs[1],
    }


# --- ranges: refused while the command line is parsed --------------------------------------
def _range_cases() -> list[tuple[str, list[str], str]]:
    chirp = ["identify", "chirp", "{chirp}", *CHIRP, "--json", "{out}/m.json"]
    ann = ["identify", "ann", "{r0}", "{r1}", "--out", "{out}/ann"]
    lin = ["identify", "linear", "{r0}", "--out", "{out}/m.json"]
    excite = ["stage", "excite", "--out", "{out}/ex"]
    play = ["stage", "play", "{r0}", "--out", "{out}/pl"]
    cal = ["calibrate", "xy-stage", "--json", "{out}/c.json"]
    return [
        # issue 44: a 100-sample "excitation" was written
        ("excite-duration", [*excite, "--duration", "0.01"], "'--duration': 0.01 s"),
        ("excite-duration-high", [*excite, "--duration", "4000"], "'--duration': 4000 s"),
        ("excite-amax", [*excite, "--amax", "0"], "'--amax': 0 m/s²"),
        # make fuzz: 1e-308 m/s² was accepted by an open bound at 0 (a run of noise)
        ("excite-amax-tiny", [*excite, "--amax", "1e-12"], "outside the allowed range [0.001,"),
        ("excite-amax-inf", [*excite, "--amax", "inf"], "'--amax': inf is not a finite"),
        ("play-hold", [*play, "--hold", "11"], "'--hold': 11 s"),
        ("play-seed", [*play, "--seed", "-1"], "'--seed': -1"),
        ("chirp-period", [*chirp, "--period", "0"], "'--period': 0 s"),
        ("chirp-period-high", [*chirp, "--period", "1e5"], "'--period': 100000 s"),
        ("chirp-f1", [*chirp[:3], "--f1", "1e9", "--json", "{out}/m.json"], "'--f1': 1e+09 Hz"),
        ("chirp-f0-nan", [*chirp[:3], "--f0", "nan", "--json", "{out}/m.json"], "'--f0': nan"),
        ("chirp-poles", [*chirp, "--poles", "21"], "'--poles': 21"),
        ("chirp-zeros", [*chirp, "--zeros", "-1"], "'--zeros': -1"),
        ("chirp-periods", [*chirp, "--periods", "0"], "'--periods': 0"),
        ("chirp-drop", [*chirp, "--drop", "20000"], "'--drop': 20000"),
        ("chirp-amplitude", [*chirp, "--amplitude", "-5"], "'--amplitude': -5"),
        ("chirp-coherence", [*chirp, "--min-coherence", "1.5"], "'--min-coherence': 1.5"),
        ("linear-order", [*lin, "--order", "31"], "'--order': 31"),
        ("linear-decimate", [*lin, "--decimate", "101"], "'--decimate': 101"),
        ("linear-block-rows", [*lin, "--block-rows", "1"], "'--block-rows': 1"),
        ("ann-epochs", [*ann, "--epochs", "10001"], "'--epochs': 10001"),
        ("ann-threads", [*ann, "--threads", "0"], "'--threads': 0"),
        ("ann-workers", [*ann, "--workers", "3"], "'--workers': 3"),
        ("ann-epoch-windows", [*ann, "--epoch-windows", "-1"], "'--epoch-windows': -1"),
        ("ann-validation", [*ann, "--validation", "0.95"], "'--validation': 0.95"),
        ("ann-seed", [*ann, "--seed", "-2"], "'--seed': -2"),
        ("ann-whiten", [*ann, "--whiten", "2"], "'--whiten': 2"),
        ("cal-duration", [*cal, "--duration", "0.1"], "'--duration': 0.1 s"),
        ("cal-ann-duration", [*cal, "--ann-duration", "0"], "'--ann-duration': 0 s"),
        ("cal-runs-seed", [*cal, "--runs-seed", "-1"], "'--runs-seed': -1"),
        ("cal-proxy-hidden", [*cal, "--proxy-hidden", "0"], "'--proxy-hidden': 0 units"),
        ("cal-proxy-offsets", [*cal, "--proxy-offsets", "26"], "'--proxy-offsets': 26"),
    ]


@pytest.mark.parametrize(("argv", "says"), [pytest.param(a, s, id=i) for i, a, s in _range_cases()])
def test_out_of_range_options_are_refused_before_any_work(
    files: dict[str, Path], tmp_path: Path, one_error_line, argv: list[str], says: str
):
    names = {k: str(v) for k, v in files.items()}
    argv = [a.format(out=tmp_path, **names) for a in argv]
    _refused(argv, says, tmp_path, one_error_line)
    res = runner.invoke(app, argv)
    assert "allowed range" in res.output or "not a finite number" in res.output


# --- shared declarations ------------------------------------------------------------------
def _param(words: tuple[str, ...], name: str) -> Any:
    cmd: Any = typer.main.get_command(app)
    for w in words:
        cmd = cmd.commands[w]
    return next(p for p in cmd.params if p.name == name)


#: (command, parameter, [section] of the stage-identify job, key)
SHARED = [
    (("stage", "excite"), "duration", "linear", "total_s"),
    (("stage", "excite"), "amax", "linear", "a_max"),
    (("stage", "excite"), "seed", "linear", "seed"),
    (("stage", "play"), "seed", "twin", "seed"),
    (("stage", "play"), "hold", "twin", "hold_s"),
    (("calibrate", "xy-stage"), "duration", "linear", "total_s"),
    (("calibrate", "xy-stage"), "runs_seed", "linear", "seed"),
    (("identify", "linear"), "order", "linear", "order"),
    (("identify", "linear"), "decimate", "linear", "decimate"),
    (("identify", "ann"), "epochs", "ann", "max_epochs"),
    (("identify", "ann"), "threads", "ann", "threads"),
    (("identify", "ann"), "workers", "ann", "workers"),
    (("identify", "ann"), "epoch_windows", "ann", "epoch_windows"),
    (("identify", "ann"), "validation", "ann", "validation"),
    (("identify", "ann"), "seed", "ann", "seed"),
    (("identify", "ann"), "whiten", "ann", "whiten"),
]


@pytest.mark.parametrize(("words", "name", "section", "key"), SHARED)
def test_options_share_the_job_keys(words, name, section, key):
    job_key = next(k for k in SCHEMA[section] if k.name == key)
    assert declared(_param(words, name)) is job_key


def test_restated_bounds_agree_with_their_sources():
    from microfab.cli.identify import MAX_BLOCK_ROWS
    from microfab.core.limits import MachineLimits
    from microfab.identify import excitation, stage_runs, subspace

    assert keys.MIN_RUN_S == stage_runs.MIN_RUN_S
    assert keys.MAX_TOTAL_S == excitation.MAX_TOTAL_S
    assert MachineLimits.seed002_stage().acceleration == (keys.A_MAX_HIGH, keys.A_MAX_HIGH)
    assert MAX_BLOCK_ROWS == subspace.MAX_BLOCK_ROWS
    pytest.importorskip("torch")
    from microfab.identify.ann import WHITEN_LOW, AnnConfig
    from microfab.machines.xy_stage.ann import AnnSettings

    assert keys.WHITEN_LOW == WHITEN_LOW
    assert keys.WHITEN == AnnConfig.__dataclass_fields__["whiten"].default
    assert keys.WHITEN == AnnSettings().whiten


# --- options with no effect in the chosen mode ---------------------------------------------
def test_seed_of_a_chirp_excitation_is_refused(tmp_path: Path, one_error_line):
    argv = ["stage", "excite", "--kind", "chirp", "--seed", "1", "--out", str(tmp_path / "o")]
    _refused(argv, "--seed has no effect with --kind chirp", tmp_path, one_error_line)


def test_seed_without_noise_is_refused(files, tmp_path: Path, one_error_line):
    argv = ["stage", "play", str(files["r0"]), "--no-noise", "--seed", "0",
            "--out", str(tmp_path / "p")]  # fmt: skip
    _refused(argv, "--seed has no effect with --no-noise", tmp_path, one_error_line)


def test_workers_with_one_axis_is_refused(files, tmp_path: Path, one_error_line):
    argv = ["identify", "ann", str(files["r0"]), str(files["r1"]), "--axis", "y",
            "--workers", "2", "--out", str(tmp_path / "a")]  # fmt: skip
    _refused(argv, "--workers has no effect with --axis y", tmp_path, one_error_line)


def test_a_whitening_too_small_to_fold_is_refused(files, tmp_path: Path, one_error_line):
    """Inside the declared [0, 1] but below the least shrinkage: refused before training."""
    argv = ["identify", "ann", str(files["r0"]), str(files["r1"]), "--whiten", "1e-9",
            "--out", str(tmp_path / "a")]  # fmt: skip
    _refused(argv, "--whiten must be 0 (not whitened) or lie in [1e-06, 1]", tmp_path,
             one_error_line)  # fmt: skip


# --- rules between options, and between an option and the file ----------------------------
@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["stage", "excite", "--kind", "prbs", "--duration", "0.8"], "two runs of 0.4 s"),
        (["stage", "excite", "--kind", "chirp", "--duration", "0.9"], "two runs of 0.45 s"),
        (["calibrate", "xy-stage", "--ann-duration", "6"],
         "--ann-duration = 6 s of the networks' data gives 3 training and 0 validation"),
    ],
)  # fmt: skip
def test_options_that_contradict_each_other_are_refused(
    tmp_path: Path, one_error_line, argv: list[str], says: str
):
    out = ["--out", str(tmp_path / "o")] if argv[0] == "stage" else ["--json", str(tmp_path / "c")]
    _refused([*argv, *out], says, tmp_path, one_error_line)


@pytest.mark.parametrize(
    ("file", "extra", "says"),
    [
        ("chirp", ["--period", "0.05", "--poles", "2", "--zeros", "3"],
         "--zeros 3 is more than --poles 2"),
        ("chirp", ["--period", "0.05", "--f0", "2000", "--f1", "20"],
         "--f1 20 Hz must be above --f0 2000 Hz"),
        ("chirp", ["--period", "0.01", "--f0", "20"],
         "--f0 20 Hz is below one FFT bin of --period 0.01 s"),
        ("chirp", ["--period", "0.05", "--periods", "2", "--drop", "2"],
         "--periods 2 must be more than --drop 2"),
        # issue 44: a --period that does not match the file
        ("chirp", ["--period", "0.04", "--f0", "30"], "does not repeat every --period 0.04 s"),
        ("chirp", ["--period", "0.025", "--f0", "40"], "does not repeat every --period 0.025 s"),
        ("chirp", ["--period", "0.1"], "holds 1 whole sweeps of --period 0.1 s and --drop 1"),
        ("chirp6", ["--period", "0.1"], "repeats every 0.05 s, a half of --period 0.1 s"),
        ("chirp6", ["--period", "0.15", "--f0", "20"], "repeats every 0.05 s, a third of"),
    ],
)  # fmt: skip
def test_identify_chirp_refuses_options_that_do_not_match(
    files, tmp_path: Path, one_error_line, file: str, extra: list[str], says: str
):
    given = [*extra, "--band", "20:2000"]
    given += [] if "--f0" in extra else ["--f0", "20"]
    given += [] if "--f1" in extra else ["--f1", "2000"]
    argv = ["identify", "chirp", str(files[file]), *given, "--json", str(tmp_path / "m")]
    _refused(argv, says, tmp_path, one_error_line)


def test_the_repeat_check_passes_a_noisy_input_and_refuses_a_wrong_period():
    from microfab.cli.identify import _REPEAT_TOL, _mismatch

    n = DESIGN.samples_per_period
    u = np.tile(DESIGN.one_period(), 3)
    noisy = u + 0.2 * u.std() * np.random.default_rng(0).standard_normal(u.size)
    assert _mismatch(u, n, 0) == pytest.approx(0.0, abs=1e-12)
    # white noise of a fifth of the chirp's rms: 0.2 / sqrt(1.04) = 0.196 (± a few %)
    assert _mismatch(noisy, n, 0) < _REPEAT_TOL
    for wrong in (int(0.8 * n), int(0.5 * n), int(1.2 * n)):
        assert _mismatch(noisy, wrong, 0) > 0.9  # measured 0.998-1.006
