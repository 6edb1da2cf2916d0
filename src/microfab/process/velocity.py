"""Beam velocity from encoder outputs, as evaluated in seed 000 §4.2.

The encoder outputs (volts) of the x and y galvanometer scanners are differentiated,
low-pass filtered with a zero-phase 4th-order Butterworth filter of 20 kHz bandwidth,
scaled by 0.3 mm/V and combined into the beam speed ``sqrt(vx² + vy²)``.

References
----------
Seed 000 (galvo-scanner micro-stereolithography with ILC), §4.2 "Beam Velocity
Evaluation", Fig. 7 and Table 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from microfab.core.validate import check_int, check_positive

__all__ = [
    "SEED000_BEAM_VELOCITY",
    "BeamVelocity",
    "BeamVelocityParams",
    "beam_velocity",
    "target_speed_mm_s",
]


@dataclass(frozen=True, kw_only=True)
class BeamVelocityParams:
    """Parameters of the beam-velocity evaluation.

    Attributes
    ----------
    cutoff_hz : float
        Cut-off frequency of the low-pass Butterworth filter in Hz, > 0; must also be
        below the Nyquist frequency ``1/(2·dt)``, checked by :func:`beam_velocity`.
    order : int
        Order of the Butterworth filter, >= 1. Applied forward and backward, so the
        effective magnitude response is squared and the phase is zero.
    scale_mm_per_v : tuple of float
        Encoder-to-beam-position scale per axis in mm/V, each > 0. A single value is
        applied to every axis. Note: seed 000 §4.3 quotes encoder amplitudes of 1 V (x)
        and 1.44 V (y) for the same 0.6 mm square, which is inconsistent with one common
        0.3 mm/V; the seed's common value is used by default.

    References
    ----------
    Seed 000 §4.2.
    """

    cutoff_hz: float = 20e3  # seed 000 §4.2: Butterworth bandwidth 20 kHz, zero phase
    order: int = 4  # seed 000 §4.2: 4th-order low-pass Butterworth
    scale_mm_per_v: tuple[float, ...] = (0.3, 0.3)  # seed 000 §4.2: scaled by 0.3 mm/V

    def __post_init__(self) -> None:
        check_positive("cutoff_hz", self.cutoff_hz, "Hz")
        check_int("order", self.order, 1)
        scale = tuple(float(s) for s in np.atleast_1d(self.scale_mm_per_v))
        if len(scale) == 0:
            raise ValueError("scale_mm_per_v must hold at least one value, got () mm/V")
        for i, s in enumerate(scale):
            check_positive(f"scale_mm_per_v[{i}]", s, "mm/V")
        object.__setattr__(self, "order", int(self.order))
        object.__setattr__(self, "scale_mm_per_v", scale)


#: The evaluation of seed 000 §4.2 (20 kHz, 4th order, 0.3 mm/V on both axes).
SEED000_BEAM_VELOCITY = BeamVelocityParams()


@dataclass(frozen=True)
class BeamVelocity:
    """Beam velocity and speed along a trajectory.

    Attributes
    ----------
    speed_mm_s : np.ndarray
        Beam speed ``sqrt(sum(v_i²))``, shape (n_samples,), in mm/s.
    velocity_mm_s : np.ndarray
        Filtered velocity per axis, shape (n_samples, n_axes), in mm/s.
    dt : float
        Sample period in s.

    References
    ----------
    Seed 000 §4.2, Table 2 (mean, standard deviation, minimum, maximum).
    """

    speed_mm_s: np.ndarray
    velocity_mm_s: np.ndarray
    dt: float

    @property
    def mean(self) -> float:
        """Mean beam speed in mm/s."""
        return float(np.mean(self.speed_mm_s))

    @property
    def std(self) -> float:
        """Standard deviation of the beam speed in mm/s."""
        return float(np.std(self.speed_mm_s))

    @property
    def min(self) -> float:
        """Minimum beam speed in mm/s."""
        return float(np.min(self.speed_mm_s))

    @property
    def max(self) -> float:
        """Maximum beam speed in mm/s."""
        return float(np.max(self.speed_mm_s))

    def max_rel_error(self, target_mm_s: float) -> float:
        """Largest relative deviation of the speed from a target.

        Parameters
        ----------
        target_mm_s : float
            Target speed in mm/s, > 0.

        Returns
        -------
        float
            ``max |speed - target| / target``, dimensionless (seed 000 §4.2 reports
            45.8 % with feedback and 14.6 % with ILC at 400 features/s).
        """
        check_positive("target_mm_s", target_mm_s, "mm/s")
        return float(np.max(np.abs(self.speed_mm_s - target_mm_s)) / target_mm_s)


def _min_samples(sos: np.ndarray) -> int:
    """Smallest record length accepted by ``sosfiltfilt`` with its default padding."""
    n_sections = sos.shape[0]
    zeros_b = int(np.sum(sos[:, 2] == 0))
    zeros_a = int(np.sum(sos[:, 5] == 0))
    padlen = 3 * (2 * n_sections + 1 - min(zeros_b, zeros_a))
    return padlen + 1


def beam_velocity(
    positions: np.ndarray,
    dt: float,
    params: BeamVelocityParams = SEED000_BEAM_VELOCITY,
    *,
    periodic: bool = False,
) -> BeamVelocity:
    """Beam velocity from encoder positions (seed 000 §4.2).

    Each axis is differentiated with ``np.gradient`` (second-order central differences
    inside, first-order one-sided at the ends), low-pass filtered with
    ``scipy.signal.butter(order, cutoff_hz, fs=1/dt, output='sos')`` applied zero-phase
    by ``scipy.signal.sosfiltfilt`` (default odd padding), scaled by its mm/V factor,
    and the speed is the Euclidean norm of the axis velocities.

    Parameters
    ----------
    positions : np.ndarray
        Encoder outputs, shape (n_samples, n_axes) (or (n_samples,) for one axis), in V.
    dt : float
        Sample period in s, > 0.
    params : BeamVelocityParams, optional
        Filter and scale; defaults to the seed's evaluation.
    periodic : bool, optional
        If True, the record is taken as an integer number of periods of a periodic
        signal (sample ``n_samples`` would equal sample 0): it is tiled three times,
        differentiated and filtered, and the middle copy is kept, so there are no edge
        effects. If False (default), the ends carry the one-sided difference and the
        filter's start-up transient.

    Returns
    -------
    BeamVelocity
        Speed (n_samples,) and velocity (n_samples, n_axes), in mm/s.

    Raises
    ------
    ValueError
        If ``dt`` is not positive, the cut-off is not below Nyquist, the number of axes
        does not match ``scale_mm_per_v``, or the record is too short for the filter.

    References
    ----------
    Seed 000 §4.2.
    """
    pos = np.asarray(positions, dtype=float)
    if pos.ndim == 1:
        pos = pos[:, np.newaxis]
    if pos.ndim != 2:
        raise ValueError(f"positions must have shape (n_samples, n_axes), got {pos.shape}")
    if not np.all(np.isfinite(pos)):
        raise ValueError("positions must be finite; found NaN or inf")
    check_positive("dt", dt, "s")
    fs = 1.0 / dt
    if params.cutoff_hz >= fs / 2:
        raise ValueError(
            f"cutoff_hz = {params.cutoff_hz} Hz must be below the Nyquist frequency "
            f"{fs / 2} Hz (dt = {dt} s)"
        )
    n, n_axes = pos.shape
    scale = np.asarray(params.scale_mm_per_v, dtype=float)
    if scale.size == 1:
        scale = np.full(n_axes, scale[0])
    if scale.size != n_axes:
        raise ValueError(f"scale_mm_per_v has {scale.size} values but positions has {n_axes} axes")
    sos = scipy.signal.butter(params.order, params.cutoff_hz, fs=fs, output="sos")
    n_min = 2 if periodic else _min_samples(sos)
    if n < n_min:
        raise ValueError(
            f"positions has {n} samples; at least {n_min} are needed for an order-"
            f"{params.order} zero-phase filter"
        )
    if periodic:
        tiled = np.concatenate([pos, pos, pos], axis=0)
        vel = scipy.signal.sosfiltfilt(sos, np.gradient(tiled, dt, axis=0), axis=0)
        vel = vel[n : 2 * n]
    else:
        vel = scipy.signal.sosfiltfilt(sos, np.gradient(pos, dt, axis=0), axis=0)
    vel_mm_s = vel * scale[np.newaxis, :]
    speed = np.sqrt(np.sum(np.square(vel_mm_s), axis=1))
    return BeamVelocity(speed_mm_s=speed, velocity_mm_s=vel_mm_s, dt=float(dt))


def target_speed_mm_s(side_mm: float, rate_features_per_s: float) -> float:
    """Target beam speed for a square traced once per feature.

    Parameters
    ----------
    side_mm : float
        Side length of the square in mm, > 0 (seed 000 §4.2: 0.6 mm).
    rate_features_per_s : float
        Feature rate in features/s (squares per second), > 0.

    Returns
    -------
    float
        ``4 · side_mm · rate_features_per_s`` in mm/s (seed 000 §4.2: 240, 480 and
        960 mm/s at 100, 200 and 400 features/s for the 0.6 mm square).

    References
    ----------
    Seed 000 §4.2.
    """
    check_positive("side_mm", side_mm, "mm")
    check_positive("rate_features_per_s", rate_features_per_s, "features/s")
    return 4.0 * side_mm * rate_features_per_s
