"""Line exposure, cure depth and line width from the beam speed (Jacobs working curve).

Seed 000 §4.3 observes that the printed line thickness follows the beam-velocity
variations. This module turns a beam-speed profile into a line-width profile with the
Jacobs working-curve model of a Gaussian beam scanned along a line:

* peak exposure on the line centre ``E_max = sqrt(2/π) · P / (w0 · v)`` [J/m²],
* cure depth ``C_d = D_p · ln(E_max / E_c)`` [m],
* cured line width ``L_w = w0 · sqrt(2 · ln(E_max / E_c))`` [m],

with ``C_d = L_w = 0`` where ``E_max <= E_c``. The model is quasi-steady: each sample
uses its local speed as if the beam moved at that speed forever. This is valid while
the speed changes little over the time ``w0 / v`` the beam needs to cross its own
width; at very low speeds (e.g. a turnaround that stops the beam) it overestimates the
exposure, which diverges as ``1/v`` instead of being bounded by the finite dwell time.

References
----------
Seed 000 (galvo-scanner micro-stereolithography with ILC), §4.3 "Printing Results" and
§2 (405 nm laser). P. F. Jacobs, *Rapid Prototyping & Manufacturing* (SME, 1992) for
the working curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from microfab.core.validate import check_positive

__all__ = [
    "ENVISIONTEC_R11_ASSUMED",
    "SEED000_BEAM",
    "BeamParams",
    "LineProfile",
    "ResinParams",
    "line_profile",
]


@dataclass(frozen=True, kw_only=True)
class ResinParams:
    """Working-curve parameters of a photo-resin.

    Attributes
    ----------
    penetration_depth_m : float
        Penetration depth ``D_p`` in m, > 0.
    critical_exposure_j_m2 : float
        Critical exposure ``E_c`` in J/m², > 0 (1 mJ/cm² = 10 J/m²).

    References
    ----------
    Jacobs working curve ``C_d = D_p ln(E / E_c)``.
    """

    penetration_depth_m: float
    critical_exposure_j_m2: float

    def __post_init__(self) -> None:
        check_positive("penetration_depth_m", self.penetration_depth_m, "m")
        check_positive("critical_exposure_j_m2", self.critical_exposure_j_m2, "J/m²")


#: Envisiontec R11 (the resin of seed 000 §4.3) with ASSUMED working-curve parameters.
#: The seed publishes no D_p or E_c; D_p = 100 µm and E_c = 100 J/m² (10 mJ/cm²) are
#: assumptions typical of acrylate resins at 405 nm, not values from the seed.
ENVISIONTEC_R11_ASSUMED = ResinParams(
    penetration_depth_m=100e-6,  # assumption (not in seed 000)
    critical_exposure_j_m2=100.0,  # assumption (not in seed 000): 10 mJ/cm²
)


@dataclass(frozen=True, kw_only=True)
class BeamParams:
    """Gaussian writing beam.

    Attributes
    ----------
    power_w : float
        Optical power at the resin in W, > 0. The seed's set laser power is used;
        losses in the optical path are ignored.
    waist_radius_m : float
        1/e² intensity radius ``w0`` of the focused spot in m, > 0. The default 5 µm
        is an ASSUMPTION (effective spot size), not a value from the seed; the
        diffraction limit of the seed's 0.3 NA objective would be about
        ``λ / (π · NA) ≈ 0.43 µm``.
    wavelength_m : float
        Laser wavelength in m, > 0 (informational; the working curve does not use it).

    References
    ----------
    Seed 000 §2 (405 nm diode laser, 0.3 NA objective) and §4.3 (30 mW).
    """

    power_w: float = 30e-3  # seed 000 §4.3: laser power set to 30 mW
    waist_radius_m: float = 5e-6  # assumption (not in seed 000): effective spot radius
    wavelength_m: float = 405e-9  # seed 000 §2: 405 nm diode laser

    def __post_init__(self) -> None:
        check_positive("power_w", self.power_w, "W")
        check_positive("waist_radius_m", self.waist_radius_m, "m")
        check_positive("wavelength_m", self.wavelength_m, "m")


#: The writing beam of seed 000 §4.3 (30 mW at 405 nm, assumed 5 µm spot radius).
SEED000_BEAM = BeamParams()


@dataclass(frozen=True)
class LineProfile:
    """Quasi-steady exposure, cure depth and width along a scanned line.

    Attributes
    ----------
    speed_m_s : np.ndarray
        Local beam speed, shape (n_samples,), in m/s.
    peak_exposure_j_m2 : np.ndarray
        Exposure on the line centre ``E_max``, shape (n_samples,), in J/m².
    cure_depth_m : np.ndarray
        Cure depth ``C_d``, shape (n_samples,), in m (0 where uncured).
    width_m : np.ndarray
        Cured line width ``L_w``, shape (n_samples,), in m (0 where uncured).

    References
    ----------
    Seed 000 §4.3 (line thickness uniformity).
    """

    speed_m_s: np.ndarray
    peak_exposure_j_m2: np.ndarray
    cure_depth_m: np.ndarray
    width_m: np.ndarray

    @property
    def width_mean_m(self) -> float:
        """Mean line width in m."""
        return float(np.mean(self.width_m))

    @property
    def width_std_m(self) -> float:
        """Standard deviation of the line width in m."""
        return float(np.std(self.width_m))

    @property
    def width_min_m(self) -> float:
        """Minimum line width in m."""
        return float(np.min(self.width_m))

    @property
    def width_max_m(self) -> float:
        """Maximum line width in m."""
        return float(np.max(self.width_m))

    @property
    def uniformity(self) -> float:
        """Coefficient of variation of the width, ``std / mean`` (dimensionless).

        Smaller is more uniform; ``nan`` when nothing is cured (mean width 0).
        """
        mean = self.width_mean_m
        if mean == 0:
            return float("nan")
        return self.width_std_m / mean


def line_profile(
    speed_m_s: np.ndarray,
    beam: BeamParams = SEED000_BEAM,
    resin: ResinParams = ENVISIONTEC_R11_ASSUMED,
) -> LineProfile:
    """Exposure, cure depth and width of a line scanned at a varying speed.

    Parameters
    ----------
    speed_m_s : np.ndarray
        Local beam speed, shape (n_samples,) (a scalar is taken as one sample), in m/s,
        each > 0. Convert from :class:`microfab.process.velocity.BeamVelocity` with
        ``speed_mm_s * 1e-3``.
    beam : BeamParams, optional
        Writing beam; defaults to seed 000 §4.3 (30 mW, assumed 5 µm radius).
    resin : ResinParams, optional
        Resin working curve; defaults to the ASSUMED Envisiontec R11 parameters.

    Returns
    -------
    LineProfile
        Per-sample peak exposure (J/m²), cure depth (m) and width (m).

    Raises
    ------
    ValueError
        If a speed is not positive and finite (the first offending sample is named).

    Notes
    -----
    Quasi-steady: valid while the speed varies slowly over the crossing time
    ``w0 / v``; at very low speeds the model overestimates exposure, depth and width.

    References
    ----------
    Seed 000 §4.3; Jacobs working curve.
    """
    v = np.atleast_1d(np.asarray(speed_m_s, dtype=float))
    if v.ndim != 1:
        raise ValueError(f"speed_m_s must have shape (n_samples,), got {v.shape}")
    if v.size == 0:
        raise ValueError("speed_m_s must hold at least one sample, got 0")
    bad = np.flatnonzero(~(np.isfinite(v) & (v > 0)))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"speed_m_s must be positive and finite; sample {i} is {v[i]} m/s "
            f"({bad.size} invalid sample(s))"
        )
    w0 = beam.waist_radius_m
    e_max = math.sqrt(2.0 / math.pi) * beam.power_w / (w0 * v)
    log_ratio = np.maximum(np.log(e_max / resin.critical_exposure_j_m2), 0.0)
    return LineProfile(
        speed_m_s=v,
        peak_exposure_j_m2=e_max,
        cure_depth_m=resin.penetration_depth_m * log_ratio,
        width_m=w0 * np.sqrt(2.0 * log_ratio),
    )
