"""``microfab identify chirp`` (seed 003 part 2 §1)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.signal
from typer.testing import CliRunner

from microfab.cli import app
from microfab.identify.chirp import ChirpDesign
from microfab.identify.model import TFModel
from microfab.io.trace import write_columns
from microfab.plants.galvo_slm import galvo_slm_twin

runner = CliRunner()

# a short chirp keeps the test fast: 20 Hz - 2 kHz in 50 ms, 2 periods after the dropped one
DESIGN = ChirpDesign(f0_hz=20.0, f1_hz=2000.0, period_s=0.05, n_periods=3, n_dropped=1)
CHIRP_ARGS = ["--f0", "20", "--period", "0.05", "--band", "20:2000"]


def _write_chirp(path: Path, *, u=None, y=None, time=None, drop_output=False) -> Path:
    """The twin's chirp record (default: the seed's model, ZOH at 10 µs, no noise)."""
    if u is None:
        u = DESIGN.signal().input
    if y is None:
        ax = galvo_slm_twin().axis_model
        y = np.ravel(scipy.signal.dlsim((ax.A, ax.B, ax.C, ax.D, ax.dt), u)[1])
    cols = {"time": np.arange(u.size) * DESIGN.dt if time is None else time, "input_x": u}
    if not drop_output:
        cols["output_x"] = y
    write_columns(path, cols, unit="bit")
    return path


@pytest.fixture(scope="module")
def chirp_file(tmp_path_factory) -> Path:
    return _write_chirp(tmp_path_factory.mktemp("chirp") / "chirp.csv")


def test_identify_chirp_round_trips_the_twin(chirp_file: Path, seed_model: TFModel, tmp_path: Path):
    out, fig = tmp_path / "model.json", tmp_path / "fit.png"
    res = runner.invoke(
        app,
        ["identify", "chirp", str(chirp_file), *CHIRP_ARGS, "--json", str(out), "--plot", str(fig)],
    )
    assert res.exit_code == 0, res.output
    m = TFModel.from_dict(json.loads(out.read_text()))
    # issue 16 §6: the seed's coefficients to 1e-4 without noise
    np.testing.assert_allclose(m.den, seed_model.den, rtol=1e-4)
    np.testing.assert_allclose(m.num, seed_model.num, rtol=1e-4)
    saved = json.loads(out.read_text())["fit"]
    assert saved["sampling"] == "zoh" and saved["dt_s"] == pytest.approx(1e-5)
    assert saved["n_averages"] == 2 and saved["band_hz"] == [20.0, 2000.0]
    assert "550.4" in res.output  # seed §1 model: real pole 550.5 Hz
    assert "965.1" in res.output and "0.499" in res.output  # complex pair 965.2 Hz, ζ 0.4995
    assert fig.stat().st_size > 0
    # the H1 estimate on whole sweeps fits as well
    res = runner.invoke(
        app,
        ["identify", "chirp", str(chirp_file), *CHIRP_ARGS, "--method", "h1", "--json", str(out)],
    )
    assert res.exit_code == 0, res.output
    h1 = TFModel.from_dict(json.loads(out.read_text()))
    np.testing.assert_allclose(h1.den, seed_model.den, 1e-4)


def _unstable(u: np.ndarray) -> np.ndarray:
    """Periodic response of a right-half-plane pair (300 Hz, damping -0.2), as sampled."""
    n = DESIGN.samples_per_period
    w = 2 * np.pi * 300.0
    bad = TFModel(num=[w**2], den=[1.0, -2 * 0.2 * w, w**2])
    h = bad.frequency_response(np.fft.rfftfreq(n, DESIGN.dt), sampling="zoh", dt=DESIGN.dt)
    return np.tile(np.fft.irfft(np.fft.rfft(u[:n]) * h, n), u.size // n)


@pytest.fixture(scope="module")
def bad_chirps(tmp_path_factory) -> dict[str, Path]:
    """Chirp records with one fault each (written once for the refusal tests)."""
    tmp = tmp_path_factory.mktemp("bad")
    u = DESIGN.signal().input
    t = np.arange(u.size) * DESIGN.dt
    jitter, nan_t = t.copy(), t.copy()
    jitter[100] += 0.3 * DESIGN.dt
    nan_t[7] = np.nan
    ax = galvo_slm_twin().axis_model
    y = np.ravel(scipy.signal.dlsim((ax.A, ax.B, ax.C, ax.D, ax.dt), u)[1])
    noisy = y + 30.0 * np.random.default_rng(3).standard_normal(y.size)
    nan_y = y.copy()
    nan_y[50] = np.nan
    return {
        "jitter": _write_chirp(tmp / "jitter.csv", time=jitter),
        "nan_time": _write_chirp(tmp / "nan_time.csv", time=nan_t),
        "nan_output": _write_chirp(tmp / "nan_y.csv", y=nan_y),
        "no_output": _write_chirp(tmp / "no_y.csv", drop_output=True),
        "short": _write_chirp(tmp / "short.csv", u=u[:3000], y=y[:3000]),
        "noisy": _write_chirp(tmp / "noisy.csv", y=noisy),
        "unstable": _write_chirp(tmp / "unstable.h5", y=_unstable(u)),
    }


@pytest.mark.parametrize(
    "file, extra, says",
    [
        ("jitter", [], "time must be uniformly sampled"),
        ("nan_time", [], "time"),
        ("nan_output", [], "output_x"),
        ("no_output", [], "no column 'output_x'"),
        ("good", ["--axis", "y"], "no column 'input_y'"),
        ("good", ["--band", "20:60000"], "above the Nyquist frequency 50000 Hz"),
        ("good", ["--band", "5:2000"], "outside the excited band 20-2000 Hz of the chirp"),
        ("good", ["--band", "2000"], "--band must look like LOW:HIGH"),
        ("short", [], "(0.03 s) is shorter than one sweep of --period 0.05 s"),
        ("good", ["--drop", "3"], "is 3 whole periods of 5000 samples (0.05 s); with n_dropped"),
        ("good", ["--periods", "4"], "holds 3 whole sweeps of 0.05 s, --periods says 4"),
        ("good", ["--period", "0.050005"], "--period must be a whole number"),
        ("good", ["--f1", "60000"], "--f1 must lie below the Nyquist frequency"),
        ("good", ["--amplitude", "50"], "not the --amplitude 50"),
        ("noisy", [], "coherence below 0.8 from"),
        ("unstable", ["--poles", "2"], "the fitted model is unstable"),
        ("good", ["--poles", "2", "--zeros", "3"], "n_zeros must not exceed n_poles"),
    ],
)
def test_identify_chirp_refusals_write_nothing(
    chirp_file: Path,
    bad_chirps: dict[str, Path],
    tmp_path: Path,
    one_error_line,
    file: str,
    extra: list[str],
    says: str,
):
    path = chirp_file if file == "good" else bad_chirps[file]
    out = tmp_path / "model.json"
    argv = ["identify", "chirp", str(path), *CHIRP_ARGS, *extra, "--json", str(out)]
    res = runner.invoke(app, [*argv, "--plot", str(tmp_path / "f.png")])
    one_error_line(res, says)
    assert not out.exists() and not (tmp_path / "f.png").exists()
