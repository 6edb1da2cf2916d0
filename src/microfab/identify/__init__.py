"""System identification: chirp experiments, frequency responses, transfer function fits.

Seed 003 part 2 (the SLM galvo): ``chirp`` (`ChirpDesign`, `Chirp`: a periodic chirp
experiment, §1),
``frf`` (`FRF`; `frf_periodic`, the per-period FFT ratio, and `frf_h1`, H1 with coherence
via Welch; `estimate_frf` from a `Chirp` and its recorded output), ``model`` (`TFModel`:
a continuous transfer function with its poles, gain, modes, bandwidth, JSON form and
python-control form) and ``fit`` (`fit_tf`: Sanathanan-Koerner start, then non-linear
least squares on the coherence-weighted complex FRF, sampling-aware; `FitResult`).

Seed 002 (the black-box XY stage): ``excitation`` (random, shape, PRBS and chirp runs
within Table I, the ANN data set and its split), ``subspace`` (chunked MOESP/N4SID/CVA,
`identify_subspace`, `SubspaceModel`), ``stage_data`` (measured runs checked, the
anti-alias decimation, `fit_linear`, errors from rest, the model file), ``ann_data``
(eq. 7 windows and scaling), ``ann`` (per-axis networks of eq. 7 and `AnnModel`) and
``ann_train`` (`train_ann`, checkpoints); the last two import torch, so they are not
imported here).

Layer: above ``trajectory`` and below ``control`` (a shaper designed from a fitted model
imports this package; this package imports ``trajectory``, ``geometry``, ``plants``,
``io`` and ``core``).
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
