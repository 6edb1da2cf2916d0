"""Measured frequency responses (FRF files), e.g. of a closed scanner loop, for the ILC.

An FRF file (CSV, MATLAB ``.mat`` or HDF5, read by `microfab.io.trace.read_columns`) holds
a ``freq_hz`` column (Hz, increasing, >= 0) and, per axis ``<a>``, either ``re_<a>`` and
``im_<a>`` (the complex response) or ``mag_<a>`` and ``phase_deg_<a>`` (magnitude and
phase in degrees). The response is output over input of the stabilised machine, as the
ILC's eq. (7) would estimate it from a trial. `FRFTable.model` interpolates it (real and
imaginary parts, linearly) at other frequencies; outside the measured range it returns
NaN, which the ILC reads as "no model here" and does not learn.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microfab.io.trace import read_columns, write_columns

__all__ = ["FRFFileError", "FRFTable", "read_frf", "write_frf"]


class FRFFileError(ValueError):
    """An FRF file is unusable (missing columns, NaN, frequencies not increasing...)."""


@dataclass(frozen=True, eq=False)
class FRFTable:
    """A measured frequency response per axis.

    Attributes
    ----------
    freq_hz : numpy.ndarray
        Frequencies, Hz, increasing, shape (n_f,).
    response : numpy.ndarray
        Complex response, shape (n_f, n_axes).
    axes : tuple of str
        Axis names, in column order.
    """

    freq_hz: np.ndarray
    response: np.ndarray
    axes: tuple[str, ...]

    def model(self, axes: Sequence[str] | None = None) -> Callable[[np.ndarray], np.ndarray]:
        """An FRF model ``P(f)`` for `microfab.control.ilc.FrequencyILC` (``model=``).

        Parameters
        ----------
        axes : sequence of str, optional
            Axes in the learner's order (default: the file's).

        Returns
        -------
        callable
            ``f (n,) in Hz -> complex (n, len(axes))``; NaN outside the measured range.

        Raises
        ------
        FRFFileError
            An axis the file does not hold.
        """
        order = tuple(self.axes if axes is None else axes)
        missing = [a for a in order if a not in self.axes]
        if missing:
            raise FRFFileError(
                f"the FRF file has no axis {missing[0]!r} (it holds {', '.join(self.axes)})"
            )
        cols = [self.axes.index(a) for a in order]
        fr, h = self.freq_hz, self.response[:, cols]

        def frf(f: np.ndarray) -> np.ndarray:
            f = np.asarray(f, dtype=float)
            out = np.empty((f.size, len(cols)), complex)
            for i in range(len(cols)):
                re = np.interp(f, fr, h[:, i].real, left=np.nan, right=np.nan)
                im = np.interp(f, fr, h[:, i].imag, left=np.nan, right=np.nan)
                out[:, i] = re + 1j * im
            return out

        return frf


def read_frf(path: str | Path) -> FRFTable:
    """Read and check an FRF file (module docstring).

    Raises
    ------
    FRFFileError
        No ``freq_hz`` or no axis columns, an axis with one of a pair missing, NaN/inf,
        fewer than 2 frequencies, negative or not strictly increasing frequencies.
    FileNotFoundError
        The file does not exist.
    """
    p = Path(path)
    try:
        cols = read_columns(p)
    except ValueError as exc:
        raise FRFFileError(f"{p}: {exc}") from exc
    if "freq_hz" not in cols:
        raise FRFFileError(f"{p}: no 'freq_hz' column (found: {', '.join(cols) or 'none'})")
    pairs = (("re_", "im_"), ("mag_", "phase_deg_"))
    axes: list[str] = []
    for k in cols:
        for first, second in pairs:
            if k.startswith(first) and k[len(first) :]:
                a = k[len(first) :]
                if f"{second}{a}" not in cols:
                    raise FRFFileError(f"{p}: axis {a!r} has '{k}' but no '{second}{a}' column")
                axes.append(a)
    if not axes:
        raise FRFFileError(
            f"{p}: no axis columns: expected 're_<axis>' and 'im_<axis>', or 'mag_<axis>' "
            f"and 'phase_deg_<axis>' (found: {', '.join(cols)})"
        )
    if len(set(axes)) != len(axes):
        raise FRFFileError(f"{p}: an axis is given both as re/im and as mag/phase")
    for name, col in cols.items():
        bad = np.nonzero(~np.isfinite(col))[0]
        if bad.size:
            raise FRFFileError(f"{p}: column {name!r} holds NaN/inf at row {bad[0]}")
    f = cols["freq_hz"]
    if f.size < 2:
        raise FRFFileError(f"{p}: an FRF needs at least 2 frequencies, got {f.size}")
    if f[0] < 0 or np.any(np.diff(f) <= 0):
        raise FRFFileError(f"{p}: 'freq_hz' must be >= 0 and strictly increasing")
    resp = np.empty((f.size, len(axes)), complex)
    for i, a in enumerate(axes):
        if f"re_{a}" in cols:
            resp[:, i] = cols[f"re_{a}"] + 1j * cols[f"im_{a}"]
        else:
            mag = cols[f"mag_{a}"]
            if np.any(mag < 0):
                raise FRFFileError(f"{p}: 'mag_{a}' must be >= 0")
            resp[:, i] = mag * np.exp(1j * np.deg2rad(cols[f"phase_deg_{a}"]))
    return FRFTable(freq_hz=f.astype(float), response=resp, axes=tuple(axes))


def write_frf(
    path: str | Path, freq_hz: np.ndarray, response: np.ndarray, axes: Sequence[str]
) -> None:
    """Write an FRF file with ``re_<a>``/``im_<a>`` columns (atomically; format by suffix).

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.mat`` or ``.h5``.
    freq_hz : numpy.ndarray
        Frequencies, Hz, shape (n_f,).
    response : numpy.ndarray
        Complex response, shape (n_f, n_axes).
    axes : sequence of str
        Axis names.
    """
    h = np.asarray(response, dtype=complex).reshape(len(freq_hz), -1)
    cols = {"freq_hz": np.asarray(freq_hz, dtype=float)}
    for i, a in enumerate(axes):
        cols[f"re_{a}"] = h[:, i].real
        cols[f"im_{a}"] = h[:, i].imag
    write_columns(path, cols)
