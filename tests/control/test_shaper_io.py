from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

from microfab.control.shaper_io import (
    FORMAT,
    read_shaper,
    shaper_from_dict,
    shaper_lti,
    shaper_to_dict,
    write_shaper,
)
from microfab.control.shapers import ImpulseShaper, design_shaper
from microfab.control.shaping import InverseShaper, InverseShaperConfig, design_inverse_shaper
from microfab.identify.model import TFModel

SEED_G = ((1.242e11,), (1.0, 9517.0, 5.773e7, 1.272e11))  # seed 003 part 2 §1


def _through_json(d: dict) -> dict:
    return json.loads(json.dumps(d))


@pytest.mark.parametrize("disc", ["zoh", "zpetc"])
def test_inverse_round_trip(disc: str):
    cfg = InverseShaperConfig(pole_hz=5000.0, order=4, dt=1e-5, discretization=disc)
    s = design_inverse_shaper(SEED_G, cfg)
    d = _through_json(shaper_to_dict(s))
    assert d["format"] == FORMAT == 1 and d["kind"] == "inverse"
    assert d["config"] == {"pole_hz": 5000.0, "order": 4, "dt": 1e-5, "discretization": disc}
    assert TFModel.from_dict(d["model"]).static_gain == pytest.approx(1.242e11 / 1.272e11)
    r = shaper_from_dict(d)
    assert isinstance(r, InverseShaper) and r.config == cfg and r.preview == s.preview
    for name in ("plant_num", "plant_den", "num", "den", "num_d", "den_d"):
        np.testing.assert_allclose(getattr(r, name), getattr(s, name), rtol=1e-12, atol=0)
    assert d["derived"]["num_d"] == pytest.approx(list(s.num_d), rel=1e-15)


def test_impulse_round_trip_keeps_a_numeric_design():
    s = design_shaper("ei", 3000.0, 0.5)  # beyond Klipper's closed form: solved numerically
    assert s.numeric
    d = _through_json(shaper_to_dict(s))
    assert d["kind"] == "impulse" and d["name"] == "ei" and d["numeric"] is True
    r = shaper_from_dict(d)
    assert isinstance(r, ImpulseShaper)
    np.testing.assert_array_equal(r.amplitudes, s.amplitudes)
    np.testing.assert_array_equal(r.times, s.times)
    assert (r.name, r.freq_hz, r.damping, r.v_tol, r.numeric, r.constraint_miss) == (
        s.name, s.freq_hz, s.damping, s.v_tol, s.numeric, s.constraint_miss,
    )  # fmt: skip


def test_files_round_trip_and_name_the_file(tmp_path: Path):
    s = design_shaper("zv", 2500.0, 0.1)
    write_shaper(tmp_path / "zv.json", s)
    r = read_shaper(tmp_path / "zv.json")
    np.testing.assert_array_equal(r.times, s.times)
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(
        ValueError, match=r"bad\.json: not a shaper \(JSON of shaper design\) \(not JSON"
    ):
        read_shaper(tmp_path / "bad.json")
    with pytest.raises(FileNotFoundError, match="shaper file not found"):
        read_shaper(tmp_path / "none.json")


def _inverse_dict() -> dict:
    return _through_json(shaper_to_dict(design_inverse_shaper(SEED_G)))


def _impulse_dict() -> dict:
    return _through_json(shaper_to_dict(design_shaper("zvd", 1000.0, 0.05)))


@pytest.mark.parametrize(
    "edit, says",
    [
        (lambda d: d.update(format=2), "not a shaper file of format 1: its format is 2"),
        (lambda d: d.pop("format"), "its format is None"),
        (lambda d: d.update(kind="mystery"), "unknown shaper kind 'mystery'; known: inverse"),
        (lambda d: d.update(extra=1), "unknown key 'extra' in the inverse shaper"),
        (lambda d: d.pop("config"), "the inverse shaper has no 'config'"),
        (lambda d: d["config"].pop("dt"), "config has no 'dt'"),
        (lambda d: d["config"].update(order=4.0), "'order' must be an integer"),
        (lambda d: d["config"].update(pole_hz="4k"), "'pole_hz' must be a finite number"),
        (lambda d: d["config"].update(pole_hz=100.0), "not faster than the model's fastest pole"),
        (lambda d: d["config"].update(discretization="tustin"), "discretization must be"),
        (lambda d: d["model"].update(num=[1.0, -2.0]), "right half-plane"),
        (lambda d: d["model"].update(format="x"), "inverse shaper 'model': format must be"),
    ],
)
def test_inverse_refusals(edit, says: str):
    d = _inverse_dict()
    edit(d)
    with pytest.raises(ValueError) as e:
        shaper_from_dict(d)
    assert says in str(e.value)


@pytest.mark.parametrize(
    "edit, says",
    [
        (lambda d: d.pop("times_s"), "the impulse shaper has no 'times_s'"),
        (lambda d: d.update(amplitudes=[]), "'amplitudes' must be a non-empty list"),
        (lambda d: d.update(times_s=[0.0, "a", 1.0]), "'times_s' must be a non-empty list"),
        (lambda d: d.update(freq_hz=True), "'freq_hz' must be a finite number"),
        (lambda d: d.update(numeric="yes"), "'numeric' must be true or false"),
        (lambda d: d.update(times_s=[0.0, 2e-3, 1e-3]), "times must start at 0 s and not"),
        (lambda d: d.update(pole_hz=1.0), "unknown key 'pole_hz' in the impulse shaper"),
    ],
)
def test_impulse_refusals(edit, says: str):
    d = _impulse_dict()
    edit(d)
    with pytest.raises(ValueError) as e:
        shaper_from_dict(d)
    assert says in str(e.value)


def test_a_model_file_is_not_a_shaper():
    with pytest.raises(ValueError, match="a model file: design a shaper from it first"):
        shaper_from_dict(TFModel(num=SEED_G[0], den=SEED_G[1]).to_dict())
    with pytest.raises(ValueError, match="must be a JSON object, got list"):
        shaper_from_dict([1])  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        shaper_to_dict(object())  # type: ignore[arg-type]


def test_shaper_lti_filters_as_the_shaper_does():
    dt = 1e-5
    u = np.zeros(200)
    u[5:] = 1.0
    zv = design_shaper("zv", 2345.0, 0.05)
    sys = shaper_lti(zv, dt)
    _, y, _ = scipy.signal.dlsim((sys.A, sys.B, sys.C, sys.D, dt), u)
    np.testing.assert_allclose(np.ravel(y), np.convolve(u, zv.taps(dt))[: u.size], atol=1e-14)
    inv = design_inverse_shaper(SEED_G)
    sys = shaper_lti(inv, dt)
    _, y, _ = scipy.signal.dlsim((sys.A, sys.B, sys.C, sys.D, dt), u)
    np.testing.assert_allclose(
        np.ravel(y), scipy.signal.lfilter(inv.num_d, inv.den_d, u), rtol=1e-9, atol=1e-9
    )
    with pytest.raises(ValueError, match="designed for dt = 1e-05 s"):
        shaper_lti(inv, 2e-5)
    one = ImpulseShaper(name="none", freq_hz=1.0, damping=0.0, amplitudes=[1.0], times=[0.0])
    gain = shaper_lti(one, dt)
    assert gain.D[0, 0] == 1.0 and not gain.C.any()


def test_a_shaper_too_long_for_its_filter_is_refused_before_allocation() -> None:
    """Issue 32: a 10 s shaper at 10 µs asked for a 7.28 TiB state matrix."""
    from microfab.control.shaper_io import MAX_FIR_TAPS, shaper_lti

    long = ImpulseShaper(name="zv", freq_hz=0.05, damping=0.0, amplitudes=[0.5, 0.5],
                         times=[0.0, 10.0])  # fmt: skip
    with pytest.raises(ValueError, match=r"10 s long at dt = 1e-05 s is 1e\+06 taps"):
        shaper_lti(long, 1e-5)
    ok = ImpulseShaper(name="zv", freq_hz=1.0, damping=0.0, amplitudes=[0.5, 0.5],
                       times=[0.0, (MAX_FIR_TAPS - 1) * 1e-5])  # fmt: skip
    assert shaper_lti(ok, 1e-5).A.shape[0] <= MAX_FIR_TAPS


def test_a_shaper_file_whose_amplitudes_do_not_sum_to_one_is_refused(tmp_path) -> None:
    """Issue 32: slm scan-time took a shaper whose amplitudes sum to 0.6 (40 % short)."""
    zv = design_shaper("zv", 2000.0, 0.05)
    d = shaper_to_dict(zv)
    assert shaper_from_dict(d).amplitudes.sum() == pytest.approx(1.0)
    d["amplitudes"] = [0.3, 0.3]
    with pytest.raises(ValueError, match=r"amplitudes sum to 0\.6, not 1"):
        shaper_from_dict(d)
