"""Model-inverse input shaper of seed 003 part 2 (Buls et al., §2), and shaped-command checks.

The seed inverts the identified galvo model and adds ``n`` poles at ``p`` "for system
stability" (seed 003 §2):

``S(s) = [G(s) / G(0)]^-1 p^n / (s + p)^n``,

so that the shaped axis behaves as ``G(s) S(s) = G(0) p^n / (s + p)^n``: ``n`` real
poles at ``p`` instead of the model's, unit static gain for the shaper (it inverts the
dynamics, not ``G(0) = 0.9764``). Written the way the seed prints it (seed 003 §2,
"Input shaper (continuous)"), with the model's numerator and denominator made monic::

    num_S = p^n  den_G(s) / den_G[0] * num_G(0) / num_G[0]
    den_S = den_G(0) / den_G[0] * num_G(s) / num_G[0] * (s + p)^n

For the seed's ``G(s) = 1.242e11 / (s^3 + 9517 s^2 + 5.773e7 s + 1.272e11)`` (seed 003
§1) this gives ``num 3.99e17, 3.797e21, 2.303e25, 5.075e28`` and ``den 1.272e11,
1.279e16, 4.82e20, 8.076e24, 5.075e28``. The seed says the poles sit at "3000rad/s";
its own coefficients give ``p^4 = 5.075e28 / 1.272e11`` and ``4 p = 1.279e16 / 1.272e11``,
i.e. ``p = 2 pi 4000 rad/s`` (25133 rad/s), which is therefore the default
(``pole_hz = 4000``); its "6 times the cutoff frequency" fits that too (6 x the model's
-3 dB bandwidth of 710.6 Hz is 4.26 kHz; 3000 rad/s is 477 Hz). Its ``8.076e24`` implies
``a0 = 1.27185e11`` (the unrounded fit); from the printed ``1.272e11`` one gets
``8.077e24``.

**Discretisation.** ZOH at ``dt = 10 us``: the seed's "[fs = 1e-5]" is the period
(seed 003 §2, "Input shaper (discrete)"). The discrete filter is built from the
continuous design, not from the seed's printed 4-digit discrete numerator
``19.61, -56.99, 55.26, -17.88``: those sum to 0 (a zero at ``z = 1``), so taken literally
that filter has no static gain; the exact one sums to what its denominator
``1, -3.111, 3.63, -1.882, 0.3659`` sums to, ``(1 - exp(-p dt))^4 = 0.00244``, which the
printed digits (+-0.005 each) cannot carry. The poles are ``exp(-p dt)`` exactly; the
numerator is the one for which the filter reproduces the continuous step response at
the samples (what ZOH means), computed from the exact step response
(`microfab.control.shaping_metrics.step_response`).

**The sampled axis.** ``ZOH(S) ZOH(G)`` is not ``ZOH(S G)``: the shaper's fast output
(a 23.7x spike within 20 us) reaches the axis as a 10 us staircase, ``G``'s poles are no
longer cancelled, and on the seed's model sampled at 10 us the shaped step settles (2 %)
in 725 us instead of the continuous design's 362 us (95 % speed: 473 instead of 308 us;
ramp lag 195 instead of 159 us). ``discretization="zpetc"`` designs the filter on the
sampled axis instead: Tomizuka's zero-phase-error tracking inverse (ASME J. Dyn. Syst.
109, 1987) of ``G_d = ZOH(G)`` times ``F_d = ZOH(p^n / (s + p)^n)``. ``G_d``'s zeros
inside the unit circle are cancelled; each zero ``z_u`` on or outside it (the seed's model
has the sampling zero -3.644) is replaced by ``(z^-1 - z_u) / (1 - z_u)^2``, which makes
the axis ``F_d`` times a zero-phase low-pass with unit static gain. The filter is causal
with a delay of ``preview`` samples (the plant's delay plus one per such zero), which
`InverseShaper.shape` removes by reading the command that many samples ahead (a vector
list is known in advance). On the sampled seed model it settles in 362 us.

**Refusals** (`design_inverse_shaper`): a model with right-half-plane (or imaginary-axis)
zeros, whose inverse would have unstable poles; an unstable model or one with a pole at
``s = 0`` (no ``G(0)``); ``n`` below the model's relative degree (improper shaper); shaper
poles not faster than the model's fastest pole (``p <= max |pole|``), which would make
the axis slower, not faster; shaper poles at or above the Nyquist frequency of ``dt``.

**Shaped commands.** The inverse amplifies: its gain peaks at 40.3 at 6.99 kHz and a step
becomes a 23.7x command peak (continuous; 23.63 on the 10 us samples). `check_shaped_command`
refuses a shaped command outside a field or a machine's declared limits and names the
axis, the time, the value and the limit; `InverseShaper.shape` calls it when given
``bounds`` or ``limits``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, TypeAlias

import numpy as np
import scipy.optimize
import scipy.signal

from microfab.control.shaped_command import (
    Bounds,
    ShapedCommandError,
    check_design_dt,
    check_shaped_command,
    filter_command,
    shaped_trajectory,
)
from microfab.control.shaping_metrics import (
    TransferModel,
    as_tf,
    discrete_lag,
    filter_vibration,
    ramp_lag,
    series,
    step_peak,
    step_response,
)
from microfab.core.arrays import readonly
from microfab.core.limits import AxisLimits
from microfab.core.threads import one_blas_thread
from microfab.core.validate import check_int, check_positive
from microfab.plants.lti import DiscreteLTI
from microfab.trajectory.base import Trajectory

__all__ = [
    "MAX_ADDED_POLES",
    "Bounds",
    "Discretization",
    "InverseShaper",
    "InverseShaperConfig",
    "ShapedCommandError",
    "check_shaped_command",
    "design_inverse_shaper",
    "filter_command",
    "shaped_trajectory",
]

#: How the continuous design becomes a filter at ``dt`` (see the module).
Discretization: TypeAlias = Literal["zoh", "zpetc"]

#: Most poles the inverse shaper may add (assumed: 4x the seed's four, seed 003 §2; the
#: coefficients of (s/p + 1)^n in double precision lose the low-frequency gain well before
#: n = 100 and overflow near n = 1000).
MAX_ADDED_POLES = 16

_TAIL_TOL = 1e-9  # a shaped command held at its end has settled to this fraction of a step
#: Most samples `InverseShaper.tail_samples` looks through (assumed 2**22: 42 s at the seed's
#: 10 µs, far beyond any settling of a stable shaper; a filter whose rounded coefficients
#: never settle within 1e-9 would otherwise be simulated without end).
_TAIL_MAX = 2**22


@dataclass(frozen=True, kw_only=True)
class InverseShaperConfig:
    """Design choices of the model-inverse shaper.

    Parameters
    ----------
    pole_hz : float
        Frequency of the added real poles, Hz (default 4000: ``p = 2 pi 4000 rad/s``, what
        the seed's coefficients give; the seed's text says "3000rad/s", seed 003 §2).
    order : int
        Number of added poles ``n`` (default 4, seed 003 §2 "four extra poles"); at least
        the model's relative degree.
    dt : float
        Sample time of the discrete filter, s (default 1e-5: seed 003 §2 "[fs = 1e-5]",
        a period, and the galvo's 10 us set-point period).
    discretization : {"zoh", "zpetc"}
        ``"zoh"`` (default, the seed's): ZOH of the continuous ``S``. ``"zpetc"``: the
        zero-phase-error inverse of the sampled axis ``ZOH(G)`` times ``ZOH(p^n/(s+p)^n)``,
        read ``preview`` samples ahead (see the module).
    """

    pole_hz: float = 4000.0  # seed 003 §2: coefficients give 2 pi 4000 rad/s (text: 3000 rad/s)
    order: int = 4  # seed 003 §2: "four extra poles"
    dt: float = 1e-5  # seed 003 §2: "[fs = 1e-5]" is the sample period
    discretization: Discretization = "zoh"  # the seed's (its printed discrete shaper is ZOH)

    def __post_init__(self) -> None:
        if self.discretization not in ("zoh", "zpetc"):
            raise ValueError(
                f"discretization must be 'zoh' (the seed's) or 'zpetc' (inverse of the "
                f"sampled axis), got {self.discretization!r}"
            )
        check_positive("pole_hz", self.pole_hz, "Hz")
        check_int("order", self.order, 1, "poles")
        if self.order > MAX_ADDED_POLES:
            raise ValueError(
                f"order must be at most {MAX_ADDED_POLES} added poles, got {self.order} (seed "
                "003 §2 adds four)"
            )
        check_positive("dt", self.dt, "s")
        nyquist = 0.5 / self.dt
        if self.pole_hz >= nyquist:
            raise ValueError(
                f"pole_hz = {self.pole_hz} Hz lies at or above the Nyquist frequency "
                f"{nyquist:g} Hz of dt = {self.dt} s: lower pole_hz or dt"
            )

    @property
    def pole_rad_s(self) -> float:
        """``p = 2 pi pole_hz``, rad/s."""
        return 2.0 * math.pi * self.pole_hz


def _check_model(num: np.ndarray, den: np.ndarray, cfg: InverseShaperConfig) -> np.ndarray:
    """Refuse a model the seed's inverse cannot be built from; return its poles."""
    poles = np.roots(den)
    zeros = np.roots(num) if num.size > 1 else np.zeros(0, dtype=complex)
    if poles.size == 0:
        raise ValueError("the plant model has no poles: nothing to invert")
    if np.any(poles.real >= 0.0):
        bad = poles[np.argmax(poles.real)]
        raise ValueError(
            f"the plant model has a pole at {bad:.6g} rad/s (not in the left half-plane): "
            "its static gain G(0) is undefined or the axis unstable; identify the closed "
            "scanner loop, which is stable"
        )
    if np.any(zeros.real >= 0.0):
        bad = zeros[np.argmax(zeros.real)]
        raise ValueError(
            f"the plant model has a zero at {bad:.6g} rad/s ({abs(bad) / (2 * math.pi):.6g} Hz) "
            "in the right half-plane or on the imaginary axis: its inverse would be an "
            "unstable (or undamped) pole of the shaper; refit without it or invert only "
            "the minimum-phase part"
        )
    rel_deg = den.size - num.size
    if cfg.order < rel_deg:
        raise ValueError(
            f"order = {cfg.order} is below the model's relative degree {rel_deg}: the shaper "
            f"would be improper (more zeros than poles); use order >= {rel_deg}"
        )
    fastest = float(np.max(np.abs(poles)))
    if cfg.pole_rad_s <= fastest:
        raise ValueError(
            f"pole_hz = {cfg.pole_hz} Hz ({cfg.pole_rad_s:.6g} rad/s) is not faster than the "
            f"model's fastest pole, |s| = {fastest:.6g} rad/s ({fastest / (2 * math.pi):.6g} "
            f"Hz): the shaped axis would be slower; choose pole_hz above "
            f"{fastest / (2 * math.pi):.6g} Hz"
        )
    return poles


def _zoh(num: np.ndarray, den: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """ZOH equivalent of a stable proper continuous filter, in powers of ``z^-1``.

    Poles ``exp(s_i dt)`` exactly; numerator from the exact continuous step response at
    the samples (``b = first n + 1 terms of a * diff(y)``).
    """
    n = den.size - 1
    a = np.real(np.poly(np.exp(np.roots(den) * dt)))
    y = step_response((num, den), np.arange(n + 1) * dt)
    h = np.diff(np.concatenate([[0.0], y]))  # impulse response of the ZOH filter
    b = np.convolve(a, h)[: n + 1]
    return b, a


def _zpetc(
    plant: tuple[np.ndarray, np.ndarray], target: tuple[np.ndarray, np.ndarray], dt: float
) -> tuple[np.ndarray, np.ndarray, int]:
    """Zero-phase-error tracking inverse of ``ZOH(plant)`` times ``ZOH(target)``.

    Returns ``(b, a, preview)`` in powers of ``z^-1``, ``a[0] = 1``, ``b(1)/a(1) = 1``;
    the sampled axis through it is ``ZOH(G)(1) ZOH(target) z^-preview`` times a zero-phase
    factor ``prod |1 - z_u e^-jw|^2 / (1 - z_u)^2`` (see the module).
    """
    bg, ag = _zoh(*plant, dt)
    bf, af = _zoh(*target, dt)
    d = int(np.flatnonzero(bg)[0])  # the sampled plant's delay, samples
    bt = bg[d:]
    zeros = np.roots(bt) if bt.size > 1 else np.zeros(0, dtype=complex)
    outside = np.abs(zeros) >= 1.0
    z_u, z_s = zeros[outside], zeros[~outside]
    b_s = np.real(np.poly(z_s))  # prod (1 - z_s q), ascending powers of q = z^-1
    b_u_star = np.real(np.poly(z_u))[::-1]  # prod (q - z_u), ascending powers of q
    b_u_1 = float(np.real(np.prod(1.0 - z_u)))
    g0 = bg.sum() / ag.sum()
    b = g0 * np.convolve(np.convolve(ag, b_u_star), bf)
    a = bt[0] * b_u_1**2 * np.convolve(b_s, af)
    b, a = b / a[0], a / a[0]
    return b, a, d + int(z_u.size)


def _same_length(b: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``b``, ``a`` (powers of ``z^-1``) padded with trailing zeros to one length."""
    n = max(b.size, a.size)
    return np.pad(b, (0, n - b.size)), np.pad(a, (0, n - a.size))


@dataclass(frozen=True, kw_only=True, eq=False)
class InverseShaper:
    """A designed model-inverse shaper (build it with `design_inverse_shaper`).

    Attributes
    ----------
    config : InverseShaperConfig
        The design choices (pole, order, dt).
    plant_num, plant_den : numpy.ndarray
        The inverted continuous model ``G``, descending powers of ``s``.
    num, den : numpy.ndarray
        Continuous shaper ``S(s)`` in the seed's normalisation (see the module), shapes
        (n_den_G,) and (n_num_G + order,).
    num_d, den_d : numpy.ndarray
        The causal filter at ``config.dt`` in powers of ``z^-1`` (``scipy.signal.lfilter``'s
        ``b``, ``a``; ``den_d[0] = 1``; same length). ZOH: ``num_d[0]`` is the direct
        feed-through (0 when ``S`` is strictly proper: one sample of delay).
    preview : int
        Samples the command is read ahead (0 for ZOH; the plant's delay plus its zeros
        outside the unit circle for ZPETC): the shaped command is the filter's output
        ``preview`` samples later.
    """

    config: InverseShaperConfig
    plant_num: np.ndarray
    plant_den: np.ndarray
    num: np.ndarray
    den: np.ndarray
    num_d: np.ndarray
    den_d: np.ndarray
    preview: int = 0

    @property
    def dt(self) -> float:
        """Sample time of the discrete filter, s."""
        return self.config.dt

    @property
    def pole_rad_s(self) -> float:
        """The added poles' ``p``, rad/s."""
        return self.config.pole_rad_s

    @property
    def discrete_static_gain(self) -> float:
        """``S_d(1) = sum(num_d) / sum(den_d)`` (1 to rounding: ZOH keeps the static gain)."""
        return float(self.num_d.sum() / self.den_d.sum())

    def overall(self) -> tuple[np.ndarray, np.ndarray]:
        """The shaped axis ``G(s) S(s)`` as continuous ``(num, den)`` (no cancellation)."""
        return series((self.plant_num, self.plant_den), (self.num, self.den))

    def frequency_response(
        self, freq_hz: np.ndarray | float, *, discrete: bool = False
    ) -> np.ndarray:
        """Complex response of the shaper at ``freq_hz`` (Hz), shape (n,).

        ``discrete=True`` evaluates the filter at ``z = exp(j 2 pi f dt)``, with the
        preview's advance ``z^preview``.
        """
        f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
        if discrete:
            zi = np.exp(-2j * np.pi * f * self.dt)
            h = np.polyval(self.num_d[::-1], zi) / np.polyval(self.den_d[::-1], zi)
            return h * zi ** (-self.preview)
        s = 2j * np.pi * f
        return np.polyval(self.num, s) / np.polyval(self.den, s)

    def gain_peak(self, *, discrete: bool = False) -> tuple[float, float]:
        """Largest gain ``|S|`` and its frequency: ``(gain, freq_hz)``.

        Searched on a log grid from 1 Hz to 20 ``pole_hz`` (continuous) or to Nyquist
        (discrete), then refined. Seed 003 default: 40.27 at 6987 Hz (continuous),
        39.62 at 7066 Hz (discrete, 10 us).
        """
        f_hi = 0.5 / self.dt if discrete else 20.0 * self.config.pole_hz
        f = np.geomspace(1.0, f_hi, 4000)
        g = np.abs(self.frequency_response(f, discrete=discrete))
        k = int(np.argmax(g))
        lo, hi = f[max(k - 1, 0)], f[min(k + 1, f.size - 1)]
        res = scipy.optimize.minimize_scalar(
            lambda x: -abs(self.frequency_response(x, discrete=discrete)[0]),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-9 * hi},
        )
        if -res.fun >= g[k]:
            return float(-res.fun), float(res.x)
        return float(g[k]), float(f[k])

    def lag(self, *, discrete: bool = False) -> float:
        """Added delay of the shaper: its ramp lag, s (negative: the shaper leads).

        Continuous ``a1/a0 - b1/b0`` of ``S``; seed 003 default: ``4/p - 453.9 us =
        -294.7 us``. ``discrete=True``: the ZOH filter's group delay at DC (``dt / 2``
        more, the hold's half sample, and what the sampling aliases: -263.8 us for the
        seed's default), less the preview.
        """
        if discrete:
            return discrete_lag(self.num_d, self.den_d, self.dt) - self.preview * self.dt
        return ramp_lag((self.num, self.den))

    def step_peak(self, *, discrete: bool = False) -> float:
        """Command peak of a unit step through the shaper (23.66 continuous, 23.63 sampled)."""
        if not discrete:
            return step_peak((self.num, self.den))[0]
        y = scipy.signal.lfilter(self.num_d, self.den_d, np.ones(self.tail_samples() + 1))
        return float(np.max(np.abs(y)))

    def vibration(
        self, freq_hz: np.ndarray | float, damping: float, *, discrete: bool = False
    ) -> np.ndarray:
        """Residual vibration of a mode (``freq_hz``, ``damping``) after a shaped step.

        ``|S(s_p)| / S(0)``, see `microfab.control.shaping_metrics.filter_vibration`
        (above 1: the inverse excites the mode more than the plain step).
        """
        if discrete:
            f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
            v = filter_vibration((self.num_d, self.den_d), f, damping, dt=self.dt)
            # the preview's advance z^m at the mode's pole: |exp(s_p m dt)|
            return v * np.exp(-damping * 2.0 * np.pi * f * self.preview * self.dt)
        return filter_vibration((self.num, self.den), freq_hz, damping)

    def tail_samples(self) -> int:
        """Samples after which a shaped step stays within 1e-9 of its final value.

        Raises
        ------
        ValueError
            The discrete filter does not settle within 1e-9 of its static gain in
            ``2**22`` samples (or its gain is not finite): its coefficients have lost
            their precision at this ``dt`` (poles crowded at z = 1).
        """
        n = 64
        gain = self.discrete_static_gain
        while math.isfinite(gain) and n <= _TAIL_MAX:
            y = scipy.signal.lfilter(self.num_d, self.den_d, np.ones(n))
            out = np.flatnonzero(~(np.abs(y - gain) <= _TAIL_TOL))
            if out.size == 0:
                return 0
            if out[-1] < n // 2:
                return int(out[-1]) + 1
            n *= 2
        radius = float(np.max(np.abs(np.roots(self.den_d)), initial=0.0))
        raise ValueError(
            f"the discrete shaper at dt = {self.dt:g} s does not settle within {_TAIL_TOL:g} "
            f"of its static gain {gain:.10g} in {_TAIL_MAX} samples (poles up to |z| = "
            f"{radius:.6g}): its coefficients lose their precision at this dt; use a longer dt"
        )

    def shape(
        self,
        command: np.ndarray,
        *,
        dt: float | None = None,
        periodic: bool = False,
        tail: int | None = None,
        axes: Sequence[str] | None = None,
        bounds: Bounds | None = None,
        limits: Mapping[str, AxisLimits] | None = None,
        unit: str = "",
    ) -> np.ndarray:
        """The shaped command: the discrete filter applied to each column.

        Parameters
        ----------
        command : numpy.ndarray
            Set points, shape (n,) or (n, n_axes), one sample every ``dt``.
        dt : float, optional
            Sample time of ``command``, s; must equal ``config.dt`` (checked when given).
        periodic : bool
            ``False`` (default): the command starts from rest at its first sample and is
            held at its last, filtered by ``scipy.signal.lfilter`` (exact recursion),
            ``tail`` hold samples appended. ``True``: one period of a repeated command,
            filtered in steady state (exactly, by the filter's response at the DFT bins).
        tail : int, optional
            Samples appended (held last value) for a non-periodic command; default
            `tail_samples` (settled to 1e-9 of a step).
        axes : sequence of str, optional
            Column names for the messages (default ``x``, ``y``, ... or ``a0``, ...).
        bounds : (low, high) or mapping of axis to (low, high), optional
            Field the shaped command must stay in (e.g. ``(-32768, 32767)`` bit).
        limits : mapping of str to AxisLimits, optional
            Declared limits (position, velocity, acceleration) checked with
            `microfab.core.limits.check_command`.
        unit : str
            Unit of the command, for the messages.

        Returns
        -------
        numpy.ndarray
            Shaped command, shape of ``command`` with ``tail`` more rows (non-periodic).

        Raises
        ------
        ShapedCommandError, LimitViolation
            If the shaped command leaves ``bounds`` or ``limits`` (axis, time, value, limit).
        """
        if dt is not None:
            check_design_dt(dt, self.dt)
        n_tail = self.tail_samples() if tail is None else check_int("tail", tail, 0, "samples")
        return filter_command(
            command,
            self.num_d,
            self.den_d,
            dt=self.dt,
            periodic=periodic,
            tail=n_tail,
            advance=self.preview,
            axes=axes,
            bounds=bounds,
            limits=limits,
            unit=unit,
        )

    def apply(self, trajectory: Trajectory) -> Trajectory:
        """`microfab.control.base.Feedforward`: the shaped trajectory (positions only).

        At rest: ``tail_samples()`` hold samples appended; otherwise shaped as one period.
        The trajectory's ``dt`` must equal ``config.dt``.
        """
        check_design_dt(trajectory.dt, self.dt)
        return shaped_trajectory(
            trajectory,
            self.num_d,
            self.den_d,
            self.tail_samples(),
            f"inverse-{self.config.discretization}",
            advance=self.preview,
        )

    def to_lti(self) -> DiscreteLTI:
        """The discrete filter as a `microfab.plants.lti.DiscreteLTI` (one input, one output)."""
        nz = np.flatnonzero(self.num_d)
        num = self.num_d[nz[0] :] if nz.size else self.num_d[-1:]  # z-form: same filter
        A, B, C, D = scipy.signal.tf2ss(num, self.den_d)
        return DiscreteLTI(A, B, C, D, self.dt)


def design_inverse_shaper(
    model: TransferModel, config: InverseShaperConfig | None = None
) -> InverseShaper:
    """Design the seed's model-inverse shaper for a continuous axis model.

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        Identified continuous model ``G`` of the axis (set position to position), e.g.
        ``((1.242e11,), (1, 9517, 5.773e7, 1.272e11))`` (seed 003 §1).
    config : InverseShaperConfig, optional
        Pole frequency, order and sample time (defaults: 4000 Hz, 4, 10 us).

    Returns
    -------
    InverseShaper
        The continuous design and its ZOH filter.

    Raises
    ------
    ValueError
        Right-half-plane (or imaginary-axis) zeros of ``G``, an unstable ``G``, ``order``
        below the relative degree, poles not faster than ``G``'s fastest (see the module).
    """
    cfg = InverseShaperConfig() if config is None else config
    num_g, den_g = as_tf(model, "plant model")
    _check_model(num_g, den_g, cfg)
    p = cfg.pole_rad_s
    lead_n, lead_d = num_g[0], den_g[0]
    # seed 003 §2 normalisation: G's numerator and denominator monic
    num = p**cfg.order * (den_g / lead_d) * (num_g[-1] / lead_n)
    den = (den_g[-1] / lead_d) * np.polymul(num_g / lead_n, np.poly([-p] * cfg.order))
    preview = 0
    with one_blas_thread():  # small matrices: BLAS threads only cost here
        if cfg.discretization == "zoh":
            num_d, den_d = _zoh(num, den, cfg.dt)
        else:
            target = (np.array([p**cfg.order]), np.poly([-p] * cfg.order))
            num_d, den_d, preview = _zpetc((num_g, den_g), target, cfg.dt)
    num_d, den_d = _same_length(num_d, den_d)
    return InverseShaper(
        config=cfg,
        plant_num=readonly(num_g),
        plant_den=readonly(den_g),
        num=readonly(num),
        den=readonly(den),
        num_d=readonly(num_d),
        den_d=readonly(den_d),
        preview=preview,
    )
