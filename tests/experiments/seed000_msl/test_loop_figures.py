"""Bode plot with margins and the eq. 5 convergence figure (seed 000)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.margins import loop_margins
from microfab.experiments.seed000_msl.loop_figures import fig_bode, fig_eq5
from microfab.experiments.seed000_msl.run import run_msl_ilc
from microfab.machines.galvo import open_loop
from microfab.plants.galvo import default_galvo_axes


@pytest.fixture(scope="module")
def result():
    return run_msl_ilc(400, 3)


def test_bode_marks_each_axis_margins() -> None:
    axes = default_galvo_axes()
    fig = fig_bode(axes)
    ax_m, ax_p = fig.axes
    texts = [t.get_text() for t in ax_p.texts + ax_m.texts]
    for name, axis in axes.items():
        m = loop_margins(open_loop(axis), f_min_hz=10.0, n_points=20_000)
        assert any(t.startswith(f"{name}: PM {m.pm_deg:.1f}") for t in texts), texts
        assert any(t.startswith(f"{name}: GM {m.gm_db:.1f} dB") for t in texts), texts


def test_eq5_is_within_the_bound_on_the_twin(result) -> None:
    assert [v.shape for v in result.eq5] == [h.shape for h in result.harmonics]
    for v in result.eq5:
        assert np.all(v <= 1.0)  # seed 000 eq. 5 holds at every learned harmonic
        np.testing.assert_allclose(v, 0.6, atol=0.1)  # rho = 0.4 and P P^-1 ~ 1
    fig = fig_eq5(result)
    ax = fig.axes[0]
    assert len(ax.lines) == 3  # x, y, the bound
    f1 = result.features_per_s
    np.testing.assert_allclose(ax.lines[0].get_xdata(), result.harmonics[0] * f1 / 1e3)
