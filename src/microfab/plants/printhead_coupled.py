"""The printhead's acoustics without their lumped meniscus, sampled for a coupled jet model.

:mod:`microfab.plants.printhead` closes the nozzle with a lumped meniscus spring
(``V_m / C_m``, a small spherical cap). A jet model that follows the meniscus itself
(:mod:`microfab.process.inkjet.jet_euler_meniscus`: the liquid outside, a meniscus that
retracts into the bore) replaces that spring by the pressure ``p_m`` it computes, so the
meniscus is counted once. This module gives the acoustics in that form: the same channel,
nozzle inertance and resistance (`printhead_state_space` with ``meniscus_input=True``),
with inputs ``dV/dt`` (V/s) and ``p_m`` (Pa) and output the nozzle flow ``q_n`` (m³/s),
discretised with a zero-order hold at a fixed step so that a jet solver with its own
adaptive steps can march it alongside, one step at a time.

The state is diagonally balanced (:func:`scipy.linalg.matrix_balance`) before the
exponential is taken; the meniscus volume, an integrator the spring no longer reads, is
dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from microfab.core.arrays import readonly
from microfab.core.validate import check_positive
from microfab.plants.printhead import DriveSignal, Printhead, printhead_state_space

__all__ = ["DiscreteAcoustics", "discrete_acoustics", "drive_slopes"]


@dataclass(frozen=True, kw_only=True)
class DiscreteAcoustics:
    """Zero-order-hold model ``x_{k+1} = Φ x_k + γ_v s_k + γ_p p_k``, ``q_n = c·x``.

    Attributes
    ----------
    phi : numpy.ndarray
        State transition over one step, shape ``(nx, nx)`` (balanced state).
    gamma_drive : numpy.ndarray
        State increment per V/s of voltage slope held over a step, shape ``(nx,)``.
    gamma_pressure : numpy.ndarray
        State increment per Pa of meniscus pressure held over a step, shape ``(nx,)``.
    flow_row : numpy.ndarray
        Nozzle flow ``q_n`` in m³/s per state, shape ``(nx,)`` (positive out of the
        nozzle).
    dt_s : float
        Step in s.
    """

    phi: np.ndarray
    gamma_drive: np.ndarray
    gamma_pressure: np.ndarray
    flow_row: np.ndarray
    dt_s: float


def discrete_acoustics(
    printhead: Printhead,
    *,
    density_kg_m3: float,
    viscosity_pa_s: float,
    dt_s: float = 50e-9,
) -> DiscreteAcoustics:
    """The dispenser's acoustics with the meniscus pressure as an input, sampled at ``dt_s``.

    Parameters
    ----------
    printhead : Printhead
        Dispenser model.
    density_kg_m3 : float
        Liquid density in kg/m³, > 0.
    viscosity_pa_s : float
        Dynamic viscosity in Pa s, >= 0 (channel and nozzle friction).
    dt_s : float, optional
        Sample step in s, > 0 (default 50 ns, the step of
        :func:`microfab.plants.printhead.nozzle_flow`, which hits every corner of the
        seed's waveform).

    Returns
    -------
    DiscreteAcoustics

    Raises
    ------
    ValueError
        If an argument is out of range.

    Examples
    --------
    >>> ac = discrete_acoustics(Printhead(cells=10), density_kg_m3=1000.0,
    ...                         viscosity_pa_s=1e-3)
    >>> ac.phi.shape, ac.gamma_pressure.shape
    ((21, 21), (21,))
    """
    check_positive("dt_s", dt_s, "s")
    a_mat, b_mat, c_mat, _ = printhead_state_space(
        printhead,
        density_kg_m3=density_kg_m3,
        viscosity_pa_s=viscosity_pa_s,
        surface_tension_n_m=0.0,
        meniscus_input=True,
    )
    keep = a_mat.shape[0] - 1  # drop the meniscus volume: nothing reads it any more
    a_mat, b_mat, c_mat = a_mat[:keep, :keep], b_mat[:keep], c_mat[:, :keep]
    _, (scale, _) = scipy.linalg.matrix_balance(a_mat, permute=False, separate=True)
    a_bal = a_mat / scale[:, None] * scale[None, :]
    b_bal = b_mat / scale[:, None]
    c_bal = c_mat[0] * scale
    aug = np.zeros((keep + 2, keep + 2))
    aug[:keep, :keep] = a_bal * dt_s
    aug[:keep, keep:] = b_bal * dt_s
    expo = scipy.linalg.expm(aug)
    return DiscreteAcoustics(
        phi=readonly(expo[:keep, :keep]),
        gamma_drive=readonly(expo[:keep, keep]),
        gamma_pressure=readonly(expo[:keep, keep + 1]),
        flow_row=readonly(c_bal),
        dt_s=dt_s,
    )


def drive_slopes(drive: DriveSignal, *, duration_s: float, dt_s: float) -> np.ndarray:
    """Mean voltage slope over each step ``[k dt, (k + 1) dt]`` from 0 to ``duration_s``.

    Parameters
    ----------
    drive : DriveSignal
        Drive voltage.
    duration_s : float
        Span in s, > 0.
    dt_s : float
        Step in s, > 0.

    Returns
    -------
    numpy.ndarray
        Slopes in V/s, shape ``(ceil(duration_s / dt_s),)``: exact where no corner of a
        piecewise-linear drive falls inside a step, the step's mean otherwise (the
        voltage at the step ends is kept exact).

    Examples
    --------
    >>> from microfab.trajectory.waveform import seed003_waveform
    >>> s = drive_slopes(seed003_waveform(50.0), duration_s=3e-6, dt_s=1e-6)
    >>> [round(x / 1e6, 3) for x in s]
    [16.667, 16.667, 16.667]
    """
    check_positive("duration_s", duration_s, "s")
    check_positive("dt_s", dt_s, "s")
    n = max(1, math.ceil(duration_s / dt_s - 1e-9))
    t = np.arange(n + 1) * dt_s
    return np.diff(drive.voltage(t)) / dt_s
