"""``microfab shaper design``: the seed 003 part 2 §2 inverse and classic shapers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.control.shaper_io import read_shaper
from microfab.control.shapers import ImpulseShaper
from microfab.control.shaping import InverseShaper
from microfab.identify.model import TFModel
from microfab.io.frf import write_frf
from microfab.io.trace import write_columns
from microfab.plants.galvo_slm import galvo_slm_twin

runner = CliRunner()


def test_shaper_design_inverse(model_file: Path, tmp_path: Path):
    out = tmp_path / "inv.json"
    argv = ["shaper", "design", str(model_file), "--kind", "inverse", "--poles-hz", "4000"]
    res = runner.invoke(app, [*argv, "--order", "4", "--dt", "1e-5", "--out", str(out)])
    assert res.exit_code == 0, res.output
    s = read_shaper(out)
    assert isinstance(s, InverseShaper) and s.preview == 0
    # seed 003 part 2 §2, the printed digits of the continuous shaper and its ZOH filter
    assert "3.99e+17, 3.797e+21, 2.303e+25, 5.075e+28" in res.output
    np.testing.assert_allclose(s.num_d[1:], (19.61, -56.99, 55.26, -17.88), atol=0.005)
    np.testing.assert_allclose(s.den_d, (1, -3.111, 3.63, -1.882, 0.3659), atol=0.0005)
    assert "40.27 at 6986" in res.output  # issue 16 §3: the gain peaks at 40.3 at 6.99 kHz
    assert "23.66" in res.output  # a step becomes a 23.7x command peak
    res = runner.invoke(app, [*argv, "--discretization", "zpetc", "--out", str(out)])
    assert res.exit_code == 0 and read_shaper(out).preview == 2, res.output


@pytest.mark.parametrize(
    "extra, says",
    [
        (["--poles-hz", "800"], "--poles-hz = 800.0 Hz (5026.55 rad/s) is not faster than"),
        (["--dt", "1e-3"], "above the Nyquist frequency 500 Hz"),
        (["--dt", "0"], "'--dt': 0 s is outside the allowed range [1e-07, 0.01] s"),
        # fuzz: a dt of 1e-300 s crashed the table, 1 µs made the settling search run
        # out of memory (the rounded ZOH filter never settles to 1e-9)
        (["--dt", "1e-300"], "'--dt': 1e-300 s is outside the allowed range"),
        (["--dt", "1e-6"], "does not settle within 1e-09 of its static gain"),
        (["--order", "2"], "--order = 2 is below the model's relative degree 3"),
        (
            ["--discretization", "tustin"],
            "Invalid value for '--discretization': 'tustin' is not one of zoh, zpetc",
        ),
        (
            ["--kind", "zz"],
            "Invalid value for '--kind': 'zz' is not one of inverse, zv, mzv, zvd, ei",
        ),
        (["--freq-hz", "3000"], "--freq-hz has no effect with --kind inverse"),
        (["MODEL=rhp"], "in the right half-plane"),
        (["MODEL=none"], "--kind inverse needs MODEL"),
        (["MODEL=missing"], "model file not found"),
        (["MODEL=shaper"], "format = 1 should be 'microfab.identify.TFModel'"),
        (["MODEL=deep"], "nested too deeply to be a transfer-function model"),  # fuzz
    ],
)
def test_shaper_design_inverse_refusals(
    model_file: Path,
    seed_model: TFModel,
    tmp_path: Path,
    one_error_line,
    extra: list[str],
    says: str,
):
    model = [str(model_file)]
    if extra and extra[0].startswith("MODEL="):
        which = extra.pop(0).split("=")[1]
        path = tmp_path / f"{which}.json"
        if which == "rhp":  # a zero at +1000 rad/s
            rhp = TFModel(num=[-1.272e8, 1.272e11], den=seed_model.den)
            path.write_text(json.dumps(rhp.to_dict()))
        elif which == "shaper":
            path.write_text(json.dumps({"format": 1, "kind": "impulse"}))
        elif which == "deep":
            path.write_text("[" * 100_000)
        model = [] if which == "none" else [str(path)]
    out = tmp_path / "s.json"
    res = runner.invoke(app, ["shaper", "design", *model, *extra, "--out", str(out)])
    one_error_line(res, says)
    assert not out.exists()


@pytest.fixture(scope="module")
def mirror_frf(tmp_path_factory) -> Path:
    """The mirror-mode twin's FRF (continuous, 100 Hz - 8 kHz) as an FRF file."""
    f = np.linspace(100.0, 8000.0, 400)
    tf = galvo_slm_twin(mirror_mode=True).transfer_function()
    h = np.array([complex(tf(2j * np.pi * x)) for x in f])
    p = tmp_path_factory.mktemp("frf") / "mirror.csv"
    write_frf(p, f, h[:, None], ("x",))
    return p


def test_shaper_design_auto_fits_the_mirror_mode(
    model_file: Path, mirror_frf: Path, tmp_path: Path
):
    # the seed's model as the baseline leaves the assumed 3 kHz, ζ 0.02 mirror mode
    out = tmp_path / "zv.json"
    argv = ["shaper", "design", str(model_file), "--kind", "zv", "--frf", str(mirror_frf)]
    res = runner.invoke(app, [*argv, "--damping", "0.02", "--out", str(out)])
    assert res.exit_code == 0, res.output
    s = read_shaper(out)
    assert isinstance(s, ImpulseShaper) and s.name == "zv" and s.damping == 0.02
    # Klipper's rule trades a little vibration for delay: the mode is left at its 5 %
    assert abs(s.freq_hz / 3000.0 - 1.0) < 0.03
    assert float(s.vibration(3000.0, 0.02)[0]) <= 0.05
    assert "remaining vibration of the fit" in res.output
    # the same from a PSD of what the model does not explain
    data = json.loads(model_file.read_text())
    base = TFModel.from_dict(data).frequency_response(np.linspace(100.0, 8000.0, 400))
    tf = galvo_slm_twin(mirror_mode=True).transfer_function()
    f = np.linspace(100.0, 8000.0, 400)
    h = np.array([complex(tf(2j * np.pi * x)) for x in f])
    psd = tmp_path / "psd.csv"
    write_columns(psd, {"freq_hz": f, "psd": np.abs(h / base) ** 2})
    argv = ["shaper", "design", "--kind", "mzv", "--psd", str(psd), "--damping", "0.02"]
    res = runner.invoke(app, [*argv, "--out", str(out)])
    assert res.exit_code == 0, res.output
    mzv = read_shaper(out)
    assert 2500.0 < mzv.freq_hz < 3500.0  # MZV is broader: its score prefers a shorter one
    assert float(mzv.vibration(3000.0, 0.02)[0]) <= 0.05


def test_shaper_design_classic_for_a_given_mode(tmp_path: Path):
    out = tmp_path / "ei.json"
    res = runner.invoke(
        app,
        ["shaper", "design", "--kind", "ei", "--freq-hz", "3000", "--damping", "0.5",
         "--out", str(out)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    s = read_shaper(out)
    assert s.numeric and "solved numerically" in res.output  # Klipper's form misses at 0.5
    assert abs(float(s.vibration(3000.0)[0]) - 0.05) < 1e-9  # EI: V = 5 % at the mode


@pytest.mark.parametrize(
    "extra, says",
    [
        ([], "--kind zv needs one of --freq-hz, --frf or --psd, got none"),
        (["--freq-hz", "3000", "--psd", "PSD"], "got --freq-hz and --psd"),
        (["--freq-hz", "60000"], "at or above the Nyquist frequency 50000 Hz of --dt"),
        (["--freq-hz", "3000", "--damping", "1.5"], "1.5 is outside the allowed range [0, 0.99]"),
        (["--freq-hz", "-3"], "'--freq-hz': -3 Hz is outside the allowed range [1, 1e+06]"),
        # fuzz: taps of a shaper lasting years, or at dt 8e-294 s (negative dimensions)
        (["--freq-hz", "1e-9"], "'--freq-hz': 1e-09 Hz is outside the allowed range"),
        (["--freq-hz", "3000", "--dt", "8e-294"], "'--dt': 8e-294 s is outside the allowed"),
        # fuzz: a mode of 5e-324 Hz overflowed the impulse times with warnings on stderr
        (["--freq-hz", "5e-324"], "e-324 Hz is outside the allowed range [1, 1e+06] Hz"),
        (["--freq-hz", "3000", "MODEL"], "MODEL serves a classic kind only as the baseline"),
        (["--psd", "PSD_BAD"], "no column 'psd'"),
        (["--frf", "FRF", "--freq-range", "9:3"], "--freq-range must look like LOW:HIGH"),
    ],
)
def test_shaper_design_classic_refusals(
    model_file: Path,
    mirror_frf: Path,
    tmp_path: Path,
    one_error_line,
    extra: list[str],
    says: str,
):
    write_columns(tmp_path / "psd.csv", {"freq_hz": [1.0, 2.0, 3.0], "psd": [1.0, 2.0, 1.0]})
    write_columns(tmp_path / "bad.csv", {"freq_hz": [1.0, 2.0, 3.0], "p": [1.0, 2.0, 1.0]})
    subs = {
        "PSD": str(tmp_path / "psd.csv"),
        "PSD_BAD": str(tmp_path / "bad.csv"),
        "FRF": str(mirror_frf),
        "MODEL": str(model_file),
    }
    argv = [subs.get(a, a) for a in extra]
    out = tmp_path / "s.json"
    res = runner.invoke(app, ["shaper", "design", "--kind", "zv", *argv, "--out", str(out)])
    one_error_line(res, says)
    assert not out.exists()


def test_compare_command_gives_the_library_rows(tmp_path: Path):
    from microfab.machines.slm_galvo.shapers import CompareSettings, compare_shapers

    out = tmp_path / "cmp.json"
    res = runner.invoke(
        app,
        ["shaper", "compare", "--twin", "mirror", "--shapers", "zv,ei", "--true-mode",
         "--json", str(out)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "Shapers on the mirror twin" in res.output
    want = compare_shapers("mirror", CompareSettings(shapers=("zv", "ei"), frf_noise=False))
    assert json.loads(out.read_text()) == json.loads(json.dumps(want.summary()))


@pytest.mark.parametrize(
    "extra, says",
    [
        (["--twin", "bunny"], "Invalid value for '--twin': 'bunny' is not one of seed, mirror"),
        (["--shapers", "zv,nope"], "unknown shaper 'nope'"),
        (["--start-bit", "40000"], "40000 bit is outside the allowed range [-32768, 32768] bit"),
        (
            ["--inverse", "tustin"],
            "Invalid value for '--inverse': 'tustin' is not one of zoh, zpetc",
        ),
        (["--band-pct", "0"], "--band-pct"),
        (["--seed", "-1"], "seed"),
    ],
)
def test_compare_command_refusals(extra: list[str], says: str):
    zv = [] if "--shapers" in extra else ["--shapers", "zv"]  # an option is given once
    res = runner.invoke(app, ["shaper", "compare", "--true-mode", *zv, *extra])
    assert res.exit_code == 2 and says in res.output, res.output
