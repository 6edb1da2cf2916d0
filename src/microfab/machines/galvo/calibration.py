"""Reproducible calibration of the galvo twin against seed 000 Table 1.

Three parameters per axis are not given by the seed and are fitted here:

* ``rigid_pole_hz`` and ``gain_ratio`` (rigid-body damping pole and true/nominal gain) by
  least squares on the log-ratios of the six feedback-only numbers of Table 1 (RMS and PP
  at 100, 200, 400 features/s). The feedback error of the periodic steady state is
  ``E[n] = (T[n] - 1) Y_d[n]`` on every DFT bin, exact for the LTI twin and fast.
* ``noise_rms_v`` (encoder noise) in closed form from the 100 features/s ILC row: after
  learning, the error is the reference content above the 8 kHz cutoff (which eq. (2) sets
  to zero) plus noise, so ``sigma^2 = rms_ILC^2 - rms_truncation^2``.

Run ``microfab calibrate galvo`` to redo the fit and rewrite ``data/galvo_twin.toml``.
The seed's Table 1 (`TABLE1_MV`, at the rates `RATES`) is the calibration's target and
lives here; ``microfab.experiments.seed000_msl.paper`` re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from microfab.core.provenance import Calibration, quantity
from microfab.io.atomic import atomic_write_text
from microfab.machines.galvo.machine import complementary_sensitivity
from microfab.plants.galvo import GalvoAxis, _seed_axes
from microfab.trajectory.periodic import square_scan

__all__ = [
    "CALIBRATION",
    "RATES",
    "TABLE1_MV",
    "AxisCalibration",
    "calibrate_galvo",
    "fb_error",
    "table1_quantity",
    "truncation_error",
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


def table1_quantity(axis: str, key: str, rate: int) -> str:
    """Id of one Table 1 number: ``key`` in ``fb_rms``, ``fb_pp``, ``ilc_rms``, ``ilc_pp``."""
    return quantity("000", "Table 1", axis, key, rate)


#: What the fit targets: the six feedback numbers per axis (pole and gain ratio) and the ILC
#: RMS at the lowest rate (the encoder noise).
CALIBRATION = Calibration(
    command="microfab calibrate galvo",
    data_file="galvo_twin.toml",
    targets=frozenset(
        {table1_quantity(a, k, r) for a in TABLE1_MV for r in RATES for k in ("fb_rms", "fb_pp")}
        | {table1_quantity(a, "ilc_rms", RATES[0]) for a in TABLE1_MV}
    ),
    what="rigid-body pole, gain ratio and encoder noise per axis",
)


@dataclass(frozen=True)
class AxisCalibration:
    """Fitted values of one axis and how well they reproduce Table 1.

    Attributes
    ----------
    axis : GalvoAxis
        The calibrated axis.
    residual_pct : dict
        ``{rate: (rms_err_pct, pp_err_pct)}`` of the feedback rows, model vs seed.
    """

    axis: GalvoAxis
    residual_pct: dict[int, tuple[float, float]]


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


def _fit_axis(axis: GalvoAxis) -> AxisCalibration:
    seed = TABLE1_MV[axis.name]

    def residuals(p: np.ndarray) -> np.ndarray:
        ax = axis.with_calibration(rigid_pole_hz=float(p[0]), gain_ratio=float(np.exp(p[1])))
        out = []
        for r in RATES:
            e = fb_error(ax, r) * 1e3
            out += [np.log(e.std() / seed[r]["fb_rms"]), np.log(np.ptp(e) / seed[r]["fb_pp"])]
        return np.array(out)

    sol = least_squares(
        residuals, x0=[150.0, 0.0], bounds=([1.0, -1.0], [1000.0, 1.0]), diff_step=1e-3
    )
    fitted = axis.with_calibration(
        rigid_pole_hz=float(sol.x[0]), gain_ratio=float(np.exp(sol.x[1]))
    )
    trunc = truncation_error(fitted, 100).std()
    ilc = TABLE1_MV[axis.name][100]["ilc_rms"] * 1e-3
    noise = float(np.sqrt(max(ilc**2 - trunc**2, 0.0)))
    fitted = fitted.with_calibration(noise_rms_v=noise)
    res = np.expm1(sol.fun) * 100
    return AxisCalibration(
        fitted, {r: (float(res[2 * i]), float(res[2 * i + 1])) for i, r in enumerate(RATES)}
    )


def calibrate_galvo(write_to: str | Path | None = None) -> dict[str, AxisCalibration]:
    """Fit the x and y twins to seed 000 Table 1 and optionally write the TOML file.

    Parameters
    ----------
    write_to : str or Path, optional
        Where to write the calibration (atomically), e.g.
        ``src/microfab/data/galvo_twin.toml``.

    Returns
    -------
    dict of str to AxisCalibration
    """
    out = {name: _fit_axis(ax) for name, ax in _seed_axes().items()}
    if write_to is not None:
        lines = [
            "# Galvo twin calibration, written by `microfab calibrate galvo`",
            "# (microfab.machines.galvo.calibration).",
            "# Fitted to seed 000 Table 1 feedback rows;",
            "# residual_pct = model/seed - 1 in % for (RMS, PP) at 100, 200, 400 features/s.",
            "",
        ]
        for name, cal in out.items():
            ax = cal.axis
            res = ", ".join(f"{v[0]:.2f}, {v[1]:.2f}" for v in cal.residual_pct.values())
            lines += [
                f"[axes.{name}]",
                f"rigid_pole_hz = {ax.rigid_pole_hz:.6g}",
                f"gain_ratio = {ax.gain_ratio:.6g}",
                f"noise_rms_v = {ax.noise_rms_v:.6g}",
                f"residual_pct = [{res}]",
                "",
            ]
        atomic_write_text(write_to, "\n".join(lines))
    return out
