"""Silhouette: the radius profiles of the liquid bodies at one instant.

The drop-on-demand model (:mod:`.droplet`) describes the jet at each stored time as a set
of axisymmetric liquid bodies, each a radius profile ``r(z)`` downstream of the nozzle
exit. That is the physics output; cameras and image analysis
(:mod:`microfab.measure.shadowgraph`, :mod:`microfab.measure.imaging`) turn it into frames
and measure it back, like the strobed JetXpert camera of seed 003 part 1
(``../shared/seeds/003_4915b267b12a78d4.txt``, Fig. 2 and 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from microfab.core.validate import check_finite, check_positive

__all__ = ["BodyProfile", "Silhouette"]

#: One liquid body: axial positions (m) and radii (m), both shape (n,).
BodyProfile = tuple[np.ndarray, np.ndarray]


def _check_body(index: int, body: object) -> BodyProfile:
    try:
        z_raw, r_raw = body  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ValueError(f"body {index} must be a pair (z_m, r_m) of arrays") from None
    z = np.array(z_raw, dtype=float)
    r = np.array(r_raw, dtype=float)
    if z.ndim != 1 or r.ndim != 1 or z.shape != r.shape:
        raise ValueError(
            f"body {index}: z_m and r_m must be 1-D arrays of equal length, "
            f"got shapes {z.shape} and {r.shape}"
        )
    if z.size < 2:
        raise ValueError(f"body {index}: needs at least 2 samples, got {z.size}")
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(r))):
        raise ValueError(f"body {index}: z_m and r_m must be finite")
    if np.any(np.diff(z) <= 0):
        k = int(np.argmax(np.diff(z) <= 0))
        raise ValueError(
            f"body {index}: z_m must be strictly ascending, got {z[k]} m then {z[k + 1]} m"
        )
    if np.any(r < 0):
        k = int(np.argmax(r < 0))
        raise ValueError(f"body {index}: r_m must be >= 0, got {r[k]} m at z = {z[k]} m")
    z.setflags(write=False)
    r.setflags(write=False)
    return z, r


@dataclass(frozen=True, kw_only=True)
class Silhouette:
    """Axisymmetric liquid bodies at one instant, as a 1D jet solver describes them.

    Attributes
    ----------
    time_s : float
        Time of the snapshot in s (finite; e.g. since the start of the drive pulse).
    bodies : tuple of (numpy.ndarray, numpy.ndarray)
        One ``(z_m, r_m)`` pair per liquid body: axial positions in m downstream of the
        nozzle exit plane (strictly ascending) and the local radius in m (>= 0). The body
        attached to the nozzle starts at ``z = 0`` with ``r`` equal to the nozzle radius.
        Between samples the radius is interpolated linearly; outside its ``z`` range a body
        is absent. Arrays are copied and made read-only. May be empty (no liquid out).
    nozzle_radius_m : float
        Radius of the nozzle orifice in m (> 0); 60 µm for the seed's 120 µm orifice.

    Raises
    ------
    ValueError
        If a value is not finite/positive or a body is malformed (lengths, order, sign).
    """

    time_s: float
    bodies: tuple[BodyProfile, ...]
    nozzle_radius_m: float

    def __post_init__(self) -> None:
        check_finite("time_s", self.time_s, "s")
        check_positive("nozzle_radius_m", self.nozzle_radius_m, "m")
        checked = tuple(_check_body(i, b) for i, b in enumerate(self.bodies))
        object.__setattr__(self, "bodies", checked)
