"""The ILC learning run of the galvo MSL machine (seed 000): `run_msl_ilc`.

`run_msl_ilc` learns one scan rate (the square of seed 000 §4, both axes) for a number of
trials with the frequency-domain ILC (`microfab.control.ilc.FrequencyILC`) through the
one learning loop (`microfab.machines.learning.learn`) on the galvo twin
(`microfab.machines.galvo.twin`) or another `Machine`. With a state directory the learning
state and the twin's snapshot are saved as it goes (at least every `SAVE_EVERY_S`), so an
interrupted run resumes bit-identically. `MSLRunResult` holds what it measured: the
feedback-only and last trials, the learning curves, the eq. (5) convergence factor at
every learned harmonic, and the seed's error and beam-speed figures of one rate
(`MSLRunResult.table1_row`, `MSLRunResult.velocity_stats`); `axis_margins` gives the
feedback loops' margins (seed 000 §3.1). The ``msl-ilc`` job kind
(``microfab run``, `microfab.experiments.seed000_msl.job`) runs it per rate; its figures
are `microfab.report.galvo_ilc`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from microfab.control.ilc import FrequencyILC, ILCConfig
from microfab.control.margins import loop_margins
from microfab.machines.base import Machine
from microfab.machines.galvo import machine as galvo_machine
from microfab.machines.galvo.machine import complementary_sensitivity, open_loop
from microfab.machines.learning import learn
from microfab.plants.galvo import GalvoAxis
from microfab.process.exposure import (
    ENVISIONTEC_R11_ASSUMED,
    SEED000_BEAM,
    BeamParams,
    LineProfile,
    ResinParams,
    line_profile,
)
from microfab.process.velocity import BeamVelocity, BeamVelocityParams, beam_velocity
from microfab.trajectory.periodic import square_scan

__all__ = [
    "SAVE_EVERY_S",
    "BeamExposure",
    "MSLRunResult",
    "axis_margins",
    "beam_exposure",
    "run_msl_ilc",
    "square_reference",
]

#: Least wall time between two saves of the learning state on the twin, s. Assumed: a
#: killed run then replays at most 2 s of trials (bit-identical), and the state file,
#: which grows with the trials, is not rewritten after each ~1-10 ms trial.
SAVE_EVERY_S = 2.0

Progress = Callable[[int, int], None]


@dataclass(frozen=True, kw_only=True, eq=False)
class MSLRunResult:
    """Feedback-only and ILC results of one scan rate, both axes.

    All signals are one period, shape (N, n_axes), in encoder volts.

    Attributes
    ----------
    features_per_s : float
        Scan rate, features/s (laps of the square per second).
    dt : float
        Sample time, s.
    axes : tuple of str
        Axis names.
    reference : numpy.ndarray
        Desired output ``y_d``.
    fb_output : numpy.ndarray
        Measured output of trial 1 (``u_1 = y_d``: feedback only).
    ilc_output : numpy.ndarray
        Measured output of the last trial.
    ilc_input : numpy.ndarray
        Input applied in the last trial (``u_30`` of seed Fig. 4).
    rms_history, pp_history : numpy.ndarray
        Error RMS and peak-to-peak per trial, shape (n_trials, n_axes), V.
    scale_mm_per_v : tuple of float
        Beam position per encoder volt per axis, mm/V.
    noise_rms_v : tuple of float
        Encoder noise per axis, V.
    harmonics : list of numpy.ndarray
        Learned harmonic numbers per axis.
    eq5 : list of numpy.ndarray
        Per axis, ``|1 - rho P P^-1|`` at each learned harmonic (the true loop of the
        twin against the learned inverse; seed 000 eq. 5 asks for <= 1), in the order of
        ``harmonics``.
    """

    features_per_s: float
    dt: float
    axes: tuple[str, ...]
    reference: np.ndarray
    fb_output: np.ndarray
    ilc_output: np.ndarray
    ilc_input: np.ndarray
    rms_history: np.ndarray
    pp_history: np.ndarray
    scale_mm_per_v: tuple[float, ...]
    noise_rms_v: tuple[float, ...]
    harmonics: list[np.ndarray] = field(default_factory=list)
    eq5: list[np.ndarray] = field(default_factory=list)

    @property
    def fb_error(self) -> np.ndarray:
        """Feedback-only error ``y_1 - y_d``, V."""
        return self.fb_output - self.reference

    @property
    def ilc_error(self) -> np.ndarray:
        """Error of the last ILC trial, V."""
        return self.ilc_output - self.reference

    @property
    def period_s(self) -> float:
        """Scan period, s."""
        return self.reference.shape[0] * self.dt

    def to_mm(self, signal: np.ndarray) -> np.ndarray:
        """Encoder volts, shape (N, n_axes), to beam position, mm, per-axis scale."""
        return np.asarray(signal, dtype=float) * np.asarray(self.scale_mm_per_v)[np.newaxis, :]

    def velocity_params(self) -> BeamVelocityParams:
        """Seed 000 §4.2 beam-velocity settings with this run's mm/V scales."""
        return BeamVelocityParams(scale_mm_per_v=self.scale_mm_per_v)

    def beam_velocities(self) -> dict[str, BeamVelocity]:
        """Beam velocity of the FB (``"fb"``) and ILC (``"ilc"``) outputs (seed 000 §4.2)."""
        params = self.velocity_params()
        return {
            tag: beam_velocity(y, self.dt, params, periodic=True)
            for tag, y in (("fb", self.fb_output), ("ilc", self.ilc_output))
        }

    def velocity_stats(self) -> dict[str, float]:
        """Mean, std, min, max beam speed (mm/s) for FB and ILC (seed Table 2 keys)."""
        return _speed_stats(self.beam_velocities())

    def table1_row(self, axis: str) -> dict[str, float]:
        """RMS and PP (mV) of FB and ILC for one axis (seed Table 1 keys)."""
        a = self.axes.index(axis)
        fb, ilc = self.fb_error[:, a], self.ilc_error[:, a]
        return {
            "fb_rms": float(np.sqrt(np.mean(fb**2)) * 1e3),
            "fb_pp": float(np.ptp(fb) * 1e3),
            "ilc_rms": float(np.sqrt(np.mean(ilc**2)) * 1e3),
            "ilc_pp": float(np.ptp(ilc) * 1e3),
        }


def square_reference(axes: Mapping[str, GalvoAxis], features_per_s: float) -> np.ndarray:
    """One period of the square scan of seed 000 §4 on the first two axes, encoder V.

    Parameters
    ----------
    axes : mapping of str to GalvoAxis
        The axes; their ``amplitude_v`` sizes the square, the first one's ``fs_hz`` samples it.
    features_per_s : float
        Laps of the square per second.

    Returns
    -------
    numpy.ndarray
        Shape (N, 2), N samples per period at the first axis' sample rate.
    """
    ax = list(axes.values())
    return square_scan(features_per_s, (ax[0].amplitude_v, ax[1].amplitude_v), ax[0].fs_hz)


def run_msl_ilc(
    features_per_s: float = 400,
    iterations: int = 30,
    *,
    machine: Machine | None = None,
    axes: dict[str, GalvoAxis] | None = None,
    config: ILCConfig | None = None,
    seed: int = 0,
    state_dir: str | Path | None = None,
    check_convergence: bool = True,
    progress: Progress | None = None,
) -> MSLRunResult:
    """Learn the square scan at one rate on the twin (or a given machine).

    Parameters
    ----------
    features_per_s : float
        Scan rate, features/s (laps of the square per second; seed 000: 100, 200, 400);
        one period must be a whole number (>= 8) of samples at the axes' sample rate.
    iterations : int
        Number of trials (seed 000 §4: 30). Trial 1 is feedback only (``u_1 = y_d``).
    machine : Machine, optional
        Where to run; the calibrated galvo twin when omitted.
    axes : dict of str to GalvoAxis, optional
        Axis models (reference amplitudes, scales, noise, and the true FRF used to check
        eq. (5)); the calibrated defaults when omitted.
    config : ILCConfig, optional
        ILC settings; the seed's (8 kHz, rho 0.4) when omitted.
    seed : int
        Noise seed of the twin.
    state_dir : str or Path, optional
        Where the learning state is saved after every trial; an existing state there is
        resumed (the run continues to ``iterations`` trials).
    check_convergence : bool
        Check eq. (5) against the twin's true FRF.
    progress : callable, optional
        Called as ``progress(done, total)`` after each trial.

    Returns
    -------
    MSLRunResult
    """
    if iterations < 2:
        raise ValueError(f"iterations must be >= 2 (trial 1 is feedback only), got {iterations}")
    axes = axes or galvo_machine.calibrated_axes()
    names = tuple(axes)
    machine = machine or galvo_machine.twin(axes, seed=seed)
    ref = square_reference(axes, features_per_s)
    dt = machine.dt

    def true_frf(f: np.ndarray) -> np.ndarray:
        return np.column_stack([complementary_sensitivity(axes[a], f) for a in names])

    frf = true_frf if check_convergence else None
    if state_dir is not None and FrequencyILC.exists(state_dir):
        ilc = FrequencyILC.load(state_dir, true_frf=frf)
        if ilc.state.reference.shape != ref.shape or not np.allclose(
            ilc.state.reference, ref, rtol=0, atol=1e-12
        ):
            raise ValueError(f"the state in {state_dir} belongs to another reference")
    else:
        ilc = FrequencyILC(ref, dt, names, config, true_frf=frf)
    record = learn(
        machine, ilc, iterations=iterations, state_dir=state_dir, progress=progress,
        save_every_s=SAVE_EVERY_S,
    )  # fmt: skip
    fb_output, last_output = record.first_output, record.last_output
    last_input = record.last_input if record.last_input is not None else ilc.state.inputs[-2]
    assert fb_output is not None and last_output is not None
    return MSLRunResult(
        features_per_s=float(features_per_s),
        dt=dt,
        axes=names,
        reference=ref,
        fb_output=fb_output,
        ilc_output=last_output,
        ilc_input=last_input,
        rms_history=ilc.rms_history,
        pp_history=ilc.pp_history,
        scale_mm_per_v=tuple(axes[a].scale_mm_per_v for a in names),
        noise_rms_v=tuple(axes[a].noise_rms_v for a in names),
        harmonics=ilc.harmonics,
        eq5=_eq5(ilc, true_frf),
    )


def _eq5(ilc: FrequencyILC, true_frf: Callable[[np.ndarray], np.ndarray]) -> list[np.ndarray]:
    """``|1 - rho P P^-1|`` at each learned harmonic, per axis (seed 000 eq. 5)."""
    f = ilc.harmonic_freq_hz
    st = ilc.state
    out = []
    for a, h in enumerate(ilc.harmonics):  # the learned bins only (not all N/2 + 1)
        p = np.asarray(true_frf(f[h]), dtype=complex).reshape(h.size, -1)[:, a]
        out.append(np.abs(1.0 - st.gain[h, a] * p * st.pinv[h, a]))
    return out


def axis_margins(axes: Mapping[str, GalvoAxis]) -> dict[str, dict[str, float]]:
    """Gain and phase margins of each axis' feedback loop ``L = C G`` (seed 000 §3.1).

    Parameters
    ----------
    axes : mapping of str to GalvoAxis
        The axes (their discrete open loops, `microfab.machines.galvo.open_loop`).

    Returns
    -------
    dict
        Per axis: ``gm_db`` (dB), ``pm_deg`` (deg), ``gm_freq_hz`` and ``pm_freq_hz`` (Hz).
    """
    out = {}
    for name, ax in axes.items():
        m = loop_margins(open_loop(ax))
        out[name] = {
            "gm_db": m.gm_db,
            "pm_deg": m.pm_deg,
            "gm_freq_hz": m.gm_freq_hz,
            "pm_freq_hz": m.pm_freq_hz,
        }
    return out


#: Slowest speed passed to the exposure model, m/s: keeps the quasi-steady model finite
#: if the beam ever stops (it then overestimates the width anyway, see process/exposure.py).
_MIN_SPEED_M_S = 1e-6


@dataclass(frozen=True, kw_only=True, eq=False)
class BeamExposure:
    """Beam speed and the predicted cured line of one run, FB and ILC (seed 000 §4.2-4.3).

    Attributes
    ----------
    speed_mm_s : dict of str to numpy.ndarray
        ``"fb"`` and ``"ilc"``: beam speed per sample over the period, mm/s, shape (N,).
    stats : dict of str to float
        Mean, std, min, max speed of each (seed Table 2 keys, `MSLRunResult.velocity_stats`).
    line : dict of str to LineProfile
        ``"fb"`` and ``"ilc"``: exposure, cure depth and width per sample.
    target_speed_m_s : float
        Constant speed of the desired path (its perimeter over one period), m/s.
    target_width_m : float
        Line width at that speed, m.
    beam : BeamParams
    resin : ResinParams
    """

    speed_mm_s: dict[str, np.ndarray]
    stats: dict[str, float]
    line: dict[str, LineProfile]
    target_speed_m_s: float
    target_width_m: float
    beam: BeamParams
    resin: ResinParams


def beam_exposure(
    result: MSLRunResult,
    beam: BeamParams = SEED000_BEAM,
    resin: ResinParams = ENVISIONTEC_R11_ASSUMED,
) -> BeamExposure:
    """The beam speed of a run's FB and ILC outputs and the line each would cure.

    The speed is `microfab.process.velocity.beam_velocity` with the run's mm/V scales
    (seed 000 §4.2); the width the quasi-steady Jacobs working curve
    (`microfab.process.exposure.line_profile`, seed 000 §4.3).

    Parameters
    ----------
    result : MSLRunResult
        The run.
    beam : BeamParams, optional
        Writing beam (seed 000 §4.3: 30 mW; assumed spot radius).
    resin : ResinParams, optional
        Resin working curve (assumed Envisiontec R11 values).
    """
    velocities = result.beam_velocities()
    speed = {tag: bv.speed_mm_s for tag, bv in velocities.items()}
    line = {
        tag: line_profile(np.maximum(v * 1e-3, _MIN_SPEED_M_S), beam, resin)
        for tag, v in speed.items()
    }
    stats = _speed_stats(velocities)
    ref_mm = result.to_mm(result.reference)
    ref_mm = np.concatenate([ref_mm, ref_mm[:1]], axis=0)  # the closed path
    perimeter_mm = float(np.sum(np.hypot(*np.diff(ref_mm[:, :2], axis=0).T)))
    target_m_s = perimeter_mm * 1e-3 / result.period_s
    target = line_profile(np.array([target_m_s]), beam, resin)
    return BeamExposure(
        speed_mm_s=speed,
        stats=stats,
        line=line,
        target_speed_m_s=target_m_s,
        target_width_m=float(target.width_m[0]),
        beam=beam,
        resin=resin,
    )


def _speed_stats(velocities: Mapping[str, BeamVelocity]) -> dict[str, float]:
    """``<tag>_mean``, ``_std``, ``_min``, ``_max`` beam speed, mm/s (seed Table 2 keys)."""
    out: dict[str, float] = {}
    for tag, bv in velocities.items():
        out |= {f"{tag}_mean": bv.mean, f"{tag}_std": bv.std, f"{tag}_min": bv.min,
                f"{tag}_max": bv.max}  # fmt: skip
    return out
