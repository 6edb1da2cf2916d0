"""Identification, input shaping and scan time on the SLM galvo twin: `run_shaping`.

One run is seed 003 part 2's procedure, end to end, on the twin
(`microfab.machines.slm_galvo.twin`, `microfab.plants.galvo_slm`), on the user's
settings (`ShapingSettings`); the ``slm-shaping`` job kind (``microfab run``,
`microfab.experiments.seed003_slm.job`) runs it:

1. **Identify** (seed §1): play the chirp through the scanner's loop with the twin's
   seeded noise, estimate the FRF per period (`microfab.machines.slm_galvo.chirp_frf`)
   and fit ``G(s)`` by the ZOH-aware least squares (`microfab.identify`).
2. **Shape** (seed §2): invert the *fitted* model (`design_inverse_shaper`), both
   discretisations (the seed's ZOH, and ZPETC on the sampled axis), and measure lag,
   settling and time to 95 % speed (`microfab.control.shaping_metrics`).
3. **Validate** (seed §3, Figs. 6-7): one lattice cell's jump at the jump speed, from rest,
   without and with the shaper, through the compiled loop; the jump delay each needs
   (`process.slm.estimate.jump_delay`, 2 % band).
4. **Scan time** (seed §4): a layer (a lattice section or any drawing,
   `process.slm.source.scan_program`): naive, fixed-delay and dynamics-aware estimates,
   without and with the shaper (the shaper's own derived jump delay).

`ShapingRun` holds what it measured and its JSON summary (`ShapingRun.summary`, with the
fit beside the seed's identified ``G``). The side-by-side comparison of shapers
(`microfab.machines.slm_galvo.shapers`, ``microfab shaper compare``) and the whole build
(`microfab.process.slm.build`, ``microfab slm build``) are the job's optional parts. Every
part is seconds long. The figures are `microfab.report.slm`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from microfab.control.shaping import InverseShaper, InverseShaperConfig, design_inverse_shaper
from microfab.control.shaping_metrics import ramp_lag, ramp_speed_time, step_settling_time
from microfab.identify.chirp import Chirp, ChirpDesign
from microfab.identify.fit import FitResult, fit_tf
from microfab.identify.frf import FRF
from microfab.machines.slm_galvo import machine as slm_galvo
from microfab.machines.slm_galvo.machine import SEED_MODEL_DEN, SEED_MODEL_NUM
from microfab.plants.galvo_slm import GalvoSLMPlant
from microfab.process.slm.estimate import (
    ScanTimeComparison,
    SettleTolerance,
    estimate_with_shaper,
    jump_delay,
    series,
)
from microfab.process.slm.lattice import LatticeSpec
from microfab.process.slm.program import VectorPath
from microfab.process.slm.source import scan_program
from microfab.process.slm.timing import TICK_S, RTCSettings

__all__ = [
    "DISCRETIZATIONS",
    "SPEED_JUMP_S",
    "Identification",
    "IdentifySettings",
    "JumpResponse",
    "LayerSettings",
    "ShaperSettings",
    "ShapingRun",
    "ShapingSettings",
    "TwinSettings",
    "design_shapers",
    "identify_twin",
    "jump_response",
    "run_shaping",
]

Discretization = Literal["zoh", "zpetc"]
#: Length of the speed-validation jump at the jump speed, s (assumed: 2 ms, well past the
#: unshaped axis's 788 µs to 95 % speed, so that both runs reach it; Fig. 7).
SPEED_JUMP_S = 2e-3
DISCRETIZATIONS: tuple[Discretization, ...] = ("zoh", "zpetc")


# ---------------------------------------------------------------------------- settings
@dataclass(frozen=True, kw_only=True)
class TwinSettings:
    """Which twin and its noise.

    Parameters
    ----------
    seed : int
        Noise seed (>= 0).
    noise : bool
        The twin's 0.3 bit measurement noise on the identification and the jumps.
    mirror_mode : bool
        Add the twin's lightly damped mirror mode (assumed 3 kHz, ζ 0.02) to the truth.
    """

    seed: int = 0
    noise: bool = True
    mirror_mode: bool = False

    def twin(self) -> GalvoSLMPlant:
        """The twin of these settings."""
        return slm_galvo.twin(mirror_mode=self.mirror_mode)


@dataclass(frozen=True, kw_only=True)
class IdentifySettings:
    """The chirp experiment and the model fitted to it (seed 003 part 2 §1).

    Parameters
    ----------
    chirp : ChirpDesign
        The excitation (default the seed's 10 Hz-2 kHz, 100 bit, 1 s).
    n_poles, n_zeros : int
        Model orders (seed: 3 poles, no zeros).
    band_hz : (float, float), optional
        Band fitted (default the chirp's whole band).
    """

    chirp: ChirpDesign = field(default_factory=ChirpDesign)
    n_poles: int = 3  # seed 003 part 2 §1: a third-order model
    n_zeros: int = 0  # seed §1: G(s) has a constant numerator
    band_hz: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.chirp, ChirpDesign):
            raise ValueError(f"chirp must be a ChirpDesign, got {self.chirp!r}")
        if abs(self.chirp.dt - TICK_S) > 1e-12 * TICK_S:
            raise ValueError(
                f"the chirp's dt is {self.chirp.dt:g} s; the twin runs on {TICK_S:g} s ticks"
            )
        if not 1 <= self.n_poles <= 8:
            raise ValueError(f"n_poles must be 1 to 8, got {self.n_poles}")
        if not 0 <= self.n_zeros <= self.n_poles:
            raise ValueError(f"n_zeros must be 0 to n_poles = {self.n_poles}, got {self.n_zeros}")


@dataclass(frozen=True, kw_only=True)
class ShaperSettings:
    """The inverse shaper (seed 003 part 2 §2).

    Parameters
    ----------
    discretization : {"zoh", "zpetc"}
        The filter used for the layer and the validation jump (default ZPETC: on the
        10 µs axis the seed's ZOH filter loses half its gain in settling, see
        `microfab.control.shaping`); both are always designed and reported.
    pole_hz : float
        The added poles, Hz (seed: 2π·4000 rad/s by its coefficients).
    order : int
        How many poles are added (seed: four).
    """

    discretization: Discretization = "zpetc"
    pole_hz: float = 4000.0  # seed 003 part 2 §2, by its printed coefficients
    order: int = 4  # seed §2: "four added poles"

    def __post_init__(self) -> None:
        if self.discretization not in DISCRETIZATIONS:
            raise ValueError(
                f"discretization must be one of {', '.join(DISCRETIZATIONS)}, got "
                f"{self.discretization!r}"
            )
        self.config(self.discretization)  # validates pole_hz and order

    def config(self, discretization: Discretization) -> InverseShaperConfig:
        """The `InverseShaperConfig` of one discretisation."""
        return InverseShaperConfig(
            pole_hz=self.pole_hz, order=self.order, discretization=discretization
        )


@dataclass(frozen=True, kw_only=True)
class LayerSettings:
    """The layer whose scan time is estimated.

    Parameters
    ----------
    source : str
        ``lattice:key=value,...`` (a section of the seed's strut lattice,
        `process.slm.source.parse_lattice_source`) or a drawing (file or shape).
    hatch_spacing_m : float
        Hatch spacing of a drawing's inside, m (assumed 100 µm, as the lattice's).
    hatch_angle_deg : float
        Hatch direction, deg.
    """

    source: str = "lattice:z=8.2e-4,radius=8e-3"  # half a cell up: the cross-section of the struts
    hatch_spacing_m: float = 100e-6  # assumed, as LatticeSpec
    hatch_angle_deg: float = 0.0

    def program(self) -> VectorPath:
        """The layer's scan program (refuses an unknown source or an open contour)."""
        return scan_program(
            self.source,
            hatch_spacing_m=self.hatch_spacing_m,
            hatch_angle_deg=self.hatch_angle_deg,
        )


@dataclass(frozen=True, kw_only=True)
class ShapingSettings:
    """One ``slm-shaping`` run: twin, identification, shaper, layer and RTC settings.

    ``rtc`` holds the speeds and the fixed delays of the fixed-delay estimate (seed §4:
    750 µs jump delay without the shaper); ``tolerance`` the settling band of the
    derived delays (assumed 2 % of the jump).
    """

    twin: TwinSettings = field(default_factory=TwinSettings)
    identify: IdentifySettings = field(default_factory=IdentifySettings)
    shaper: ShaperSettings = field(default_factory=ShaperSettings)
    layer: LayerSettings = field(default_factory=LayerSettings)
    rtc: RTCSettings = field(default_factory=RTCSettings)
    tolerance: SettleTolerance = field(default_factory=SettleTolerance)
    jump_m: float = LatticeSpec().cell_m  # one lattice cell (seed §4 lattice), m


# ---------------------------------------------------------------------------- steps
@dataclass(frozen=True, eq=False)
class Identification:
    """The chirp experiment on the twin and the fitted model.

    Attributes
    ----------
    chirp : Chirp
        The input played.
    measured : numpy.ndarray
        The twin's measured x position, bit, shape (n,).
    frf : FRF
        Per-period FRF on the excited bins.
    fit : FitResult
        The fitted model (``fit.model``), its start and residuals.
    """

    chirp: Chirp
    measured: np.ndarray
    frf: FRF
    fit: FitResult


def identify_twin(
    twin: GalvoSLMPlant, settings: IdentifySettings, *, noise: bool = True, seed: int = 0
) -> Identification:
    """Play the chirp on the twin's x axis through its loop and fit the model.

    Raises
    ------
    ValueError
        From the fit: a band outside the excitation, too little coherence (named
        range), an unstable model.
    """
    chirp, y, frf = slm_galvo.chirp_frf(
        settings.chirp, noise_seed=seed if noise else None, plant=twin
    )
    fit = fit_tf(
        frf,
        n_poles=settings.n_poles,
        n_zeros=settings.n_zeros,
        dt=twin.dt,
        band_hz=settings.band_hz,
    )
    return Identification(chirp=chirp, measured=y, frf=frf, fit=fit)


def design_shapers(
    model: tuple[Any, Any], settings: ShaperSettings
) -> dict[Discretization, InverseShaper]:
    """The inverse shaper of ``model`` (``(num, den)``, s-domain), both discretisations."""
    return {d: design_inverse_shaper(model, settings.config(d)) for d in DISCRETIZATIONS}


@dataclass(frozen=True, eq=False)
class JumpResponse:
    """One jump from rest through the compiled loop (seed 003 part 2 Figs. 6-7).

    Attributes
    ----------
    time_s : numpy.ndarray
        Sample times, s, shape (n,).
    command : numpy.ndarray
        The RTC's jump vector (set position), bit, shape (n,).
    shaped : numpy.ndarray or None
        What reaches the axis when the shaper is on, bit, shape (n,).
    position : numpy.ndarray
        Measured position divided by the axis's static gain, bit, shape (n,).
    speed_m_s : numpy.ndarray
        Speed of the (noise-free) position at the work plane, m/s, shape (n,).
    """

    time_s: np.ndarray
    command: np.ndarray
    shaped: np.ndarray | None
    position: np.ndarray
    speed_m_s: np.ndarray


def jump_response(
    twin: GalvoSLMPlant,
    length_m: float,
    speed_m_s: float,
    shaper: InverseShaper | None = None,
    *,
    noise: bool = True,
    seed: int = 0,
    duration_s: float = 2e-3,
) -> JumpResponse:
    """A jump of ``length_m`` at ``speed_m_s`` on the x axis, with or without ``shaper``.

    The set position ramps from 0 at the jump speed and holds (the RTC's micro-steps);
    the shaped command must stay in the twin's field (refused otherwise, naming axis,
    time, value and limit). The speed is that of the noise-free position.
    """
    L = float(twin.to_bit(length_m))
    step = float(twin.to_bit(speed_m_s * twin.dt))
    n = round(duration_s / twin.dt) + 1
    command = np.minimum(np.arange(n) * step, L)
    field_bit = (-twin.config.field_bit, twin.config.field_bit - 1)
    shaped = None
    sent = command
    if shaper is not None:
        shaped = shaper.shape(command, dt=twin.dt, tail=0, bounds=field_bit, axes=("x",),
                              unit="bit")[:n]  # fmt: skip
        sent = shaped
    ref = np.column_stack([sent, np.zeros(n)])
    clean = slm_galvo.play(ref, plant=twin)[:, 0]
    # the set point does not read the measurement: the noisy run is the clean one plus noise
    pos = clean + twin.noise(n, seed)[:, 0] if noise else clean
    g0 = twin.static_gain
    speed = np.gradient(np.asarray(twin.to_m(clean / g0)), twin.dt)
    return JumpResponse(
        time_s=np.arange(n) * twin.dt,
        command=command,
        shaped=shaped,
        position=pos / g0,
        speed_m_s=speed,
    )


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class ShapingRun:
    """Everything one run measured (module doc).

    Attributes
    ----------
    settings : ShapingSettings
    identification : Identification
    shapers : dict
        ``{"zoh": InverseShaper, "zpetc": InverseShaper}`` from the fitted model.
    metrics : dict
        Continuous-design figures of the seed's ``G`` without and with the shaper, s:
        ``lag``, ``settling``, ``speed95`` (pairs), and the sampled settling per
        discretisation ``settling_sampled``.
    jumps : dict
        ``{"unshaped": JumpResponse, "shaped": JumpResponse}`` (the chosen discretisation),
        one ``jump_m`` jump (Fig. 6).
    speed_jumps : dict
        The same for a jump long enough to reach the jump speed (``SPEED_JUMP_S`` at
        speed, Fig. 7); ``metrics["speed95_loop"]`` holds the time each takes to reach
        95 % of the jump speed, s.
    jump_delay_s : dict
        Derived jump delay of one ``jump_m`` jump, s: ``unshaped``, ``zoh``, ``zpetc``.
    layer_vectors : int
        Vectors of the layer.
    scan : dict
        ``{"unshaped": ScanTimeComparison, "shaped": ScanTimeComparison}``; the shaped
        one runs with the chosen discretisation and its derived jump delay.
    """

    settings: ShapingSettings
    identification: Identification
    shapers: dict[Discretization, InverseShaper]
    metrics: dict[str, Any]
    jumps: dict[str, JumpResponse]
    speed_jumps: dict[str, JumpResponse]
    jump_delay_s: dict[str, float]
    layer_vectors: int
    scan: dict[str, ScanTimeComparison]

    @property
    def shaper(self) -> InverseShaper:
        """The shaper of the chosen discretisation."""
        return self.shapers[self.settings.shaper.discretization]

    @property
    def scan_cut(self) -> float:
        """Fraction of the dynamics-aware layer time the shaper saves."""
        a = self.scan["unshaped"].dynamics.total_s
        return 1.0 - self.scan["shaped"].dynamics.total_s / a

    def fit_coefficients(self) -> np.ndarray:
        """``b0; a2, a1, a0`` of a 3-pole all-pole fit (the seed's layout), else num + den."""
        m = self.identification.fit.model
        if m.n_zeros == 0:
            return np.array([m.num[-1], *m.den[1:]])
        return np.array([*m.num, *m.den[1:]])

    def fit_error(self) -> float | None:
        """Largest relative difference to the seed's coefficients (3 poles, no zeros)."""
        m = self.identification.fit.model
        if (m.n_poles, m.n_zeros) != (3, 0):
            return None
        seed = np.array([SEED_MODEL_NUM[0], *SEED_MODEL_DEN[1:]])
        return float(np.max(np.abs(self.fit_coefficients() / seed - 1.0)))

    def summary(self) -> dict[str, Any]:
        """The run's numbers, JSON-ready: times in µs, the fit beside the seed's ``G``."""
        met = self.metrics
        m = self.identification.fit
        return {
            "fit": {
                "coefficients": self.fit_coefficients().tolist(),
                "seed": [SEED_MODEL_NUM[0], *SEED_MODEL_DEN[1:]],
                "max_relative_error": self.fit_error(),
                "model": m.to_dict(),
            },
            "lag_us": [v * 1e6 for v in met["lag"]],
            "settling_us": [v * 1e6 for v in met["settling"]],
            "settling_sampled_us": {k: v * 1e6 for k, v in met["settling_sampled"].items()},
            "speed95_us": [v * 1e6 for v in met["speed95"]],
            "speed95_loop_us": [v * 1e6 for v in met["speed95_loop"]],
            "jump_delay_us": {k: v * 1e6 for k, v in self.jump_delay_s.items()},
            "layer": {
                "source": self.settings.layer.source,
                "vectors": self.layer_vectors,
                **{
                    k: {e.method: e.summary() for e in (c.naive, c.fixed, c.dynamics)}
                    for k, c in self.scan.items()
                },
            },
            "layer_s": [self.scan[k].dynamics.total_s for k in ("unshaped", "shaped")],
            "layer_cut": self.scan_cut,
            "discretization": self.settings.shaper.discretization,
        }


def run_shaping(settings: ShapingSettings | None = None, progress: Any = None) -> ShapingRun:
    """Identify, shape, validate and estimate the layer (module doc).

    Parameters
    ----------
    settings : ShapingSettings, optional
        Default: the seed's procedure on the default twin.
    progress : callable, optional
        ``progress(task, done, total)`` (as `microfab.experiments.kinds.Progress`).
    """
    s = ShapingSettings() if settings is None else settings
    say = progress if progress is not None else (lambda *_a: None)
    twin = s.twin.twin()
    say("chirp identification", 0, None)
    ident = identify_twin(twin, s.identify, noise=s.twin.noise, seed=s.twin.seed)
    m = ident.fit.model
    say("inverse shaper", 0, None)
    shapers = design_shapers((tuple(m.num), tuple(m.den)), s.shaper)
    G = (SEED_MODEL_NUM, SEED_MODEL_DEN)
    overall = shapers["zoh"].overall()
    metrics: dict[str, Any] = {
        "lag": (ramp_lag(G), ramp_lag(overall)),
        "settling": (step_settling_time(G), step_settling_time(overall)),
        "speed95": (ramp_speed_time(G), ramp_speed_time(overall)),
    }
    say("validation jumps", 0, None)
    v_jump = s.rtc.speeds.jump_m_s
    chosen = shapers[s.shaper.discretization]
    jumps = {
        "unshaped": jump_response(twin, s.jump_m, v_jump, noise=s.twin.noise, seed=s.twin.seed),
        "shaped": jump_response(
            twin, s.jump_m, v_jump, chosen, noise=s.twin.noise, seed=s.twin.seed
        ),
    }
    long_m = v_jump * SPEED_JUMP_S
    speed_jumps = {
        key: jump_response(twin, long_m, v_jump, sh, noise=False, duration_s=2 * SPEED_JUMP_S)
        for key, sh in (("unshaped", None), ("shaped", chosen))
    }
    metrics["speed95_loop"] = tuple(
        _first_reach(r.speed_m_s, 0.95 * v_jump, twin.dt) for r in speed_jumps.values()
    )
    axis = twin.axis_model
    shaped_axes = {d: series(sh.to_lti(), axis) for d, sh in shapers.items()}
    jd = {"unshaped": jump_delay(axis, s.jump_m, settings=s.rtc, tolerance=s.tolerance)}
    for d, model in shaped_axes.items():
        jd[d] = jump_delay(model, s.jump_m, settings=s.rtc, tolerance=s.tolerance)
    metrics["settling_sampled"] = {
        "unshaped": _sampled_settling(axis, s.tolerance.relative),
        **{d: _sampled_settling(mdl, s.tolerance.relative) for d, mdl in shaped_axes.items()},
    }
    say("layer scan time", 0, None)
    program = s.layer.program()
    # the shaper's own derived jump delay (at least one tick) for the fixed estimate
    rtc_shaped = s.rtc.with_delays(jump_s=max(_ticks_up(jd[s.shaper.discretization]), TICK_S))
    scan = estimate_with_shaper(
        program,
        axis,
        s.rtc,
        prefilter=shapers[s.shaper.discretization].to_lti(),
        shaped_settings=rtc_shaped,
        tolerance=s.tolerance,
    )
    return ShapingRun(
        settings=s,
        identification=ident,
        shapers=shapers,
        metrics=metrics,
        jumps=jumps,
        speed_jumps=speed_jumps,
        jump_delay_s=jd,
        layer_vectors=len(program),
        scan=scan,
    )


def _first_reach(signal: np.ndarray, level: float, dt: float) -> float:
    """First time ``signal`` reaches ``level``, s (NaN if it never does)."""
    k = np.flatnonzero(signal >= level)
    return float(k[0] * dt) if k.size else float("nan")


def _ticks_up(t_s: float) -> float:
    """``t_s`` rounded up to whole 10 µs ticks, s."""
    return float(np.ceil(t_s / TICK_S - 1e-9)) * TICK_S


def _sampled_settling(model: Any, band: float) -> float:
    """Settling (``band``) of a unit step through a sampled SISO model, s."""
    import scipy.signal

    from microfab.control.shaping_metrics import settling_time

    _t, y, _x = scipy.signal.dlsim((model.A, model.B, model.C, model.D, model.dt), np.ones(400))
    return settling_time(np.ravel(y), model.dt, band=band)
