"""Piezo drive waveforms: unipolar, bipolar and tripolar trapezoidal pulse trains.

A drop-on-demand dispenser is driven by a train of trapezoidal voltage pulses repeated at
the jetting frequency: the command signal of the printhead plant. `Waveform` satisfies
:class:`microfab.plants.printhead.DriveSignal` (a ``voltage(t_s)`` method), so it drives
:func:`microfab.plants.printhead.nozzle_flow` directly. Seed 003 part 1
(``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al., "Method" and Table 1) drives a
MicroFab 120 µm dispenser with the *bipolar* waveform of Herran & Huang (2012): a positive
pulse (the *dwell*) followed by a negative pulse (the *echo*) that cancels part of the
residual acoustic oscillation, with 3 µs rise and fall times, 30 µs dwell, 30 µs echo,
40-70 V and 50 Hz.

Shape
-----
Every waveform is piecewise linear between corner points (``Waveform.breakpoints``).
Each transition takes ``rise_s`` when the voltage goes up and ``fall_s`` when it goes
down, whatever the size of the step (so the ``+V -> -V`` swing of a bipolar pulse takes
``fall_s``, not ``2 fall_s``). With ``V = amplitude_v``:

* unipolar: ``0 -> +V`` (rise), hold ``+V`` (dwell), ``+V -> 0`` (fall);
* bipolar: ``0 -> +V`` (rise), hold ``+V`` (dwell), ``+V -> -V`` (fall), hold ``-V``
  (echo), ``-V -> 0`` (rise);
* tripolar: the bipolar train up to the echo, then ``-V -> +rV`` (rise), hold ``+rV``
  (final), ``+rV -> 0`` (fall), with ``r = final_ratio``.

``dwell_s``, ``echo_s`` and ``final_s`` are the *plateau* lengths, i.e. the time between
the end of one ramp and the start of the next; the ramps are not part of them. The train
starts at ``t = 0`` and is repeated with the period ``1 / frequency_hz``; between trains
the voltage is 0.

References
----------
Seed 003 part 1, "Method" and Table 1. J. S. Herran & Y. Huang, "Study of a bipolar
waveform for drop-on-demand inkjetting", J. Manuf. Processes 14 (2012) 98 (bipolar
waveform). J. S. Herran, Y. Huang & W. Chai, "Performance evaluation of bipolar and
tripolar excitations during nozzle-jetting-based alginate microsphere fabrication",
J. Micromech. Microeng. 22 (2012) 085025 (tripolar waveform).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from microfab.core.validate import check_in_range, check_positive
from microfab.plants.printhead import SEED003_DWELL_S

__all__ = [
    "MAX_AMPLITUDE_V",
    "SEED003_DWELL_S",
    "SEED003_ECHO_S",
    "SEED003_FREQUENCY_HZ",
    "SEED003_RISE_FALL_S",
    "SEED003_VOLTAGES_V",
    "Waveform",
    "WaveformKind",
    "seed003_waveform",
]

WaveformKind = Literal["unipolar", "bipolar", "tripolar"]

#: Largest accepted peak voltage, V. Assumption: a generous upper bound of the output
#: range of piezo dispenser drivers such as the MicroFab Jet Driver; the seed uses at most
#: 70 V, and the bound only catches unit mistakes (e.g. millivolts passed as volts).
MAX_AMPLITUDE_V = 200.0

#: Excitation voltages of the seed, V.
SEED003_VOLTAGES_V = (40.0, 45.0, 50.0, 55.0, 60.0, 65.0, 70.0)  # seed 003 part 1, Table 1
#: Voltage rise and fall times of the seed, s.
SEED003_RISE_FALL_S = 3e-6  # seed 003 part 1, Table 1
# SEED003_DWELL_S (30 µs, seed 003 part 1, Table 1) is defined with the printhead, whose
# default channel length it sets (Bogy & Talke: L = c × dwell), and re-exported here.
#: Echo time of the seed, s.
SEED003_ECHO_S = 30e-6  # seed 003 part 1, Table 1
#: Excitation (jetting) frequency of the seed, Hz.
SEED003_FREQUENCY_HZ = 50.0  # seed 003 part 1, Table 1

_KINDS = ("unipolar", "bipolar", "tripolar")


@dataclass(frozen=True, kw_only=True)
class Waveform:
    """A trapezoidal piezo drive waveform repeated at a fixed frequency.

    Attributes
    ----------
    kind : {"unipolar", "bipolar", "tripolar"}
        Number of pulses in the train (see the module docstring for the shapes).
    amplitude_v : float
        Peak voltage ``V`` of the first (positive) pulse in V, ``0 < V <= 200``
        (`MAX_AMPLITUDE_V`); the echo pulse goes to ``-V``.
    rise_s : float
        Duration of every upward transition in s, > 0 (default 3 µs, seed 003 Table 1).
    fall_s : float
        Duration of every downward transition in s, > 0 (default 3 µs, seed 003 Table 1).
    dwell_s : float
        Plateau length of the first, positive pulse in s, > 0 (default 30 µs, seed 003
        Table 1).
    echo_s : float
        Plateau length of the second, negative pulse in s, > 0 (default 30 µs, seed 003
        Table 1); ignored for ``"unipolar"``.
    final_s : float
        Plateau length of the third, positive pulse of a ``"tripolar"`` train in s, > 0
        (default 30 µs; assumption: equal to the dwell, as in the symmetric tripolar
        trains of Herran, Huang & Chai 2012); ignored otherwise.
    final_ratio : float
        Height of the third pulse as a fraction of ``amplitude_v``, ``0 < r <= 1``
        (default 0.5; assumption: a half-height cancelling pulse in the spirit of the
        tripolar excitation of Herran, Huang & Chai 2012, J. Micromech. Microeng. 22
        085025); ignored unless ``"tripolar"``.
    frequency_hz : float
        Repetition (jetting) frequency in Hz, > 0 (default 50 Hz, seed 003 Table 1). The
        period ``1 / frequency_hz`` must be longer than the pulse train.

    Examples
    --------
    >>> w = Waveform(kind="bipolar", amplitude_v=50.0)
    >>> round(w.duration_s * 1e6, 6)
    69.0
    >>> float(w.voltage(20e-6))
    50.0
    """

    kind: WaveformKind
    amplitude_v: float
    rise_s: float = SEED003_RISE_FALL_S
    fall_s: float = SEED003_RISE_FALL_S
    dwell_s: float = SEED003_DWELL_S
    echo_s: float = SEED003_ECHO_S
    final_s: float = SEED003_DWELL_S  # assumption: third plateau as long as the dwell
    final_ratio: float = 0.5  # assumption: half-height third pulse (Herran et al. 2012)
    frequency_hz: float = SEED003_FREQUENCY_HZ

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {self.kind!r}")
        check_positive("amplitude_v", self.amplitude_v, "V")
        if self.amplitude_v > MAX_AMPLITUDE_V:
            raise ValueError(
                f"amplitude_v must not exceed the driver range of {MAX_AMPLITUDE_V} V, "
                f"got {self.amplitude_v} V"
            )
        for name in ("rise_s", "fall_s", "dwell_s", "echo_s", "final_s"):
            check_positive(name, getattr(self, name), "s")
        check_in_range(
            "final_ratio", self.final_ratio, 0.0, 1.0, "(fraction of amplitude_v)", low_closed=False
        )
        check_positive("frequency_hz", self.frequency_hz, "Hz")
        if not self.period_s > self.duration_s:
            raise ValueError(
                f"period 1/frequency_hz = {self.period_s} s must be longer than the "
                f"pulse train of {self.duration_s} s (frequency_hz = {self.frequency_hz} Hz)"
            )

    @property
    def period_s(self) -> float:
        """Repetition period ``1 / frequency_hz`` in s."""
        return 1.0 / self.frequency_hz

    @property
    def duration_s(self) -> float:
        """End of the pulse train in s (the voltage is back at 0 from here to the period)."""
        return float(self.breakpoints()[0][-1])

    def breakpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """Corner points of one pulse train.

        Returns
        -------
        t_s : numpy.ndarray
            Corner times in s, shape (n_corners,), strictly increasing, from 0 to
            `duration_s`.
        v_v : numpy.ndarray
            Voltage at the corners in V, shape (n_corners,); first and last are 0.

        Examples
        --------
        >>> t, v = Waveform(kind="unipolar", amplitude_v=10.0, dwell_s=5e-6).breakpoints()
        >>> (t * 1e6).round(6).tolist(), v.tolist()
        ([0.0, 3.0, 8.0, 11.0], [0.0, 10.0, 10.0, 0.0])
        """
        v = self.amplitude_v
        rise, fall = self.rise_s, self.fall_s
        # (duration of the segment ending at the corner, voltage at the corner)
        segments: list[tuple[float, float]] = [(rise, v), (self.dwell_s, v)]
        if self.kind == "unipolar":
            segments.append((fall, 0.0))
        else:
            segments += [(fall, -v), (self.echo_s, -v)]
            if self.kind == "bipolar":
                segments.append((rise, 0.0))
            else:
                vf = self.final_ratio * v
                segments += [(rise, vf), (self.final_s, vf), (fall, 0.0)]
        dt = np.array([0.0] + [s[0] for s in segments])
        t = np.cumsum(dt)
        volts = np.array([0.0] + [s[1] for s in segments])
        return t, volts

    def _phase(self, t_s: np.ndarray | float) -> np.ndarray:
        """Time since the start of the current period, in [0, period)."""
        return np.mod(np.asarray(t_s, dtype=float), self.period_s)

    def voltage(self, t_s: np.ndarray | float) -> np.ndarray:
        """Drive voltage at any times (periodic in ``1 / frequency_hz``).

        Parameters
        ----------
        t_s : float or numpy.ndarray
            Times in s, any shape; negative times are folded into the period too.

        Returns
        -------
        numpy.ndarray
            Voltage in V, same shape as ``t_s`` (0-d for a scalar).

        Examples
        --------
        >>> w = Waveform(kind="bipolar", amplitude_v=40.0)
        >>> w.voltage([1.5e-6, 50e-6, 1e-3]).tolist()
        [20.0, -40.0, 0.0]
        """
        tb, vb = self.breakpoints()
        return np.interp(self._phase(t_s), tb, vb, left=0.0, right=0.0)

    def slope(self, t_s: np.ndarray | float) -> np.ndarray:
        """Time derivative ``dV/dt`` (piecewise constant, right-continuous).

        Parameters
        ----------
        t_s : float or numpy.ndarray
            Times in s, any shape (periodic like `voltage`).

        Returns
        -------
        numpy.ndarray
            Slope in V/s, same shape as ``t_s``; at a corner (within 1e-9 of the shortest
            segment, to absorb round-off) the slope of the segment that starts there; 0 on
            the plateaus and between trains.

        Examples
        --------
        >>> w = Waveform(kind="bipolar", amplitude_v=30.0)
        >>> (w.slope([1e-6, 10e-6, 34e-6]) * 1e-6).round(9).tolist()
        [10.0, 0.0, -20.0]
        """
        tb, vb = self.breakpoints()
        seg = np.diff(tb)
        seg_slope = np.append(np.diff(vb) / seg, 0.0)  # after the train: 0
        # A time within round-off of a corner counts as the corner (e.g. 33e-6 against
        # 3e-6 + 30e-6): tolerance 1e-9 of the shortest segment.
        tol = 1e-9 * float(seg.min())
        idx = np.searchsorted(tb, self._phase(t_s) + tol, side="right") - 1
        return seg_slope[idx]

    def sample(
        self, sample_rate_hz: float, duration_s: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Sample the voltage on a uniform grid.

        Parameters
        ----------
        sample_rate_hz : float
            Sample rate in Hz, > 0; the samples are ``t_k = k / sample_rate_hz`` exactly.
        duration_s : float, optional
            Length of the record in s, > 0 (default: the pulse train, `duration_s`). The
            last sample is the last grid time not after ``duration_s`` (within 1e-9 of a
            sample, to absorb round-off).

        Returns
        -------
        t_s : numpy.ndarray
            Sample times in s, shape (n,).
        v_v : numpy.ndarray
            Voltage in V, shape (n,).

        Examples
        --------
        >>> t, v = Waveform(kind="unipolar", amplitude_v=9.0).sample(1e6, 6e-6)
        >>> v.tolist()
        [0.0, 3.0, 6.0, 9.0, 9.0, 9.0, 9.0]
        """
        check_positive("sample_rate_hz", sample_rate_hz, "Hz")
        span = self.duration_s if duration_s is None else duration_s
        check_positive("duration_s", span, "s")
        n = math.floor(span * sample_rate_hz + 1e-9) + 1
        t = np.arange(n) / sample_rate_hz
        return t, self.voltage(t)


def seed003_waveform(voltage_v: float = 50.0) -> Waveform:
    """The bipolar excitation of seed 003 part 1, Table 1.

    Parameters
    ----------
    voltage_v : float, optional
        Peak voltage in V (default 50 V, the voltage of the seed's Fig. 2; the seed spans
        40-70 V in 5 V steps, `SEED003_VOLTAGES_V`).

    Returns
    -------
    Waveform
        Bipolar: 3 µs rise and fall, 30 µs dwell, 30 µs echo, 50 Hz.

    Examples
    --------
    >>> w = seed003_waveform()
    >>> w.kind, w.amplitude_v, round(w.dwell_s * 1e6, 9), w.frequency_hz
    ('bipolar', 50.0, 30.0, 50.0)
    """
    return Waveform(
        kind="bipolar",
        amplitude_v=voltage_v,
        rise_s=SEED003_RISE_FALL_S,  # seed 003 part 1, Table 1
        fall_s=SEED003_RISE_FALL_S,  # seed 003 part 1, Table 1
        dwell_s=SEED003_DWELL_S,  # seed 003 part 1, Table 1
        echo_s=SEED003_ECHO_S,  # seed 003 part 1, Table 1
        frequency_hz=SEED003_FREQUENCY_HZ,  # seed 003 part 1, Table 1
    )
