"""Shapers side by side on both SLM galvo twins (issue 16 §3, seed 003 part 2).

`compare_shapers` runs one jump and one ramp through every shaper on one twin and reads
the same figures off each: residual vibration over 0.8-1.2 f, added delay, command peak,
2 % settling and ramp lag. Rows: ``"unshaped"``, ``"inverse"`` (the seed's model-inverse
shaper, §2), each classic shaper of `microfab.control.shapers.SHAPERS` asked for, and
``"inverse+zv"``.

**Twins.** ``"seed"``: `microfab.plants.galvo_slm.galvo_slm_twin` (the seed's 3rd-order
``G``, ZOH at 10 µs). ``"mirror"``: the same with the optional mirror mode (3 kHz,
``zeta`` 0.02, assumed; ``mirror_mode=True``).

**The mode each twin's classic shapers target** (and at which every row's ``V`` is
measured, ``ShaperComparison.mode_hz``, ``damping``: the twin's true mode):

* seed twin: ``G``'s complex pair, 965.2 Hz, ``zeta`` 0.4995 (seed 003 §1 via
  `GalvoSLMParams.factors`). At that damping Klipper's EI-family closed forms miss their
  constraints, so `design_shaper` solves them numerically (EI); the 2-hump and 3-hump EI
  families end below it (near 0.448 and 0.276) and those rows are refused at design
  (``refused`` holds the design's message, every figure NaN, the arrays empty).
* mirror twin: the 3 kHz mode. The inverse is designed from the seed's ``G`` and does
  not know the mode (the robustness study of issue 16 §1).

**Design from the twin's chirp** (``frf_noise=True``, default): a chirp (10 Hz to 2 kHz
on the seed twin, the seed's band; to 6 kHz on the mirror twin, assumed, so that it sees
the mode; 100 bit, 0.1 s periods, four played and the first dropped) runs through the
scanner's loop with the twin's 0.3 bit noise (seeded) and gives the FRF
(`microfab.machines.slm_galvo.chirp_frf`), and the mode is read off it: on the seed twin
the complex pair of the ZOH-aware 3-pole fit (`microfab.identify.fit_tf`, as ``reproduce
slm-shaper``); on the mirror twin a 2-pole fit of the FRF divided by the seed's ``G``
(ZOH, the model the inverse cancels) over 0.7-1.3 times its peak. Each classic shaper is
then designed at that frequency and damping (`design_shaper`).
`microfab.control.shaper_fit.fit_shaper` (Klipper's auto-tune) is not used for the rows:
its score trades remaining vibration against delay and only asks for ``V`` below 1/20 at
the measured peak, so on the mirror twin's FRF (design dampings 0.01-0.05 scanned over
1.5-6 kHz) it moves MZV, ZVD and the EI family up to 3.1-5.9 kHz, where their worst ``V``
over 0.8-1.2 f is 21-26 % instead of their designs' 9 % (ZVD) and 5 % (EI family); on the
seed twin the pair (``zeta`` 0.5) makes no peak for it to find. A comparison of shapers
*for a mode* designs them for the mode. ``frf_noise=False`` designs them at the true
mode.

**Figures** (one row each; all on 10 µs samples, no noise, positions calibrated by
``1 / G(0)`` as in `microfab.process.slm.estimate`):

* ``vibration``: worst residual vibration over ``0.8 f .. 1.2 f`` (401 frequencies, the
  mode's damping). Impulse shapers: Singer-Seering's ``V`` of the *sampled* taps
  (`ImpulseShaper.sampled_vibration`, the convention their ``v_tol`` is designed in);
  the inverse: ``|S_d(e^{s_p dt})| / S_d(1)`` with its look-ahead
  (`InverseShaper.vibration`, equal-time: an IIR filter has no last impulse);
  ``"inverse+zv"``: the product of the two; ``"unshaped"``: 1 by definition.
* ``delay_s``: the command filter's own ramp lag as applied, i.e. its group delay at DC
  less its look-ahead, `microfab.control.shaping_metrics.discrete_lag` minus
  ``preview dt``: an impulse shaper's centroid (exactly: its taps interpolate), the
  inverse's negative lead (it removes ``G``'s lag). ``look_ahead_s`` says how far ahead
  the command must be known (ZPETC: 2 ticks).
* ``command_peak``: largest ``|command - start| / jump`` of the shaped step.
* ``settling_s``: 2 % settling (``band`` of the jump) of the calibrated position after
  the step, `microfab.control.shaping_metrics.settling_time` on the sampled series (the
  approach of the sampled settling of `microfab.machines.slm_galvo.shaping`, with the
  shaped command simulated through the twin's axis model by `scipy.signal.dlsim`).
* ``lag_s``: the calibrated position's steady lag behind an unshaped ramp, read on the
  sampled series (``G``'s 453.9 µs plus the ZOH's half tick plus the shaper's delay).

**Jump and refusal.** The step is ``jump_bit`` (default 1000 bit = 1.5 mm, about one
lattice cell, the seed's typical jump) from ``start_bit`` (default 0, mid-field, where a part
is usually centred; assumed). Near the field edge (e.g. ``start_bit = 30000``) the
inverse-shaped step leaves the field. Each shaped step is checked
against the twin's field (``±field_bit``) by `check_shaped_command`; a command that
leaves it (the inverse: about 22x the jump) is refused and the row records the
`ShapedCommandError` message (axis, time from the record's start, value, bound). The
figures are still those of the jump as shaped (the dynamics are linear, the same at any
start). The declared velocity and acceleration limits are not checked here: a step is
no vector at a jump speed and exceeds them unshaped too. The record starts one tick
before the jump (``t_s[0] = -dt``).

``microfab shaper compare`` runs it; its table is
`microfab.report.slm_tables.comparison_table`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Literal, TypeAlias

import numpy as np
import scipy.signal

from microfab.control.shaped_command import ShapedCommandError, filter_command
from microfab.control.shapers import DEFAULT_V_TOL, SHAPER_NAMES, ImpulseShaper, design_shaper
from microfab.control.shaping import (
    Discretization,
    InverseShaper,
    InverseShaperConfig,
    design_inverse_shaper,
)
from microfab.control.shaping_metrics import discrete_lag, settling_time
from microfab.core.arrays import readonly
from microfab.core.validate import check_in_range, check_int, check_positive
from microfab.identify.chirp import ChirpDesign
from microfab.identify.fit import fit_tf
from microfab.identify.frf import FRF
from microfab.machines.slm_galvo import machine as slm_galvo
from microfab.plants.galvo_slm import GalvoSLMPlant

__all__ = [
    "ROW_COMBINED",
    "ROW_INVERSE",
    "ROW_UNSHAPED",
    "CompareSettings",
    "ShaperComparison",
    "ShaperRow",
    "TwinName",
    "compare_shapers",
]

TwinName: TypeAlias = Literal["seed", "mirror"]
ROW_UNSHAPED = "unshaped"
ROW_INVERSE = "inverse"
ROW_COMBINED = "inverse+zv"

_BAND = (0.8, 1.2)  # issue 16 §3: V over 0.8-1.2 f
_N_BAND = 401  # frequencies evaluated over the band (band_vibration's default)
_RECORD = 4096  # samples of the first step and ramp records (41 ms), doubled until settled
_MAX_RECORD = 1 << 18  # 2.6 s: a row that has not settled by then is a bug
_RAMP_CHECK = 100  # the ramp lag must agree over this many final samples (steady state)
_CHIRP_PERIOD_S = 0.1  # assumed: 10 Hz bins, 4 periods = 0.4 s of chirp (fast)
_CHIRP_F1_HZ = {"seed": 2000.0, "mirror": 6000.0}  # seed §1 band; assumed past the mode
_MODE_FIT_SPAN = (0.7, 1.3)  # mirror mode: 2-pole fit over 0.7-1.3 times the FRF peak


@dataclass(frozen=True, kw_only=True)
class CompareSettings:
    """What `compare_shapers` does (see the module for each figure).

    Parameters
    ----------
    jump_bit : float
        Step used for settling, command peak and the field check, bit (default 1000 bit
        = 1.5 mm at 1.5 µm/bit: about one lattice cell, 1.64 mm, the seed's jump; assumed).
    start_bit : float
        Position before the step, bit (default 0: mid-field, assumed; from 30000 bit,
        near the +32768 bit edge, the inverse-shaped step leaves the field and is refused).
    band : float
        Settling band, fraction of the jump (default 0.02: issue 16's 2 %).
    v_tol : float
        Vibration tolerance of the EI-family shapers, in (0, 0.25] (default 5 %).
    inverse : {"zoh", "zpetc"}
        Discretisation of the model-inverse shaper (default ZPETC: it keeps the continuous
        design's gain on the 10 µs axis; "zoh" is the seed's filter).
    shapers : tuple of str
        Classic shapers to compare (`microfab.control.shapers.SHAPER_NAMES`).
    frf_noise : bool
        Design the classic shapers at the mode identified from the twin's noisy chirp FRF
        (default) rather than at the true mode.
    """

    jump_bit: float = 1000.0  # assumed: ~ one lattice cell (1.64 mm) at 1.5 µm/bit
    start_bit: float = 0.0  # assumed: mid-field, where a part is usually centred
    band: float = 0.02  # issue 16: 2 % settling band
    v_tol: float = DEFAULT_V_TOL
    inverse: Discretization = "zpetc"
    shapers: tuple[str, ...] = SHAPER_NAMES
    frf_noise: bool = True

    def __post_init__(self) -> None:
        check_positive("jump_bit", self.jump_bit, "bit")
        if not math.isfinite(self.start_bit):
            raise ValueError(f"start_bit must be finite, got {self.start_bit} bit")
        check_in_range("band", self.band, 0.0, 1.0, "(fraction of the jump)", low_closed=False)
        check_in_range("v_tol", self.v_tol, 0.0, 0.25, "(fraction)", low_closed=False)
        if self.inverse not in ("zoh", "zpetc"):
            raise ValueError(
                f"inverse must be 'zoh' (the seed's filter) or 'zpetc' (inverse of the "
                f"sampled axis), got {self.inverse!r}"
            )
        object.__setattr__(self, "shapers", tuple(self.shapers))
        for name in self.shapers:
            if name not in SHAPER_NAMES:
                raise ValueError(
                    f"unknown shaper {name!r} in shapers; known: {', '.join(SHAPER_NAMES)}"
                )
        if len(set(self.shapers)) != len(self.shapers):
            raise ValueError(f"shapers lists a name twice: {self.shapers}; give each once")
        if not isinstance(self.frf_noise, bool):
            raise ValueError(f"frf_noise must be true or false, got {self.frf_noise!r}")


@dataclass(frozen=True, kw_only=True, eq=False)
class ShaperRow:
    """One shaper's figures on one twin (see the module for their definitions).

    Attributes
    ----------
    name : str
        ``"unshaped"``, ``"inverse"``, a classic shaper's name, or ``"inverse+zv"``.
    mode_hz, damping : float
        The twin's mode at which ``vibration`` is measured, Hz and 1 (every row).
    design_hz, design_damping : float
        The mode the row's impulse shaper was designed for (NaN: unshaped, inverse).
    vibration : float
        Worst residual vibration over 0.8-1.2 ``mode_hz``, fraction (1 unshaped).
    delay_s : float
        Added delay (ramp lag of the command filter, negative when it leads), s.
    look_ahead_s : float
        How far ahead the command is read (ZPETC's preview), s.
    command_peak : float
        Largest ``|command - start| / jump`` of the shaped step.
    settling_s : float
        2 % settling of the step on the twin, s (from the step).
    lag_s : float
        Ramp lag on the twin, s.
    refused : str or None
        The field check's message when the shaped step leaves the field, or the design's
        refusal (then every figure is NaN and the arrays empty); None when emitted.
    t_s, command, position : numpy.ndarray
        The step record (read-only), shape (n,): time from the step (s), shaped command
        and calibrated position (bit).
    """

    name: str
    mode_hz: float
    damping: float
    design_hz: float
    design_damping: float
    vibration: float
    delay_s: float
    look_ahead_s: float
    command_peak: float
    settling_s: float
    lag_s: float
    refused: str | None
    t_s: np.ndarray
    command: np.ndarray
    position: np.ndarray

    def __post_init__(self) -> None:
        for name in ("t_s", "command", "position"):
            object.__setattr__(self, name, readonly(getattr(self, name)))

    def summary(self) -> dict[str, Any]:
        """The row without its arrays, NaN as None (JSON-ready)."""
        out: dict[str, Any] = {"name": self.name, "refused": self.refused}
        for key in (
            "mode_hz",
            "damping",
            "design_hz",
            "design_damping",
            "vibration",
            "delay_s",
            "look_ahead_s",
            "command_peak",
            "settling_s",
            "lag_s",
        ):
            v = float(getattr(self, key))
            out[key] = v if math.isfinite(v) else None
        return out


@dataclass(frozen=True, kw_only=True, eq=False)
class ShaperComparison:
    """The rows of one twin (`compare_shapers`).

    Attributes
    ----------
    twin : str
        ``"seed"`` or ``"mirror"``.
    mode_hz, damping : float
        The twin's true mode (the classic shapers' target, where ``V`` is measured).
    rows : tuple of ShaperRow
        Unshaped, inverse, the classic shapers in settings order, inverse+zv.
    settings : CompareSettings
        What was run.
    """

    twin: str
    mode_hz: float
    damping: float
    rows: tuple[ShaperRow, ...]
    settings: CompareSettings

    def row(self, name: str) -> ShaperRow:
        """The row called ``name`` (KeyError naming the rows there)."""
        for r in self.rows:
            if r.name == name:
                return r
        raise KeyError(f"no row {name!r}; rows: {', '.join(r.name for r in self.rows)}")

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary: twin, mode, settings and each row's figures (no arrays)."""
        settings = asdict(self.settings)
        settings["shapers"] = list(self.settings.shapers)
        return {
            "twin": self.twin,
            "mode_hz": self.mode_hz,
            "damping": self.damping,
            "settings": settings,
            "rows": [r.summary() for r in self.rows],
        }


@dataclass(frozen=True, eq=False)
class _Filter:
    """A command filter as applied: ``b / a`` in powers of ``z^-1``, read ``advance`` ahead."""

    b: np.ndarray
    a: np.ndarray
    advance: int
    inverse: InverseShaper | None = None
    impulse: ImpulseShaper | None = None

    def vibration(self, freq_hz: np.ndarray, damping: float, dt: float) -> np.ndarray:
        """``V`` at ``freq_hz`` (module doc: Singer-Seering, equal-time, or their product)."""
        v = np.ones(freq_hz.size)
        if self.inverse is not None:
            v = v * self.inverse.vibration(freq_hz, damping, discrete=True)
        if self.impulse is not None:
            v = v * self.impulse.sampled_vibration(dt, freq_hz, damping)
        return v

    def shape(self, command: np.ndarray, dt: float, **check: Any) -> np.ndarray:
        """The shaped command, as long as ``command`` (from rest at its first sample)."""
        return filter_command(command, self.b, self.a, dt=dt, advance=self.advance, **check)


def _filter(inverse: InverseShaper | None, impulse: ImpulseShaper | None, dt: float) -> _Filter:
    b, a, adv = np.ones(1), np.ones(1), 0
    if inverse is not None:
        b, a, adv = np.asarray(inverse.num_d), np.asarray(inverse.den_d), inverse.preview
    if impulse is not None:
        b = np.convolve(b, impulse.taps(dt))
    return _Filter(b, a, adv, inverse, impulse)


def _twin(name: str) -> GalvoSLMPlant:
    if name not in ("seed", "mirror"):
        raise ValueError(
            f"twin must be 'seed' (the seed's 3rd-order model) or 'mirror' (with the 3 kHz "
            f"mirror mode), got {name!r}"
        )
    return slm_galvo.twin(mirror_mode=name == "mirror")


def _true_mode(twin: GalvoSLMPlant) -> tuple[float, float]:
    """The mode the classic shapers target: the mirror mode, or ``G``'s complex pair."""
    c = twin.config
    if twin.mirror_mode:
        return c.mirror_mode_hz, c.mirror_mode_damping
    _a, wn, zeta = c.factors()
    return wn / (2.0 * math.pi), zeta


def _identified_mode(twin: GalvoSLMPlant, name: str, seed: int) -> tuple[float, float]:
    """The mode read off the twin's noisy chirp FRF (module doc), Hz and 1."""
    design = ChirpDesign(f1_hz=_CHIRP_F1_HZ[name], period_s=_CHIRP_PERIOD_S)
    _chirp, _y, frf = slm_galvo.chirp_frf(design, noise_seed=seed, plant=twin)
    if not twin.mirror_mode:
        mode = fit_tf(frf, dt=twin.dt).model.complex_modes[0]  # ZOH-aware, 3 poles (seed §1)
        return mode.frequency_hz, mode.damping
    # the mode over the seed's G (ZOH at dt): the model the inverse already cancels
    base = slm_galvo.twin().axis_model.frequency_response(frf.freq_hz)[:, 0, 0]
    ratio = frf.response / base
    f_peak = float(frf.freq_hz[np.argmax(np.abs(ratio))])
    over = FRF(
        freq_hz=frf.freq_hz,
        response=ratio,
        coherence=frf.coherence,
        method="table",
        dt=frf.dt,
        excited_hz=frf.excited_hz,
        n_averages=frf.n_averages,
    )
    lo, hi = _MODE_FIT_SPAN
    band = (max(lo * f_peak, frf.excited_hz[0]), min(hi * f_peak, frf.excited_hz[1]))
    mode = fit_tf(over, n_poles=2, sampling="none", band_hz=band).model.complex_modes[0]
    return mode.frequency_hz, mode.damping


def _response(twin: GalvoSLMPlant, command: np.ndarray, rest: float) -> np.ndarray:
    """Calibrated position (``y / G(0)``) of one axis from rest at ``rest`` (bit), bit.

    ``rest`` is the position before the record, not ``command[0]``: a look-ahead moves
    the first shaped sample already.
    """
    m = twin.axis_model
    _t, y, _x = scipy.signal.dlsim((m.A, m.B, m.C, m.D, m.dt), command - rest)
    return np.ravel(y) / twin.static_gain + rest


def _step(
    twin: GalvoSLMPlant, flt: _Filter, s: CompareSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Step record ``(t, command, position, settling)``, lengthened until settled."""
    dt, target = twin.dt, s.start_bit + s.jump_bit
    n = _RECORD
    while True:
        u = np.full(n + 1, target)
        u[0] = s.start_bit  # one tick at rest, then the jump
        cmd = flt.shape(u, dt)
        pos = _response(twin, cmd, s.start_bit)
        try:
            settle = settling_time(pos[1:], dt, final=target, initial=s.start_bit, band=s.band)
        except ValueError:  # still outside the band at the record's end
            settle = math.inf
        if settle <= 0.5 * n * dt:
            return (np.arange(n + 1) - 1.0) * dt, cmd, pos, settle
        if n >= _MAX_RECORD:  # a band below the twin's noise, or a jump of a fraction of a bit
            raise ValueError(
                f"the {s.jump_bit:g}-bit step has not settled into its {s.band * 100:g} % band "
                f"within {n * dt:g} s: give a larger jump or band"
            )
        n *= 2


def _ramp_lag(twin: GalvoSLMPlant, flt: _Filter) -> float:
    """Steady lag of the calibrated position behind an unshaped unit ramp, s."""
    dt = twin.dt
    n = _RECORD
    while True:
        guard = flt.advance + 1  # the last samples see the ramp's end through the look-ahead
        r = np.arange(n + guard, dtype=float)  # 1 bit per tick
        pos = _response(twin, flt.shape(r, dt), 0.0)[:n]
        lag = (r[:n] - pos) * dt  # slope 1 bit/tick: the gap in bit is the lag in ticks
        if np.ptp(lag[-_RAMP_CHECK:]) <= 1e-9 * abs(lag[-1]) or n >= _MAX_RECORD:
            return float(lag[-1])
        n *= 2


def _row(
    name: str,
    twin: GalvoSLMPlant,
    flt: _Filter,
    mode: tuple[float, float],
    design: tuple[float, float],
    s: CompareSettings,
) -> ShaperRow:
    dt = twin.dt
    f = np.linspace(_BAND[0] * mode[0], _BAND[1] * mode[0], _N_BAND)
    t, cmd, pos, settle = _step(twin, flt, s)
    field = twin.config.field_bit
    refused = None
    u = np.full(cmd.size, s.start_bit + s.jump_bit)
    u[0] = s.start_bit
    try:  # the same step shaped again, now checked against the field
        flt.shape(u, dt, axes=("x",), bounds=(-field, field), unit="bit")
    except ShapedCommandError as err:
        refused = str(err)
    return ShaperRow(
        name=name,
        mode_hz=mode[0],
        damping=mode[1],
        design_hz=design[0],
        design_damping=design[1],
        vibration=float(np.max(flt.vibration(f, mode[1], dt))),
        delay_s=discrete_lag(flt.b, flt.a, dt) - flt.advance * dt,
        look_ahead_s=flt.advance * dt,
        command_peak=float(np.max(np.abs(cmd - s.start_bit)) / s.jump_bit),
        settling_s=settle,
        lag_s=_ramp_lag(twin, flt),
        refused=refused,
        t_s=t,
        command=cmd,
        position=pos,
    )


def _not_designed(name: str, mode: tuple[float, float], why: str) -> ShaperRow:
    nan, empty = math.nan, np.zeros(0)
    return ShaperRow(
        name=name,
        mode_hz=mode[0],
        damping=mode[1],
        design_hz=nan,
        design_damping=nan,
        vibration=nan,
        delay_s=nan,
        look_ahead_s=nan,
        command_peak=nan,
        settling_s=nan,
        lag_s=nan,
        refused=f"not designed: {why}",
        t_s=empty,
        command=empty,
        position=empty,
    )


def compare_shapers(
    twin_name: TwinName, settings: CompareSettings | None = None, *, seed: int = 0
) -> ShaperComparison:
    """Every shaper side by side on one SLM galvo twin (module doc).

    Parameters
    ----------
    twin_name : {"seed", "mirror"}
        The seed's 3rd-order twin, or the one with the 3 kHz mirror mode.
    settings : CompareSettings, optional
        Jump, band, shapers, inverse discretisation, design from the FRF or the truth.
    seed : int
        Noise seed of the chirp identification (``frf_noise``), >= 0.

    Returns
    -------
    ShaperComparison
        Rows: unshaped, inverse, the classic shapers, inverse+zv.

    Raises
    ------
    ValueError
        Unknown twin, or a start or end of the jump outside the twin's field.
    """
    s = CompareSettings() if settings is None else settings
    check_int("seed", seed, 0)
    twin = _twin(twin_name)
    field = twin.config.field_bit
    for label, x in (
        ("start_bit", s.start_bit),
        ("start_bit + jump_bit", s.start_bit + s.jump_bit),
    ):
        if abs(x) > field:
            raise ValueError(
                f"{label} = {x:g} bit lies outside the twin's field ±{field:g} bit: move "
                "start_bit or shorten jump_bit"
            )
    mode = _true_mode(twin)
    design = _identified_mode(twin, twin_name, seed) if s.frf_noise else mode
    dt = twin.dt
    model = (slm_galvo.SEED_MODEL_NUM, slm_galvo.SEED_MODEL_DEN)  # what the inverse inverts
    inverse = design_inverse_shaper(model, InverseShaperConfig(discretization=s.inverse))
    none = (math.nan, math.nan)
    rows = [
        _row(ROW_UNSHAPED, twin, _filter(None, None, dt), mode, none, s),
        _row(ROW_INVERSE, twin, _filter(inverse, None, dt), mode, none, s),
    ]
    for name in s.shapers:
        try:
            sh = design_shaper(name, design[0], design[1], v_tol=s.v_tol)  # type: ignore[arg-type]
        except ValueError as err:
            rows.append(_not_designed(name, mode, str(err)))
            continue
        rows.append(_row(name, twin, _filter(None, sh, dt), mode, design, s))
    zv = design_shaper("zv", design[0], design[1])
    rows.append(_row(ROW_COMBINED, twin, _filter(inverse, zv, dt), mode, design, s))
    return ShaperComparison(
        twin=twin_name, mode_hz=mode[0], damping=mode[1], rows=tuple(rows), settings=s
    )
