"""The ``[ilc]`` keys of the ``msl-ilc`` job that ``microfab ilc step`` shares.

A light module (it imports `microfab.io.job` only), so that the command line declares its
options with these keys without importing the learning run: ``ilc step --cutoff-hz`` and
``--gain`` set what ``[ilc] cutoff_hz`` and ``gain`` set, with the same unit and range.
"""

from __future__ import annotations

from microfab.io.job import Key

__all__ = ["FS_HZ", "ILC_CUTOFF_HZ", "ILC_GAIN"]

FS_HZ = 1_000_000  # seed 000 §3.1: the loop runs at 1 MHz; a rate must divide it

#: Highest learned harmonic (seed 000 §4: 8 kHz), at most the loop's Nyquist frequency.
ILC_CUTOFF_HZ = Key(
    name="cutoff_hz",
    type="float",
    default=8000.0,
    low=1.0,
    high=FS_HZ / 2,
    unit="Hz",
    help="Highest learned harmonic (seed 000 §4: 8 kHz).",
)
#: Learning gain rho (seed 000 §4: 0.4); the update converges for 0 < rho < 2.
ILC_GAIN = Key(
    name="gain",
    type="float",
    default=0.4,
    low=1e-6,
    high=2.0,
    help="Learning gain rho (seed 000 §4: 0.4).",
)
