"""Loop margins evaluated on a frequency grid.

Polynomial margin routines break down on a 1 MHz loop with 40 kHz modes (the polynomials
of such models are numerically meaningless), and the galvo loop is conditionally stable, so
margins are read off the frequency response of the discrete loop on a dense logarithmic
grid, each crossing refined by interpolation. `loop_axis_margins` adds the sensitivity
peak ``max |1 / (1 + L)|`` on the same kind of grid; `feedback_loop` breaks a loop at the
plant input, ``L = −C_fb P``, from the plant and the controller's feedback path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import control
from microfab.plants.lti import DiscreteLTI

__all__ = [
    "AxisMargins",
    "Crossing",
    "LoopMargins",
    "feedback_loop",
    "loop_axis_margins",
    "loop_margins",
]


@dataclass(frozen=True)
class Crossing:
    """One crossing of the open-loop frequency response.

    Attributes
    ----------
    freq_hz : float
        Frequency of the crossing in Hz.
    kind : str
        ``"gain"`` (|L| = 1) or ``"phase"`` (angle L = -180 deg modulo 360).
    margin : float
        Phase margin in deg at a gain crossing; gain margin in dB at a phase crossing
        (positive: gain may rise by that much; negative: gain may fall by that much).
    """

    freq_hz: float
    kind: str
    margin: float


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of a loop.

    Attributes
    ----------
    gm_db : float
        Smallest gain margin (gain increase) at a phase crossing above the crossover, dB.
    gm_freq_hz : float
        Where it occurs, Hz.
    pm_deg : float
        Phase margin at the (highest) gain crossover, deg.
    pm_freq_hz : float
        Gain-crossover frequency, Hz.
    crossings : tuple of Crossing
        Every crossing found, low to high frequency (the low-frequency phase crossings of a
        conditionally stable loop have negative gain margins).
    """

    gm_db: float
    gm_freq_hz: float
    pm_deg: float
    pm_freq_hz: float
    crossings: tuple[Crossing, ...]


def loop_margins(
    loop: DiscreteLTI,
    f_min_hz: float = 1.0,
    n_points: int = 200_000,
) -> LoopMargins:
    """Gain and phase margins of a SISO discrete open loop ``L = C G``.

    Parameters
    ----------
    loop : DiscreteLTI
        Open-loop model (controller in series with the plant, delays included).
    f_min_hz : float
        Lowest grid frequency in Hz; the grid runs to 0.999 of Nyquist.
    n_points : int
        Number of log-spaced grid points.

    Returns
    -------
    LoopMargins
    """
    f_max = 0.999 / (2 * loop.dt)
    f = np.geomspace(f_min_hz, f_max, n_points)
    L = loop.frequency_response(f)[:, 0, 0]
    mag_db = 20 * np.log10(np.abs(L))
    phase = np.unwrap(np.angle(L))
    crossings: list[Crossing] = []
    lf = np.log(f)

    def interp(i: int, a: np.ndarray, level: float) -> float:
        t = (level - a[i]) / (a[i + 1] - a[i])
        return float(np.exp(lf[i] + t * (lf[i + 1] - lf[i])))

    # gain crossings
    for i in np.nonzero(np.diff(np.sign(mag_db)) != 0)[0]:
        fc = interp(i, mag_db, 0.0)
        ph = np.interp(np.log(fc), lf[i : i + 2], phase[i : i + 2])
        pm = float(np.rad2deg(ph) % 360.0 - 180.0)
        crossings.append(Crossing(fc, "gain", pm))
    # phase crossings at -180 + k*360
    k = np.floor((phase + np.pi) / (2 * np.pi))
    for i in np.nonzero(np.diff(k) != 0)[0]:
        level = (max(k[i], k[i + 1])) * 2 * np.pi - np.pi
        fp = interp(i, phase, level)
        m = np.interp(np.log(fp), lf[i : i + 2], mag_db[i : i + 2])
        crossings.append(Crossing(fp, "phase", float(-m)))
    crossings.sort(key=lambda c: c.freq_hz)
    gains = [c for c in crossings if c.kind == "gain"]
    if not gains:
        raise ValueError("the loop gain never crosses 0 dB on the grid; no phase margin")
    gc = gains[-1]
    upper = [c for c in crossings if c.kind == "phase" and c.freq_hz > gc.freq_hz]
    gm = min(upper, key=lambda c: c.margin) if upper else Crossing(np.inf, "phase", np.inf)
    return LoopMargins(
        gm_db=gm.margin,
        gm_freq_hz=gm.freq_hz,
        pm_deg=gc.margin,
        pm_freq_hz=gc.freq_hz,
        crossings=tuple(crossings),
    )


@dataclass(frozen=True, kw_only=True)
class AxisMargins:
    """Margins of one axis loop.

    Attributes
    ----------
    axis : str
        The axis' name (``"x"``, ``"y"``, ...).
    margins : LoopMargins
        Gain and phase margins and their frequencies.
    sensitivity_peak_db : float
        ``max |S|``, dB.
    sensitivity_peak_hz : float
        Where it occurs, Hz.
    """

    axis: str
    margins: LoopMargins
    sensitivity_peak_db: float
    sensitivity_peak_hz: float


def _ss(sys: DiscreteLTI) -> control.StateSpace:
    return control.ss(sys.A, sys.B, sys.C, sys.D, sys.dt)


def feedback_loop(plant: DiscreteLTI, feedback: DiscreteLTI) -> DiscreteLTI:
    """``L = −C_fb P``: a SISO loop broken at the plant input.

    Parameters
    ----------
    plant : DiscreteLTI
        ``P``, from the plant input (the command) to the measured output.
    feedback : DiscreteLTI
        ``C_fb``, the controller's path from the measured output to the command (negative
        feedback has the sign in it: ``L`` takes it off), same sample time.
    """
    loop = -control.series(_ss(plant), _ss(feedback))
    return DiscreteLTI(loop.A, loop.B, loop.C, loop.D, plant.dt)


def loop_axis_margins(axis: str, loop: DiscreteLTI, n_points: int = 20_000) -> AxisMargins:
    """`loop_margins` of a SISO loop and its sensitivity peak, on ``n_points`` from 1 Hz.

    Parameters
    ----------
    axis : str
        The axis' name.
    loop : DiscreteLTI
        The open loop ``L``.
    n_points : int
        Log-spaced grid points from 1 Hz to 0.999 of Nyquist.
    """
    m = loop_margins(loop, n_points=n_points)
    f = np.geomspace(1.0, 0.999 / (2 * loop.dt), n_points)
    s = 1.0 / np.abs(1.0 + loop.frequency_response(f)[:, 0, 0])
    i = int(np.argmax(s))
    return AxisMargins(
        axis=axis,
        margins=m,
        sensitivity_peak_db=float(20 * np.log10(s[i])),
        sensitivity_peak_hz=float(f[i]),
    )
