from __future__ import annotations

import numpy as np
import pytest

from microfab.process.inkjet.silhouette import Silhouette

NOZ_R = 60e-6


def _cylinder(z0: float, z1: float, r: float) -> tuple[np.ndarray, np.ndarray]:
    z = np.linspace(z0, z1, 11)
    return z, np.full_like(z, r)


@pytest.mark.parametrize(
    ("bodies", "match"),
    [
        (((np.array([0.0, 2e-6, 1e-6]), np.ones(3) * 1e-6),), "strictly ascending"),
        (((np.array([0.0, 1e-6]), np.array([1e-6, -1e-7])),), "r_m must be >= 0"),
        (((np.array([0.0, 1e-6, 2e-6]), np.ones(2) * 1e-6),), "equal length"),
        (((np.array([0.0]), np.array([1e-6])),), "at least 2 samples"),
        (((np.array([0.0, np.nan]), np.ones(2)),), "finite"),
        ((np.zeros(3),), "pair"),
    ],
)
def test_silhouette_rejects_bad_bodies(bodies: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Silhouette(time_s=0.0, bodies=bodies, nozzle_radius_m=NOZ_R)


def test_silhouette_rejects_bad_scalars_and_freezes_arrays() -> None:
    with pytest.raises(ValueError, match="nozzle_radius_m"):
        Silhouette(time_s=0.0, bodies=(), nozzle_radius_m=0.0)
    with pytest.raises(ValueError, match="time_s"):
        Silhouette(time_s=float("nan"), bodies=(), nozzle_radius_m=NOZ_R)
    z, r = _cylinder(0.0, 10e-6, 1e-6)
    s = Silhouette(time_s=0.0, bodies=((z, r),), nozzle_radius_m=NOZ_R)
    r[:] = 5.0  # the silhouette holds a copy
    assert s.bodies[0][1][0] == 1e-6
    with pytest.raises(ValueError):
        s.bodies[0][1][0] = 2.0
