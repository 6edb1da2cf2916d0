"""Lead-lag feedback design of seed 000 eq. (1)."""

from __future__ import annotations

import numpy as np

import control
from microfab.core.validate import check_positive

__all__ = ["lead_lag"]


def lead_lag(
    plant: control.LTI,
    crossover_hz: float = 2000.0,
    *,
    integrator_pole_hz: float = 6.0,
    integrator_ratio: float = 10.0,
    lead_ratio: float = 3.0,
) -> control.TransferFunction:
    r"""Lead-lag (PID-like) controller placing the crossover at ``crossover_hz``.

    Implements seed 000 eq. (1):

    .. math::
        C(s) = \frac{1}{3|G(j\omega_c)|}\frac{\omega_i}{\omega_{it}}
               \frac{1+s/\omega_i}{1+s/\omega_{it}}\frac{1+s/\omega_d}{1+s/\omega_{dt}}

    with :math:`\omega_i=\omega_c/10`, :math:`\omega_d=\omega_c/3`,
    :math:`\omega_{dt}=3\omega_c` and :math:`\omega_{it}=2\pi\cdot 6` rad/s (seed 000 §3.1).
    The factor 1/3 cancels the lead's gain of 3 at :math:`\omega_c`, so that
    :math:`|C G| \approx 1` there.

    Parameters
    ----------
    plant : control.LTI
        Continuous plant model ``G`` used for the gain normalisation.
    crossover_hz : float
        Crossover frequency :math:`\omega_c/2\pi` in Hz (seed 000 §3.1: 2 kHz).
    integrator_pole_hz : float
        Lag pole :math:`\omega_{it}/2\pi` in Hz (seed 000 §3.1: 6 Hz).
    integrator_ratio : float
        :math:`\omega_c/\omega_i` (seed 000 §3.1: 10).
    lead_ratio : float
        :math:`\omega_c/\omega_d = \omega_{dt}/\omega_c` (seed 000 §3.1: 3).

    Returns
    -------
    control.TransferFunction
        Continuous controller.

    References
    ----------
    Seed 000 (Yoo et al., ILC for laser scanning micro 3D printing), §3.1, eq. (1).
    """
    for name, val, unit in (
        ("crossover_hz", crossover_hz, "Hz"),
        ("integrator_pole_hz", integrator_pole_hz, "Hz"),
        ("integrator_ratio", integrator_ratio, ""),
        ("lead_ratio", lead_ratio, ""),
    ):
        check_positive(name, val, unit)
    wc = 2 * np.pi * crossover_hz
    wi = wc / integrator_ratio  # seed 000 §3.1: w_i = w_c/10
    wd = wc / lead_ratio  # seed 000 §3.1: w_d = w_c/3
    wdt = lead_ratio * wc  # seed 000 §3.1: w_dt = 3 w_c
    wit = 2 * np.pi * integrator_pole_hz  # seed 000 §3.1: w_it = 2 pi 6
    if wit >= wi:
        raise ValueError(
            f"integrator_pole_hz ({integrator_pole_hz} Hz) must lie below the lag zero "
            f"({wi / 2 / np.pi:.4g} Hz)"
        )
    mag = float(np.abs(control.evalfr(plant, 1j * wc)))
    if not (np.isfinite(mag) and mag > 0):
        raise ValueError(f"|G(j w_c)| must be finite and non-zero, got {mag}")
    s = control.tf("s")
    return (
        1.0
        / (lead_ratio * mag)
        * (wi / wit)
        * (1 + s / wi)
        / (1 + s / wit)
        * (1 + s / wd)
        / (1 + s / wdt)
    )
