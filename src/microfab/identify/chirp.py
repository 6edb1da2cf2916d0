"""Chirp experiment design for frequency-response identification (seed 003 part 2, §1).

The seed (Buls et al., §1 "System Identification") excites one galvo axis with a chirp
"with a start frequency of 10Hz and a stop frequency of 2kHz", "amplitude ... 100bit",
"measurement period of 1s", and records the measured position every T = 10 µs (§2
"fs = 1e-5", the sample period). `ChirpDesign` holds those numbers as defaults; what the
seed leaves open is assumed and said so: a linear sweep (a logarithmic one is an option),
repeated ``n_periods = 4`` times with the first ``n_dropped = 1`` periods dropped so that
the transient of the first period does not enter the estimate.

One period of the sweep, ``t`` in ``[0, period_s)``:

* linear: ``f(t) = f0 + (f1 - f0) t / P``,
  ``u(t) = A sin(2 pi (f0 t + (f1 - f0) t^2 / (2 P)))``;
* log: ``f(t) = f0 (f1 / f0)^(t / P)``,
  ``u(t) = A sin(2 pi f0 P (exp(t ln(f1/f0) / P) - 1) / ln(f1/f0))``.

The period holds a whole number of samples, so the repeated signal is exactly periodic in
samples and the FFT of one period has no leakage: its bins are ``1 / period_s`` apart and
`microfab.identify.frf.frf_periodic` divides output by input bin by bin. The spectrum of a
linear chirp is nearly flat between ``f0`` and ``f1`` and falls off outside over about
``sqrt((f1 - f0) / P)`` Hz (45 Hz for the seed's sweep); the band the FRF may be read in is
``[f0, f1]``.

`ChirpDesign.signal` gives a `Chirp`: the design and the input samples, which
`microfab.identify.frf.estimate_frf` reads together with the recorded output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.validate import check_int, check_positive

__all__ = ["SWEEPS", "Chirp", "ChirpDesign", "Sweep"]

Sweep = Literal["linear", "log"]
SWEEPS: tuple[str, ...] = ("linear", "log")
_PERIOD_TOL = 1e-9  # relative tolerance of "period_s is a whole number of samples"


@dataclass(frozen=True, kw_only=True)
class ChirpDesign:
    """A periodic chirp experiment: sweep, amplitude, repetitions, sample time.

    Parameters
    ----------
    f0_hz : float
        Start frequency, Hz (seed 003 part 2 §1: 10 Hz). At least one FFT bin,
        ``1 / period_s``.
    f1_hz : float
        Stop frequency, Hz (seed §1: 2 kHz), above ``f0_hz`` and below the Nyquist
        frequency ``1 / (2 dt)``.
    amplitude : float
        Amplitude of the sine, in the input's unit (seed §1: 100 bit).
    period_s : float
        Length of one sweep, s (seed §1: "measurement period of 1s"); a whole number of
        samples ``dt``.
    n_periods : int
        Sweeps played back to back (assumed 4: three kept for averaging and the
        coherence, one dropped).
    n_dropped : int
        Leading periods left out of the analysis, while the transient dies out (assumed
        1); ``0 <= n_dropped < n_periods``.
    dt : float
        Sample time, s (seed §2: "fs = 1e-5", the period T = 10 µs).
    sweep : {"linear", "log"}
        Frequency law (assumed linear: the seed does not say).
    unit : str
        Unit of the input samples (default "bit", the seed's).

    Raises
    ------
    ValueError
        A non-positive or non-finite number, ``f0_hz`` below one bin, ``f1_hz`` not
        above ``f0_hz`` or not below Nyquist, a period that is not a whole number of
        samples, ``n_dropped`` not below ``n_periods``, an unknown sweep; the message
        names the parameter, the value, its unit and the fix.
    """

    f0_hz: float = 10.0  # seed 003 part 2 §1: start frequency 10 Hz
    f1_hz: float = 2000.0  # seed §1: stop frequency 2 kHz
    amplitude: float = 100.0  # seed §1: amplitude 100 bit
    period_s: float = 1.0  # seed §1: measurement period 1 s
    n_periods: int = 4  # assumed: 3 kept periods give an average and a coherence
    n_dropped: int = 1  # assumed: the first period holds the start-up transient
    dt: float = 1e-5  # seed §2: "fs = 1e-5" is the sample period T = 10 us
    sweep: Sweep = "linear"  # assumed: the seed does not name the law
    unit: str = "bit"

    def __post_init__(self) -> None:
        dt = check_positive("dt", self.dt, "s")
        period = check_positive("period_s", self.period_s, "s")
        f0 = check_positive("f0_hz", self.f0_hz, "Hz")
        f1 = check_positive("f1_hz", self.f1_hz, "Hz")
        check_positive("amplitude", self.amplitude, self.unit)
        n_per = check_int("n_periods", self.n_periods, 1)
        n_drop = check_int("n_dropped", self.n_dropped, 0)
        if self.sweep not in SWEEPS:
            raise ValueError(f"sweep must be one of {', '.join(SWEEPS)}, got {self.sweep!r}")
        ratio = period / dt
        n = round(ratio)
        if n < 2 or abs(ratio - n) > _PERIOD_TOL * ratio:
            raise ValueError(
                f"period_s must be a whole number (>= 2) of samples dt = {dt:g} s, got "
                f"{period!r} s ({ratio:.10g} samples): use {max(n, 2) * dt:.10g} s"
            )
        if n_drop >= n_per:
            raise ValueError(
                f"n_dropped must be below n_periods = {n_per} (at least one period is kept), "
                f"got {n_drop}"
            )
        bin_hz = 1.0 / period
        if f0 < bin_hz * (1.0 - 1e-12):
            raise ValueError(
                f"f0_hz must be at least one FFT bin, 1 / period_s = {bin_hz:g} Hz, got "
                f"{f0:g} Hz: raise f0_hz or lengthen period_s"
            )
        nyquist = 0.5 / dt
        if f1 >= nyquist:
            raise ValueError(
                f"f1_hz must lie below the Nyquist frequency 1 / (2 dt) = {nyquist:g} Hz, got "
                f"{f1:g} Hz: lower f1_hz or shorten dt"
            )
        if f1 <= f0:
            raise ValueError(f"f1_hz must exceed f0_hz = {f0:g} Hz, got {f1:g} Hz")

    @property
    def samples_per_period(self) -> int:
        """Samples in one sweep, ``period_s / dt``."""
        return round(self.period_s / self.dt)

    @property
    def n_samples(self) -> int:
        """Samples of the whole experiment, ``n_periods * samples_per_period``."""
        return self.n_periods * self.samples_per_period

    @property
    def duration_s(self) -> float:
        """Length of the whole experiment, s."""
        return self.n_samples * self.dt

    @property
    def bin_hz(self) -> float:
        """Frequency resolution of one period's FFT, ``1 / period_s``, Hz."""
        return 1.0 / (self.samples_per_period * self.dt)

    @property
    def nyquist_hz(self) -> float:
        """Nyquist frequency ``1 / (2 dt)``, Hz."""
        return 0.5 / self.dt

    @property
    def band_hz(self) -> tuple[float, float]:
        """The excited band ``(f0_hz, f1_hz)``, Hz: where an FRF may be read."""
        return (float(self.f0_hz), float(self.f1_hz))

    def frequency_hz(self, t: np.ndarray) -> np.ndarray:
        """Instantaneous frequency of the sweep, Hz.

        Parameters
        ----------
        t : numpy.ndarray
            Times, s, any shape; read modulo ``period_s``.

        Returns
        -------
        numpy.ndarray
            Frequencies, Hz, the shape of ``t``.
        """
        tau = np.mod(np.asarray(t, dtype=float), self.samples_per_period * self.dt)
        frac = tau / (self.samples_per_period * self.dt)
        if self.sweep == "linear":
            return self.f0_hz + (self.f1_hz - self.f0_hz) * frac
        return self.f0_hz * (self.f1_hz / self.f0_hz) ** frac

    def one_period(self) -> np.ndarray:
        """Samples of one sweep, in the input's unit, shape (samples_per_period,)."""
        n = self.samples_per_period
        period = n * self.dt  # the period the samples hold, exactly
        t = np.arange(n) * self.dt
        if self.sweep == "linear":
            phase = self.f0_hz * t + (self.f1_hz - self.f0_hz) * t * t / (2.0 * period)
        else:
            k = math.log(self.f1_hz / self.f0_hz) / period
            phase = self.f0_hz * np.expm1(k * t) / k
        return self.amplitude * np.sin(2.0 * np.pi * phase)

    def signal(self) -> Chirp:
        """The whole experiment: ``n_periods`` sweeps back to back, as a `Chirp`."""
        return Chirp(design=self, input=np.tile(self.one_period(), self.n_periods))


@dataclass(frozen=True, eq=False)
class Chirp:
    """A chirp experiment's input samples with the design that analyses them.

    Parameters
    ----------
    design : ChirpDesign
        The experiment (band, period, periods dropped, ``dt``).
    input : numpy.ndarray
        Input samples, shape (design.n_samples,), in ``design.unit``; stored read-only.
        Sample ``k`` is held over ``[k dt, (k + 1) dt)``.
    """

    design: ChirpDesign
    input: np.ndarray = field(repr=False)

    def __post_init__(self) -> None:
        u = readonly(self.input)
        if u.shape != (self.design.n_samples,):
            raise ValueError(
                f"input must have shape ({self.design.n_samples},) (the design's "
                f"{self.design.n_periods} periods of {self.design.samples_per_period}), "
                f"got {u.shape}"
            )
        if not np.all(np.isfinite(u)):
            raise ValueError(f"input holds NaN/inf at sample {int(np.argmin(np.isfinite(u)))}")
        object.__setattr__(self, "input", u)

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return self.design.dt

    @property
    def time(self) -> np.ndarray:
        """Sample times, s, shape (n_samples,)."""
        return np.arange(self.design.n_samples) * self.design.dt

    @property
    def kept(self) -> slice:
        """The samples the analysis reads: all periods after the dropped ones."""
        return slice(self.design.n_dropped * self.design.samples_per_period, None)
