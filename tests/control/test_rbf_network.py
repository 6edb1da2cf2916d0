"""Tests of the RBF network design module (seed 001 §3.2, eq. 2) and its re-export."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.control import rbf, rbf_network
from microfab.control.rbf import RBFAdaptive
from microfab.control.rbf_network import N_Z, RBFConfig, networks_for_reference

DT = 1e-4  # assumed sample rate 10 kHz (shared contract)
A = 0.075  # mm: the 0.15 mm circle of seed 001 §4.2
N_PER = 10_000  # one 1 s period at 10 kHz (assumed circle rate 1 Hz)


def circle() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One period of a circle of radius A centred at (0, A): p, v, a, each (N_PER, 2)."""
    w = 2 * math.pi
    t = np.arange(N_PER) * DT
    p = np.column_stack([A * np.sin(w * t), A * (1 - np.cos(w * t))])
    v = np.column_stack([A * w * np.cos(w * t), A * w * np.sin(w * t)])
    a = np.column_stack([-A * w * w * np.sin(w * t), A * w * w * np.cos(w * t)])
    return p, v, a


def test_names_stay_importable_from_rbf():
    for name in ("RBFConfig", "RBFNetwork", "networks_for_reference", "N_Z", "N_AXES"):
        assert getattr(rbf, name) is getattr(rbf_network, name)


def test_default_design_is_25_centres_on_6d_inputs():
    nets = networks_for_reference(*circle())
    assert RBFConfig().n_nodes == 25 and N_Z == 6
    for net in nets:
        assert net.centres.shape == (25, 6)
        assert net.widths.shape == (25,)
        assert np.all(net.widths > 0)


def test_controller_uses_the_same_networks():
    p, v, a = circle()
    cfg = RBFConfig(n_nodes=12)
    nets = networks_for_reference(p, v, a, cfg)
    ctl = RBFAdaptive.for_reference(p, v, a, DT, cfg)
    for mine, its in zip(nets, ctl.networks, strict=True):
        for field in ("offset", "scale", "centres", "widths", "weights"):
            np.testing.assert_array_equal(getattr(mine, field), getattr(its, field))


def test_design_refuses_a_non_config_and_a_short_reference():
    p, v, a = circle()
    with pytest.raises(ValueError, match="must be an RBFConfig, got dict"):
        networks_for_reference(p, v, a, {"n_nodes": 25})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="fewer than n_nodes = 25"):
        networks_for_reference(p[:10], v[:10], a[:10])
