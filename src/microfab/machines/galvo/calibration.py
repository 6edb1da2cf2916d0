"""The galvo twin calibrated on the calibration core against seed 000 Table 1.

Three parameters per axis are not given by the seed and are fitted jointly (`problem`):
``rigid_pole_hz`` (rigid-body damping pole), ``gain_ratio`` (true over nominal plant gain)
and ``noise_rms_v`` (encoder noise). The model (`evaluate`) is the periodic steady state of
each axis' LTI loop on the DFT bins of one period, exact for the twin's loop and fast:

* feedback only (the first trial, ``u_1 = y_d``, seed 000 §4): ``E = (T - 1) Y_d``;
* after learning (the ILC rows): every harmonic up to the 8 kHz cutoff learned exactly
  and nothing above it (eq. (2) sets the input there to zero), so ``E = -Y_d`` above the
  cutoff (`truncation_error`);
* the encoder noise enters the loop as measurement noise, so the measured error carries
  it shaped by the sensitivity ``S = 1 - T``: RMS values add its expected variance
  ``sigma^2 mean|S|^2``; peak-to-peak values add one fixed, seeded realisation of it over
  the period (`NOISE_SEED`), as the twin's one measured period does.

The fit targets are Table 1's feedback RMS and PP at 100, 200 and 400 features/s and the
ILC RMS at 100 features/s per axis; the other ILC numbers (RMS at 200 and 400, PP at all
rates) are held back as checks. ``microfab calibrate galvo`` runs it and rewrites
``data/galvo_twin.toml`` (`write_twin`). The seed's Table 1 (`TABLE1_MV`, at the rates
`RATES`) lives here; ``microfab.experiments.seed000_msl.paper`` re-exports it.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from microfab.calibrate import CalibrationProblem, CalibrationResult, FreeParameter, Target
from microfab.calibrate.twin_file import TwinKey, write_calibrated
from microfab.core.provenance import Calibration, quantity
from microfab.machines.galvo.machine import complementary_sensitivity, discrete_controller
from microfab.plants.galvo import GalvoAxis, _seed_axes, default_galvo_axes
from microfab.trajectory.periodic import square_scan

__all__ = [
    "CALIBRATION",
    "COMMAND",
    "CUTOFF_HZ",
    "DEFAULT_BUDGET",
    "RATES",
    "TABLE1_MV",
    "TWIN_KEYS",
    "evaluate",
    "fb_error",
    "loop_response",
    "predict",
    "problem",
    "table1_quantity",
    "truncation_error",
    "write_twin",
]

RATES = (100, 200, 400)  # seed 000 §4: features/s

# seed 000 Table 1: RMS (PP) tracking errors in mV.
TABLE1_MV: dict[str, dict[int, dict[str, float]]] = {
    "x": {
        100: {"fb_rms": 15.49, "fb_pp": 126.82, "ilc_rms": 1.41, "ilc_pp": 12.91},
        200: {"fb_rms": 41.86, "fb_pp": 243.10, "ilc_rms": 1.92, "ilc_pp": 21.24},
        400: {"fb_rms": 121.18, "fb_pp": 491.46, "ilc_rms": 4.11, "ilc_pp": 41.99},
    },
    "y": {
        100: {"fb_rms": 17.98, "fb_pp": 142.40, "ilc_rms": 1.45, "ilc_pp": 12.98},
        200: {"fb_rms": 48.29, "fb_pp": 275.90, "ilc_rms": 1.8207, "ilc_pp": 20.02},
        400: {"fb_rms": 139.59, "fb_pp": 532.96, "ilc_rms": 5.21, "ilc_pp": 44.43},
    },
}

#: The command that runs the calibration, as the twin file's sources name it.
COMMAND = "microfab calibrate galvo"
#: The twin's data file.
DATA_FILE = "galvo_twin.toml"
#: seed 000 §4: the compensated harmonics are limited up to 8 kHz.
CUTOFF_HZ = 8000.0
#: Seed of the one realisation of standard normal encoder noise the PP values carry
#: (assumed: any fixed seed; a PP of one period moves by a few % between realisations).
NOISE_SEED = 0
#: Tolerance of a fit target, relative to the paper's value. Assumed: half the 20 % band
#: the suite holds the seed 000 reproduction's feedback rows to
#: (tests/experiments/seed000_msl/test_job.py), so that a met fit leaves the reproduction
#: room for the noise of its one measured period. For small misses the residual
#: (model / paper - 1) / 0.1 is 10x the log-ratio the former least-squares fit used.
FIT_RELATIVE = 0.10
#: Tolerance of a check (an ILC number held back), relative. Assumed: the 30 % band the
#: suite holds the reproduction's ILC RMS to (tests/experiments/seed000_msl/test_job.py):
#: the learned error is a few mV of noise and truncation, far more variable than the FB.
CHECK_RELATIVE = 0.30
#: Evaluations `microfab calibrate galvo` asks for by default (six parameters: a DE
#: population of 60 for about 7 generations, then the polish).
DEFAULT_BUDGET = 600

_KEYS = {"fb_rms": "FB RMS", "fb_pp": "FB PP", "ilc_rms": "ILC RMS", "ilc_pp": "ILC PP"}
#: What the fit targets per axis: the six feedback numbers and the ILC RMS at the lowest rate.
_FIT = (*((k, r) for r in RATES for k in ("fb_rms", "fb_pp")), ("ilc_rms", RATES[0]))


def table1_quantity(axis: str, key: str, rate: int) -> str:
    """Id of one Table 1 number: ``key`` in ``fb_rms``, ``fb_pp``, ``ilc_rms``, ``ilc_pp``."""
    return quantity("000", "Table 1", axis, key, rate)


def _target_name(axis: str, key: str, rate: int) -> str:
    return f"{axis} {key} @{rate}"


def _targets() -> list[Target]:
    out = []
    for axis, rows in TABLE1_MV.items():
        for rate in RATES:
            for key in _KEYS:
                fit = (key, rate) in _FIT
                value = rows[rate][key]
                out.append(
                    Target(
                        name=_target_name(axis, key, rate),
                        value=value,
                        tolerance=(FIT_RELATIVE if fit else CHECK_RELATIVE) * value,
                        unit="mV",
                        source=f"seed 000 Table 1 ({axis} axis, {_KEYS[key]}, {rate} features/s)",
                        role="fit" if fit else "check",
                    )
                )
    return out


#: What the fit targets (the six feedback numbers per axis, pole and gain ratio, and the
#: ILC RMS at the lowest rate, the encoder noise) and the ILC numbers it holds back.
CALIBRATION = Calibration(
    command=COMMAND,
    data_file=DATA_FILE,
    targets=frozenset(table1_quantity(a, k, r) for a in TABLE1_MV for k, r in _FIT),
    what="rigid-body pole, gain ratio and encoder noise per axis",
    checks=frozenset(
        table1_quantity(a, k, r)
        for a in TABLE1_MV
        for r in RATES
        for k in _KEYS
        if (k, r) not in _FIT
    ),
)


def _reference(axis: GalvoAxis, rate: int) -> np.ndarray:
    idx = 0 if axis.name == "x" else 1
    return square_scan(rate, (1.0, 1.44), axis.fs_hz)[:, idx] * axis.amplitude_v / (1.0, 1.44)[idx]


def fb_error(axis: GalvoAxis, rate: int) -> np.ndarray:
    """Steady-state feedback-only tracking error (V) over one period, noise-free."""
    yd = _reference(axis, rate)
    f = np.fft.rfftfreq(yd.size, axis.dt)
    T = complementary_sensitivity(axis, f)
    return np.fft.irfft((T - 1.0) * np.fft.rfft(yd), n=yd.size)


def truncation_error(axis: GalvoAxis, rate: int, cutoff_hz: float = 8000.0) -> np.ndarray:
    """Error left when every harmonic up to ``cutoff_hz`` is learned perfectly (V)."""
    yd = _reference(axis, rate)
    Y = np.fft.rfft(yd)
    f = np.fft.rfftfreq(yd.size, axis.dt)
    return -np.fft.irfft(np.where(f <= cutoff_hz, 0.0, Y), n=yd.size)


@functools.lru_cache(maxsize=8)
def _noise_draw(n: int) -> np.ndarray:
    """The fixed standard normal realisation of one period of ``n`` samples, read-only."""
    z = np.random.default_rng(NOISE_SEED).standard_normal(n)
    z.flags.writeable = False
    return z


def _mean_power(spectrum: np.ndarray, n: int) -> np.ndarray:
    """Mean over all ``n`` DFT bins of ``|X|^2`` given the rfft half ``spectrum``."""
    p = np.abs(spectrum) ** 2
    w = np.full(p.shape, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    return np.sum(w * p) / n


def loop_response(axis: GalvoAxis, freq_hz: np.ndarray) -> np.ndarray:
    """``T = L / (1 + L)`` of the axis' loop, ``L`` as controller times plant response.

    `microfab.machines.galvo.machine.complementary_sensitivity` evaluates the series
    state space, whose modes are too ill-conditioned for the modal evaluation (cond
    2e13), so it solves per frequency: 70 ms for 5001 bins. The controller and the plant
    alone are well-conditioned (cond 76 and 1.5e6): 2 ms, the same ``T`` within 4e-11.

    Parameters
    ----------
    axis : GalvoAxis
        The axis.
    freq_hz : numpy.ndarray
        Frequencies, Hz, shape (n,).

    Returns
    -------
    numpy.ndarray
        Complex ``T``, shape (n,); 1 where ``L`` has a pole (DC).
    """
    c = discrete_controller(axis).frequency_response(freq_hz)[:, 0, 0]
    p = axis.discrete_plant().frequency_response(freq_hz)[:, 0, 0]
    with np.errstate(invalid="ignore", divide="ignore"):  # inf times a complex at DC
        loop = c * p
        t = loop / (1.0 + loop)
    t[~np.isfinite(loop)] = 1.0
    return t


def predict(axis: GalvoAxis, rates: tuple[int, ...] = RATES) -> dict[tuple[str, int], float]:
    """The model's Table 1 numbers of one axis, mV.

    Parameters
    ----------
    axis : GalvoAxis
        The axis (its calibrated values included).
    rates : tuple of int
        Scan rates, features/s; each a multiple of the first, whose DFT bins (harmonics of
        the first rate) then hold every other rate's.

    Returns
    -------
    dict
        ``(key, rate) -> value`` for ``key`` in ``fb_rms``, ``fb_pp``, ``ilc_rms``,
        ``ilc_pp`` (see the module docstring for the model).
    """
    base = rates[0]
    if any(r % base for r in rates):
        raise ValueError(f"every rate must be a multiple of the first, got {rates}")
    n0 = _reference(axis, base).size
    f0 = np.fft.rfftfreq(n0, axis.dt)
    # the loop does not depend on the noise: its level left out, the loops built for one
    # pole and gain are shared (lru caches) by every noise level the search tries
    t0 = loop_response(axis.with_calibration(noise_rms_v=0.0), f0)
    sigma = axis.noise_rms_v
    out: dict[tuple[str, int], float] = {}
    for r in rates:
        yd = _reference(axis, r)
        n = yd.size
        t = t0[:: r // base]
        f = f0[:: r // base]
        if t.size != n // 2 + 1:
            raise ValueError(f"{r} features/s: the period does not divide the first rate's")
        y = np.fft.rfft(yd)
        s = 1.0 - t
        noise = sigma * np.fft.irfft(s * np.fft.rfft(_noise_draw(n)), n=n)
        noise_var = sigma**2 * _mean_power(s, n)  # E[var] of white noise through S, V^2
        fb = np.fft.irfft((t - 1.0) * y, n=n)
        ilc = -np.fft.irfft(np.where(f <= CUTOFF_HZ, 0.0, y), n=n)
        for key, e in (("fb", fb), ("ilc", ilc)):
            out[(f"{key}_rms", r)] = 1e3 * float(np.sqrt(np.var(e) + noise_var))
            out[(f"{key}_pp", r)] = 1e3 * float(np.ptp(e + noise))
    return out


def evaluate(values: Mapping[str, float]) -> dict[str, float]:
    """The model of `problem`: parameter values (``<axis> <key>``) -> every target, mV.

    Module-level (picklable) for the calibration's process pool.
    """
    out: dict[str, float] = {}
    for name, seed_axis in _seed_axes().items():
        axis = seed_axis.with_calibration(
            **{k: float(values[f"{name} {k}"]) for k in ("rigid_pole_hz", "gain_ratio")},
            noise_rms_v=float(values[f"{name} noise_rms_v"]),
        )
        for (key, rate), v in predict(axis).items():
            out[_target_name(name, key, rate)] = v
    return out


def _parameters() -> list[FreeParameter]:
    out = []
    for axis in TABLE1_MV:
        out += [
            FreeParameter(
                f"{axis} rigid_pole_hz",
                1.0,
                1000.0,
                "Hz",
                "assumed: from nearly pure inertia (1 Hz) to half the 2 kHz crossover of "
                "seed 000 §3.1 (eq. (1) is a lead-lag for a double integrator there)",
                log=True,
            ),
            FreeParameter(
                f"{axis} gain_ratio",
                float(np.exp(-1.0)),
                float(np.exp(1.0)),
                "",
                "assumed: true over nominal gain within a factor e either way; seed 000 §3.1 "
                "measures 51-53 deg phase margin, so the loop is near its design",
                log=True,
            ),
            FreeParameter(
                f"{axis} noise_rms_v",
                1e-5,
                1e-2,
                "V",
                "assumed: 10 uV to 10 mV, decades around seed 000 Table 1's ILC RMS "
                "(1.41-5.21 mV), which the noise alone cannot exceed",
                log=True,
            ),
        ]
    return out


def problem(*, source: str | os.PathLike[str] | None = None) -> CalibrationProblem:
    """The galvo twin's calibration problem on seed 000 Table 1.

    Parameters
    ----------
    source : path-like, optional
        The twin data file the result will be written over. It holds only the three
        calibrated values per axis, so the model does not read it (the search covers
        the bounds); it is read here so that a broken file is refused before any work.

    Returns
    -------
    CalibrationProblem
        24 targets (14 fit, 10 checks), 6 free parameters, the model `evaluate`.
    """
    default_galvo_axes(source)  # a bad file is refused before any work
    identity = f"galvo DFT model v1; cutoff {CUTOFF_HZ} Hz; noise seed {NOISE_SEED}"
    return CalibrationProblem(_targets(), _parameters(), evaluate, identity=identity)


#: Where each free parameter goes in ``data/galvo_twin.toml``.
TWIN_KEYS = tuple(
    TwinKey(f"{axis} {key}", f"axes.{axis}", key, digits=6)
    for axis in TABLE1_MV
    for key in ("rigid_pole_hz", "gain_ratio", "noise_rms_v")
)


def write_twin(
    result: CalibrationResult,
    path: str | os.PathLike[str],
    *,
    source: str | os.PathLike[str] | None = None,
) -> Path:
    """Write the twin data file with the calibrated values (atomically).

    Parameters
    ----------
    result : CalibrationResult
        A calibration of `problem`.
    path : path-like
        Where to write.
    source : path-like, optional
        The file to start from (comments and layout kept); the packaged one when omitted.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    return write_calibrated(
        result, TWIN_KEYS, command=COMMAND, data_file=DATA_FILE, path=path, source=source
    )
