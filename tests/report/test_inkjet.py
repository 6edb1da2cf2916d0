"""Figures of seed 003 part 1: nozzle flow, regime map, frame montage, analysis, sweep."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure

from microfab.machines.printhead.machine import (
    DropletSettings,
    SweepPoint,
    droplet_sweep,
    sweep_points,
)
from microfab.measure.imaging import analyze
from microfab.measure.shadowgraph import Camera, render_sequence
from microfab.plants.printhead import nozzle_flow
from microfab.process.inkjet.dimensionless import regime_map
from microfab.process.inkjet.dispenser import default_printhead
from microfab.process.inkjet.silhouette import Silhouette
from microfab.report.inkjet import (
    fig_analysis,
    fig_montage,
    fig_nozzle_flow,
    fig_regime_map,
    fig_sweep,
)
from microfab.trajectory.waveform import seed003_waveform

US = 1e-6
WATER = {"density_kg_m3": 1000.0, "viscosity_pa_s": 1e-3, "surface_tension_n_m": 0.072}

# --- synthetic front-pinching jet of tests/measure/test_imaging.py (same frames) -------

PX = 2e-6
NOZ_R = 60e-6
HEAD_R = 40e-6
LIG_R = 10e-6
SAT_R = 12e-6
CONE = 30e-6
SPEED = 4.0
DT = 10e-6
N_FRAMES = 15
TIP0 = 120e-6
KB = 6
CAM = Camera(pixel_size_m=PX, width_px=120, height_px=400, blur_px=1.2, noise_std=0.03)
Z = np.arange(0.0, 800e-6, 0.25e-6)


def _sphere(zc: float, radius: float) -> np.ndarray:
    return np.sqrt(np.clip(radius**2 - (Z - zc) ** 2, 0.0, None))


def _capsule(za: float, zb: float, a: float) -> np.ndarray:
    """Rod of radius ``a`` with hemispherical ends, from ``za`` to ``zb``."""
    if zb - za <= 2 * a:
        return _sphere((za + zb) / 2, (zb - za) / 2)
    zc = np.clip(Z, za + a, zb - a)
    return np.sqrt(np.clip(a**2 - (Z - zc) ** 2, 0.0, None))


def _cone() -> np.ndarray:
    return np.where(Z <= CONE, NOZ_R + (LIG_R - NOZ_R) * Z / CONE, 0.0)


def _body(r: np.ndarray, z0: float, z1: float) -> tuple[np.ndarray, np.ndarray]:
    sel = (Z >= z0 - 1e-12) & (Z <= z1 + 1e-12)
    return Z[sel], r[sel]


def _tip(k: int) -> float:
    return TIP0 + SPEED * DT * k


def _scenario(frac: float, n_sat: int, kb: int | None = KB) -> list[Silhouette]:
    gap = frac * _tip(kb) if kb is not None else math.inf
    out = []
    for k in range(N_FRAMES):
        tip = _tip(k)
        zc = tip - HEAD_R
        if kb is None or k < kb:
            r = np.maximum.reduce([_cone(), _capsule(-LIG_R, zc, LIG_R), _sphere(zc, HEAD_R)])
            bodies = [_body(r, 0.0, tip)]
        else:
            half = 5e-6 + 10e-6 * (k - kb)
            end = max(gap - half, 20e-6)
            bodies = [_body(np.maximum(_cone(), _capsule(-LIG_R, end, LIG_R)), 0.0, end)]
            if k < kb + 3:
                r = np.maximum(_capsule(gap + half, zc, LIG_R), _sphere(zc, HEAD_R))
                bodies.append(_body(r, gap + half, tip))
            else:
                tail = tip - 2 * HEAD_R
                for i in range(n_sat):
                    c = end + (tail - end) * (i + 1) / (n_sat + 1)
                    bodies.append(_body(_sphere(c, SAT_R), c - SAT_R, c + SAT_R))
                bodies.append(_body(_sphere(zc, HEAD_R), tail, tip))
        out.append(Silhouette(time_s=k * DT, bodies=tuple(bodies), nozzle_radius_m=NOZ_R))
    return out


@pytest.fixture(scope="module")
def rendered() -> dict[str, np.ndarray]:
    # the "front" case of tests/measure/test_imaging.py: gap at 0.76 of the jet, 2 satellites
    return {"front": render_sequence(_scenario(0.76, 2), CAM, seed=0)}


def _fake(calls: list[SweepPoint]):
    def sim(p: SweepPoint, settings: DropletSettings) -> dict[str, Any]:
        calls.append(p)
        t = None if p.concentration_pct > 1.5 else 1e-4 * (1 + p.concentration_pct)
        return {"breakup_time_s": t, "breakup_mode": None if t is None else "exit"}

    return sim


def test_fig_nozzle_flow() -> None:
    wave = seed003_waveform()
    flow = nozzle_flow(default_printhead(), wave, **WATER, duration_s=100 * US)
    fig = fig_nozzle_flow(flow, wave)
    assert isinstance(fig, Figure)
    ax_v, ax_u = fig.axes
    np.testing.assert_allclose(ax_u.lines[0].get_ydata(), flow.velocity_m_s)
    np.testing.assert_allclose(ax_v.lines[0].get_xdata(), flow.t_s * 1e6)
    assert "µs" in ax_u.get_xlabel()
    # with the meniscus: a third axis in µm, 0 at the rim
    t = np.linspace(0.0, 100 * US, 11)
    z = -np.linspace(0.0, 50e-6, 11)
    fig = fig_nozzle_flow(flow, wave, (t, z))
    ax_v, ax_u, ax_m = fig.axes
    np.testing.assert_allclose(ax_m.lines[0].get_ydata(), z * 1e6)
    assert "meniscus" in ax_m.get_ylabel() and "µs" in ax_m.get_xlabel()


def test_fig_regime_map_builds() -> None:
    cs = np.array([0.15, 0.2, 0.25, 0.5, 1.0, 1.5, 2.0])
    vs = np.linspace(0.5, 12.0, 7)
    m = regime_map(cs, vs)
    fig = fig_regime_map(m, points=[(0.15, 3.0, "seed"), (1.0, 3.0)])
    assert len(fig.axes) == 2
    assert fig.axes[0].get_xscale() == "log" and fig.axes[0].get_yscale() == "log"
    fig2 = fig_regime_map(m, voltages_v=np.linspace(40.0, 70.0, 7), points=[(1.0, 3.0)])
    assert len(fig2.axes) == 2
    assert "voltage" in fig2.axes[1].get_xlabel()
    fig2.canvas.draw()
    with pytest.raises(ValueError, match="voltages_v"):
        fig_regime_map(m, voltages_v=[40.0, 50.0])


def test_fig_montage() -> None:
    cam = Camera(width_px=30, height_px=90)
    frames = np.full((4, 90, 30), 0.8)
    fig = fig_montage(frames, [0.0, 10e-6, 20e-6, 95e-6], cam)
    assert len(fig.axes) == 4
    assert [ax.get_title() for ax in fig.axes] == ["0 µs", "10 µs", "20 µs", "95 µs"]
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert texts == ["20 µm"]  # 1-2-5 bar not longer than 60 % of the 60 µm frame width
    with pytest.raises(ValueError, match="one time per frame"):
        fig_montage(frames, [0.0], cam)


def test_fig_analysis(rendered: dict[str, np.ndarray]) -> None:
    res = analyze(rendered["front"], pixel_size_m=PX, frame_interval_s=DT)
    fig = fig_analysis(res, rendered["front"])
    assert len(fig.axes) == 2
    assert "front-pinching" in fig.axes[1].get_title()
    with pytest.raises(ValueError, match="frames"):
        fig_analysis(res, rendered["front"][:3])


def test_fig_sweep_draws_both_panels() -> None:
    rows = droplet_sweep(sweep_points([0.15, 1.0, 2.0], [45, 55]), simulate=_fake([])).rows
    fig = fig_sweep(rows, seed_points={0.15: (95e-6, "front"), 1.0: (230e-6, "exit")})
    ax_c, ax_v = fig.axes
    assert len(ax_c.lines) == 3  # model, no-breakup crosses, seed
    assert list(ax_v.lines[0].get_xdata()) == [45.0, 50.0, 55.0]
