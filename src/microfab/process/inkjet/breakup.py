"""Pinch-off mode: where along the jet the first breakup happens.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, "Typical droplet formation
process") names two modes by the position of the first breakup: *front-pinching* "near
the front head" and *exit-pinching* "near the nozzle outlet". The seed gives no numeric
border; we split the jet length (nozzle exit to head tip) into thirds, and call the
middle third *middle-pinching* (the name Xu et al. use for the third type in their later
work). The same rule is used by the solver and by the image analyser, so that simulated
and measured modes are comparable.
"""

from __future__ import annotations

from typing import Literal

__all__ = ["EXIT_FRACTION", "FRONT_FRACTION", "BreakupMode", "classify_pinch"]

BreakupMode = Literal["front", "exit", "middle"]

#: Pinch-off closer to the nozzle than this fraction of the jet length is "exit".
EXIT_FRACTION = 1.0 / 3.0
#: Pinch-off farther from the nozzle than this fraction of the jet length is "front".
FRONT_FRACTION = 2.0 / 3.0


def classify_pinch(z_pinch_m: float, z_tip_m: float, z_nozzle_m: float = 0.0) -> BreakupMode:
    """Name the pinch-off mode from where the jet first breaks.

    Parameters
    ----------
    z_pinch_m : float
        Axial position of the first breakup, m (downstream positive).
    z_tip_m : float
        Axial position of the head's leading tip at that moment, m.
    z_nozzle_m : float, optional
        Axial position of the nozzle exit plane, m (default 0).

    Returns
    -------
    {"front", "exit", "middle"}
        ``"exit"`` if the pinch lies in the third of the jet next to the nozzle,
        ``"front"`` if it lies in the third next to the head, else ``"middle"``.

    Raises
    ------
    ValueError
        If the tip is not downstream of the nozzle or the pinch lies outside the jet.

    Examples
    --------
    >>> classify_pinch(400e-6, 500e-6)
    'front'
    >>> classify_pinch(50e-6, 500e-6)
    'exit'
    """
    length = z_tip_m - z_nozzle_m
    if not length > 0.0:
        raise ValueError(
            f"jet length must be positive: tip at {z_tip_m} m, nozzle at {z_nozzle_m} m"
        )
    frac = (z_pinch_m - z_nozzle_m) / length
    if not -1e-9 <= frac <= 1.0 + 1e-9:
        raise ValueError(
            f"pinch at {z_pinch_m} m lies outside the jet ({z_nozzle_m} m to {z_tip_m} m)"
        )
    if frac < EXIT_FRACTION:
        return "exit"
    if frac > FRONT_FRACTION:
        return "front"
    return "middle"
