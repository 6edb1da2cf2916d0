"""The FRF record: a single-input single-output response on a grid of frequencies.

`FRF` holds what an estimator of :mod:`.frf` (`frf_periodic`, `frf_h1`, `estimate_frf`)
or a measured FRF file (`FRF.from_table`) gives: frequencies, complex response, coherence
(NaN where unknown), the method, the sample time and the excited band. `FRF.band` selects
a band for a fit and refuses a band outside the excitation or above Nyquist, and one where
the coherence falls below a threshold (0.8 by default, issue 16) over some range, naming
the range (`CoherenceRange`, `LowCoherenceError`); `FRF.plot` draws it. Apart from the
estimators (:mod:`.frf`), which build it and re-export these names.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal, NamedTuple

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.validate import check_in_range, check_int, check_nonnegative, check_positive
from microfab.identify.plotting import MIN_COHERENCE, bode_axes, draw_coherence, draw_response

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from microfab.io.frf import FRFTable

__all__ = [
    "FRF",
    "CoherenceRange",
    "LowCoherenceError",
]

FRFMethod = Literal["periodic", "h1", "table"]
_METHODS: tuple[str, ...] = ("periodic", "h1", "table")
_MERGE_REL = 0.05  # low-coherence frequencies closer than 5 % of f form one range


class CoherenceRange(NamedTuple):
    """A frequency range where the coherence falls below a threshold.

    Attributes
    ----------
    start_hz, stop_hz : float
        First and last frequency below the threshold, Hz.
    n_low : int
        Frequencies of the range below the threshold.
    n_frequencies : int
        Frequencies of the FRF from ``start_hz`` to ``stop_hz``.
    lowest : float
        Lowest coherence of the range.
    lowest_hz : float
        Where it is, Hz.
    """

    start_hz: float
    stop_hz: float
    n_low: int
    n_frequencies: int
    lowest: float
    lowest_hz: float


class LowCoherenceError(ValueError):
    """The coherence falls below the threshold over a frequency range of a band.

    Attributes
    ----------
    ranges : list of CoherenceRange
        Every range below the threshold, in order of frequency.
    """

    def __init__(self, message: str, ranges: list[CoherenceRange]) -> None:
        super().__init__(message)
        self.ranges = ranges


@dataclass(frozen=True, eq=False)
class FRF:
    """A single-input single-output frequency response on a grid of frequencies.

    Parameters
    ----------
    freq_hz : numpy.ndarray
        Frequencies, Hz, strictly increasing, shape (n,).
    response : numpy.ndarray
        Complex response output / input at ``freq_hz``, shape (n,).
    coherence : numpy.ndarray
        Coherence in [0, 1] per frequency, shape (n,); all NaN when not known (one
        period or segment averaged, or an FRF read from a file).
    method : {"periodic", "h1", "table"}
        How it was estimated (per-period FFT ratio, H1 via Welch, or given).
    dt : float or None
        Sample time of the records, s (None when not known, e.g. read from a file).
    excited_hz : (float, float)
        The band the excitation covered, Hz; `band` refuses to leave it.
    n_averages : int
        Periods or segments averaged (>= 1).
    unit : str
        Unit of the response (e.g. "bit/bit"), for labels.
    """

    freq_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    method: FRFMethod
    dt: float | None
    excited_hz: tuple[float, float]
    n_averages: int = 1
    unit: str = field(default="")

    def __post_init__(self) -> None:
        f = readonly(self.freq_hz)
        h = readonly(self.response, complex)
        c = readonly(self.coherence)
        if f.ndim != 1 or f.size < 1:
            raise ValueError(f"freq_hz must be a non-empty 1-D array, got shape {f.shape}")
        if h.shape != f.shape or c.shape != f.shape:
            raise ValueError(
                f"response and coherence must have the shape of freq_hz {f.shape}, got "
                f"{h.shape} and {c.shape}"
            )
        if not np.all(np.isfinite(f)) or f[0] < 0 or np.any(np.diff(f) <= 0):
            raise ValueError("freq_hz must be finite, >= 0 and strictly increasing")
        bad = np.nonzero(~np.isfinite(h))[0]
        if bad.size:
            raise ValueError(f"response holds NaN/inf at {f[bad[0]]:g} Hz")
        known = ~np.isnan(c)
        if np.any((c[known] < 0) | (c[known] > 1 + 1e-9)):
            raise ValueError("coherence must lie in [0, 1] (or be NaN where unknown)")
        if self.method not in _METHODS:
            raise ValueError(f"method must be one of {', '.join(_METHODS)}, got {self.method!r}")
        if self.dt is not None:
            object.__setattr__(self, "dt", check_positive("dt", self.dt, "s"))
        lo, hi = (float(v) for v in self.excited_hz)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi):
            raise ValueError(f"excited_hz must be (low, high) with 0 <= low <= high, got {lo, hi}")
        object.__setattr__(self, "excited_hz", (lo, hi))
        check_int("n_averages", self.n_averages, 1)
        object.__setattr__(self, "freq_hz", f)
        object.__setattr__(self, "response", h)
        object.__setattr__(self, "coherence", c)

    @property
    def nyquist_hz(self) -> float | None:
        """``1 / (2 dt)``, Hz, or None when ``dt`` is not known."""
        return None if self.dt is None else 0.5 / self.dt

    @classmethod
    def from_table(
        cls, table: FRFTable, axis: str | None = None, *, dt: float | None = None
    ) -> FRF:
        """One axis of a measured FRF file (`microfab.io.frf.read_frf`) as an `FRF`.

        Parameters
        ----------
        table : microfab.io.frf.FRFTable
            The file's contents.
        axis : str, optional
            The axis to take (default the first).
        dt : float, optional
            Sample time of the measurement, s, if known (a ZOH-aware fit needs it).

        Returns
        -------
        FRF
            Method "table", coherence unknown (NaN), excited band the file's range.
        """
        name = table.axes[0] if axis is None else axis
        if name not in table.axes:
            raise ValueError(f"the FRF has no axis {name!r} (it holds {', '.join(table.axes)})")
        i = table.axes.index(name)
        f = np.asarray(table.freq_hz, dtype=float)
        return cls(
            freq_hz=f,
            response=table.response[:, i],
            coherence=np.full(f.size, np.nan),
            method="table",
            dt=dt,
            excited_hz=(float(f[0]), float(f[-1])),
        )

    def low_coherence_ranges(self, threshold: float = MIN_COHERENCE) -> list[CoherenceRange]:
        """Frequency ranges where the coherence falls below ``threshold``.

        Frequencies below the threshold less than 5 % of their frequency apart
        (``_MERGE_REL``) form one range: an estimate from a few averages scatters, so a
        noisy stretch dips below the threshold at most but not all of its frequencies.

        Parameters
        ----------
        threshold : float
            Coherence limit in [0, 1] (default 0.8).

        Returns
        -------
        list of CoherenceRange
            In order of frequency; empty when the coherence is unknown (NaN) or never
            below.
        """
        check_in_range("threshold (coherence)", threshold, 0.0, 1.0)
        low = np.nonzero(self.coherence < threshold)[0]  # NaN is unknown, never refused
        if low.size == 0:
            return []
        f = self.freq_hz
        breaks = np.nonzero(f[low[1:]] - f[low[:-1]] > _MERGE_REL * f[low[1:]])[0]
        out = []
        for group in np.split(low, breaks + 1):
            a, b = int(group[0]), int(group[-1])
            j = int(group[np.argmin(self.coherence[group])])
            out.append(
                CoherenceRange(
                    start_hz=float(f[a]),
                    stop_hz=float(f[b]),
                    n_low=int(group.size),
                    n_frequencies=b - a + 1,
                    lowest=float(self.coherence[j]),
                    lowest_hz=float(f[j]),
                )
            )
        return out

    def check_coherence(self, min_coherence: float = MIN_COHERENCE) -> None:
        """Refuse an FRF whose coherence falls below ``min_coherence`` anywhere.

        Raises
        ------
        LowCoherenceError
            Naming the first range (start, stop, how many of its frequencies are low,
            the lowest value and where) and how many more there are.
        """
        ranges = self.low_coherence_ranges(min_coherence)
        if not ranges:
            return
        r = ranges[0]
        more = f" (and {len(ranges) - 1} more ranges)" if len(ranges) > 1 else ""
        raise LowCoherenceError(
            f"coherence below {min_coherence:g} from {r.start_hz:g} to {r.stop_hz:g} Hz "
            f"({r.n_low} of {r.n_frequencies} frequencies, lowest {r.lowest:.3f} at "
            f"{r.lowest_hz:g} Hz){more}: the output there is mostly noise or not linear in "
            f"the input; narrow the band, raise the amplitude or average more periods",
            ranges,
        )

    def band(self, low_hz: float, high_hz: float, *, min_coherence: float = MIN_COHERENCE) -> FRF:
        """The FRF between ``low_hz`` and ``high_hz`` (inclusive), checked.

        Parameters
        ----------
        low_hz, high_hz : float
            Band edges, Hz, ``low_hz < high_hz``.
        min_coherence : float
            Coherence every frequency of the band must reach (default 0.8; 0 checks
            nothing).

        Returns
        -------
        FRF
            The frequencies inside the band, same method, ``dt`` and excitation.

        Raises
        ------
        ValueError
            The band reaches above Nyquist, leaves the excited band (half a bin of
            slack), or holds no frequency.
        LowCoherenceError
            The coherence is below ``min_coherence`` over a range of the band (named).
        """
        lo = check_nonnegative("low_hz (band)", low_hz, "Hz")
        hi = check_positive("high_hz (band)", high_hz, "Hz")
        if hi <= lo:
            raise ValueError(f"band must have low_hz < high_hz, got {lo:g} to {hi:g} Hz")
        nyq = self.nyquist_hz
        if nyq is not None and hi > nyq:
            raise ValueError(
                f"band {lo:g}-{hi:g} Hz reaches above the Nyquist frequency {nyq:g} Hz "
                f"(dt = {self.dt:g} s): lower its upper edge"
            )
        e_lo, e_hi = self.excited_hz
        slack = 0.5 * float(np.min(np.diff(self.freq_hz))) if self.freq_hz.size > 1 else 0.0
        if lo < e_lo - slack or hi > e_hi + slack:
            raise ValueError(
                f"band {lo:g}-{hi:g} Hz lies outside the excited band {e_lo:g}-{e_hi:g} Hz "
                f"of the chirp: choose a band inside it"
            )
        sel = (self.freq_hz >= lo) & (self.freq_hz <= hi)
        if not sel.any():
            raise ValueError(f"band {lo:g}-{hi:g} Hz holds no frequency of the FRF")
        out = replace(
            self,
            freq_hz=self.freq_hz[sel],
            response=self.response[sel],
            coherence=self.coherence[sel],
        )
        if min_coherence > 0:
            out.check_coherence(min_coherence)
        return out

    def plot(self, *, title: str | None = None, label: str = "measured") -> Figure:
        """Bode plot (magnitude dB, phase deg) and coherence against frequency.

        Parameters
        ----------
        title : str, optional
            Figure title.
        label : str
            Legend label of the data.

        Returns
        -------
        matplotlib.figure.Figure
            Three axes (magnitude, phase, coherence), an Agg canvas, no pyplot.
        """
        fig, axes = bode_axes(title)
        draw_response(axes, self.freq_hz, self.response, label=label, style=".")
        draw_coherence(axes[2], self)
        axes[0].legend(loc="best")
        return fig
