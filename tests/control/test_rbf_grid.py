"""The state-box grid of RBF centres (seed 001 §3.2 network as a model of the state)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.control.rbf_grid import WIDE, networks_for_box
from microfab.control.rbf_network import RBFConfig


def _sines(n: int = 2000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) * 1e-3
    w = 2 * math.pi * np.array([1.0, math.sqrt(2.0)])
    pos = 0.25 + 0.075 * np.sin(w * t[:, None])
    vel = 0.075 * w * np.cos(w * t[:, None])
    acc = -0.075 * w**2 * np.sin(w * t[:, None])
    return pos, vel, acc


def test_grid_covers_the_state_box_with_widths_of_one_spacing() -> None:
    pos, vel, acc = _sines()
    cfg = RBFConfig(n_nodes=5 * 3 * 3 * 3, lam=100.0, width_factor=1.0, s_spread=0.0)
    nx, ny = networks_for_box(pos, vel, acc, cfg, counts=(5, 3, 3, 3), margin=0.1)
    assert nx.n_nodes == ny.n_nodes == 135
    np.testing.assert_array_equal(nx.widths, 1.0)
    # the centres are the integer lattice in scaled units; s and v one layer, flat
    assert set(np.unique(nx.centres[:, 0])) == {0.0, 1.0, 2.0, 3.0, 4.0}
    np.testing.assert_array_equal(nx.centres[:, 4:], 0.0)
    np.testing.assert_array_equal(nx.scale[4:], WIDE)
    # the own position's box: its range widened by 10 %, 4 spacings across
    lo, hi = pos[:, 0].min(), pos[:, 0].max()
    span = 1.1 * (hi - lo)
    assert nx.scale[0] == pytest.approx(span / 4, rel=1e-12)
    assert nx.offset[0] == pytest.approx(0.5 * (lo + hi) - span / 2, rel=1e-12)
    # velocities: half-range λA + V, widened
    A, V = 0.5 * np.ptp(pos[:, 0]), 0.5 * np.ptp(vel[:, 0])
    assert nx.scale[1] == pytest.approx(2 * 1.1 * (100.0 * A + V) / 2, rel=1e-12)
    # every state on the path is near a centre: the largest h at least exp(-1/2 * 4 * 0.25)
    z = np.column_stack([pos[:, 0], vel[:, 0], pos[:, 1], vel[:, 1], 0 * pos[:, 0], 0 * pos[:, 0]])
    assert nx.hidden(z).max(axis=1).min() >= math.exp(-0.5) - 1e-9
    # y's network takes y as its own axis
    assert ny.offset[0] == pytest.approx(nx.offset[2], rel=1e-12)


def test_an_axis_at_rest_gets_one_flat_layer() -> None:
    pos, vel, acc = _sines()
    pos[:, 1], vel[:, 1], acc[:, 1] = 0.25, 0.0, 0.0
    cfg = RBFConfig(n_nodes=7 * 3 * 3 * 3, s_spread=0.0)
    nx, _ = networks_for_box(pos, vel, acc, cfg, counts=(7, 3, 3, 3))
    assert nx.scale[2] == WIDE and nx.offset[2] == 0.25
    np.testing.assert_array_equal(nx.centres[:, 2:4], 0.0)


@pytest.mark.parametrize(
    ("counts", "n_nodes", "match"),
    [
        ((7, 3, 3), 63, "one grid size per state"),
        ((7, 0, 3, 3), 63, r"counts\[1\]"),
        ((7, 3, 3, 3), 25, "n_nodes = 25 but the grid"),
    ],
)
def test_bad_grids_are_refused(counts: tuple[int, ...], n_nodes: int, match: str) -> None:
    pos, vel, acc = _sines(100)
    with pytest.raises(ValueError, match=match):
        networks_for_box(pos, vel, acc, RBFConfig(n_nodes=n_nodes), counts=counts)
