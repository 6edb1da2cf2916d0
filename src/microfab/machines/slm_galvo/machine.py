"""The SLM galvo scanner of seed 003 part 2 as a machine: its twin, limits and loop.

`twin` builds the scanner (`microfab.plants.galvo_slm.galvo_slm_twin`) from the data file
parsed once, once per distinct settings (`microfab.machines.twins`), so the
identification, the shaper comparison, the scan-time estimates and the whole build of one
process share it. `play` runs a command through the scanner's loop (the RTC's set point,
`microfab.control.setpoint.SetPoint`, on the compiled simulator) and returns what its
encoders measure; `chirp_frf` plays the seed's chirp experiment (§1) and estimates the
FRF. `limits` are the scanner's declared limits at the work plane.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from microfab.control.setpoint import SetPoint
from microfab.core.limits import MachineLimits
from microfab.identify.chirp import Chirp, ChirpDesign
from microfab.identify.frf import FRF, estimate_frf
from microfab.machines.twins import TwinCache
from microfab.plants.galvo_slm import GalvoSLMParams, GalvoSLMPlant, galvo_slm_twin, load_params
from microfab.sim.loop import simulate

__all__ = ["DATA_FILES", "SEED_MODEL_DEN", "SEED_MODEL_NUM", "chirp_frf", "limits", "play", "twin"]

#: The packaged data file the twin is built from (every value with its source).
DATA_FILES = ("galvo_slm.toml",)

#: The identified model ``G(s) = b0 / (s^3 + a2 s^2 + a1 s + a0)`` of one axis, bit/bit:
#: what the seed's model-inverse shaper inverts.
SEED_MODEL_NUM = (1.242e11,)  # seed 003 part 2 §1, G(s) numerator
SEED_MODEL_DEN = (1.0, 9517.0, 5.773e7, 1.272e11)  # seed 003 part 2 §1, G(s) denominator

_TWINS: TwinCache[GalvoSLMParams, GalvoSLMPlant] = TwinCache(
    load_params, lambda cfg, **s: galvo_slm_twin(params=cfg, **s), DATA_FILES[0]
)


def twin(
    path: str | os.PathLike[str] | None = None, *, mirror_mode: bool = False, **overrides: Any
) -> GalvoSLMPlant:
    """`galvo_slm_twin` (same arguments), parsed and built once per distinct settings."""
    return _TWINS(path, mirror_mode=mirror_mode, **overrides)


def limits() -> MachineLimits:
    """The scanner's declared limits at the work plane, m (all assumed, seed 003 part 2)."""
    return MachineLimits.seed003_slm()


def play(
    command: np.ndarray,
    *,
    mirror_mode: bool = False,
    noise_seed: int | None = None,
    plant: GalvoSLMPlant | None = None,
) -> np.ndarray:
    """Play a set-point command through the scanner's loop from rest; what it measures.

    Parameters
    ----------
    command : numpy.ndarray
        Set position of x and y per 10 µs tick, bit, shape (n, 2).
    mirror_mode : bool
        The twin with its optional mirror mode (assumed 3 kHz, ζ 0.02).
    noise_seed : int, optional
        Add the twin's measurement noise (0.3 bit, seeded); None: no noise.
    plant : GalvoSLMPlant, optional
        Another twin (another data file); ``mirror_mode`` is then ignored.

    Returns
    -------
    numpy.ndarray
        Measured x and y positions, bit, shape (n, 2).
    """
    t = plant if plant is not None else twin(mirror_mode=mirror_mode)
    u = np.asarray(command, dtype=float)
    n = u.shape[0]
    v = t.noise(n, noise_seed) if noise_seed is not None else np.zeros((n, 2))
    return simulate(t, SetPoint(2), u, v).measured


def chirp_frf(
    design: ChirpDesign,
    *,
    mirror_mode: bool = False,
    noise_seed: int | None = None,
    plant: GalvoSLMPlant | None = None,
) -> tuple[Chirp, np.ndarray, FRF]:
    """The chirp experiment of seed 003 part 2 §1 on the x axis: the FRF per period.

    Parameters
    ----------
    design : ChirpDesign
        The excitation (on the twin's 10 µs tick), bit.
    mirror_mode, noise_seed, plant
        As `play`.

    Returns
    -------
    chirp : Chirp
        The input played.
    measured : numpy.ndarray
        Measured x position, bit, shape (n,).
    frf : FRF
        `microfab.identify.frf.estimate_frf` of ``measured`` over the chirp.
    """
    chirp = design.signal()
    n = chirp.input.size
    y = play(
        np.column_stack([chirp.input, np.zeros(n)]),
        mirror_mode=mirror_mode,
        noise_seed=noise_seed,
        plant=plant,
    )
    measured = np.ascontiguousarray(y[:, 0])
    return chirp, measured, estimate_frf(chirp, measured)
