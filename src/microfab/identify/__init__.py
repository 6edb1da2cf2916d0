"""System identification: chirp experiments, frequency responses, transfer function fits.

``chirp`` (`ChirpDesign`, `Chirp`: a periodic chirp experiment, seed 003 part 2 §1),
``frf`` (`FRF`; `frf_periodic`, the per-period FFT ratio, and `frf_h1`, H1 with coherence
via Welch; `estimate_frf` from a `Chirp` and its recorded output), ``model`` (`TFModel`:
a continuous transfer function with its poles, gain, modes, bandwidth, JSON form and
python-control form) and ``fit`` (`fit_tf`: Sanathanan-Koerner start, then non-linear
least squares on the coherence-weighted complex FRF, sampling-aware; `FitResult`).

Layer: above ``trajectory`` and below ``control`` (a shaper designed from a fitted model
imports this package; this package imports only ``plants``, ``io`` and ``core``).
"""

from microfab.identify.chirp import Chirp, ChirpDesign
from microfab.identify.fit import FitResult, UnstableFitError, fit_tf
from microfab.identify.frf import FRF, LowCoherenceError, estimate_frf, frf_h1, frf_periodic
from microfab.identify.model import PoleMode, TFModel

__all__ = [
    "FRF",
    "Chirp",
    "ChirpDesign",
    "FitResult",
    "LowCoherenceError",
    "PoleMode",
    "TFModel",
    "UnstableFitError",
    "estimate_frf",
    "fit_tf",
    "frf_h1",
    "frf_periodic",
]
