"""A measured run on the XY stage scored against its contour as the reference job scores it.

``microfab stage score`` (`microfab.cli.stage`) scores a run played on a user's stage (or on
the twin through files, ``stage play``) with the scorer of the ``stage-reference-opt`` job
(`microfab.machines.xy_stage.reference.run_point`): the output at the 400 Hz instants
``t_1 … t_{M+TAIL}`` of eq. (13) (the same row selection,
`microfab.optimize.pipeline.at_model_rate`, not a copy of it), then eqs. (16)-(18) by
exact foot-point projection (`microfab.optimize.metrics.DeviationNorms`) over
``t_1 … t_M``, the ``TAIL`` samples after ``T`` (the input held, 500 ms) scored apart as
the tail's L∞.

``t_0`` is sample ``lead q`` of the run (``q = 25`` at 10 kHz): the optimised command of
``microfab optimize`` starts `microfab.optimize.command.LEAD` = 2 input samples before
``r_0`` (``lead = LEAD``), the baselines start at ``t_0`` (``lead = 0``), as in
`run_point`.
"""

from __future__ import annotations

import numpy as np

from microfab.geometry.path import Path as Contour
from microfab.machines.xy_stage.reference import RUN_RATE_HZ, TAIL
from microfab.optimize.metrics import DeviationNorms
from microfab.optimize.pipeline import MODEL_RATE_HZ, at_model_rate

__all__ = ["RUN_RATE_HZ", "TAIL", "samples_needed", "score_run"]

_STEP = round(RUN_RATE_HZ / MODEL_RATE_HZ)  # 10 kHz samples per 400 Hz instant: 25


def samples_needed(m: int, lead: int = 0) -> int:
    """Samples a 10 kHz run must hold to reach ``t_{M+TAIL}`` (the tail's last instant).

    Parameters
    ----------
    m : int
        ``M``, the 400 Hz instants of the run proper.
    lead : int
        Input samples (400 Hz) of the command before ``t_0``.
    """
    return (m + TAIL + lead) * _STEP + 1


def score_run(path: Contour, y: np.ndarray, m: int, lead: int = 0) -> DeviationNorms:
    """Eqs. (16)-(18) of a 10 kHz run, as `run_point` scores the runs on the twin.

    Parameters
    ----------
    path : Path
        The contour ``Ξ``, m.
    y : numpy.ndarray
        The measured positions, shape (n, 2), m, at 10 kHz from the command's first sample
        (n at least `samples_needed`).
    m : int
        ``M``: the 400 Hz instants of the run proper (the optimize folder's ``m``).
    lead : int
        Input samples (400 Hz) of the command before ``t_0``.

    Returns
    -------
    DeviationNorms
        L1, L2, L∞ over ``t_1 … t_M`` and the tail's L∞ over the ``TAIL`` after, m.

    Raises
    ------
    ValueError
        A run too short for the tail, or not (n, 2).
    """
    y = np.asarray(y, dtype=float)
    if y.ndim != 2 or y.shape[1] != 2:
        raise ValueError(f"the positions must be (n, 2), got shape {y.shape}")
    need = samples_needed(m, lead)
    if y.shape[0] < need:
        raise ValueError(
            f"the run holds {y.shape[0]} samples, the score needs {need} (to "
            f"{(need - 1) / RUN_RATE_HZ:.4g} s: the command and {TAIL / MODEL_RATE_HZ:g} s of "
            "its last set-point held)"
        )
    return DeviationNorms.of(path, at_model_rate(y, m, lead, TAIL), tail_from=m)
