"""Eulerian slender-jet solver against theory and against the Lagrangian solver: capillary
growth, pinch-off scaling, elasto-capillary thinning, mass conservation, drop-on-demand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.process.inkjet.jet import Body, JetModel, Numerics, run_jet
from microfab.process.inkjet.jet_euler import (
    EulerInitial,
    EulerNumerics,
    euler_thread,
    run_jet_euler,
)


def _perturbed_thread(k: float, eps: float, cells: int) -> EulerInitial:
    return euler_thread(math.pi / k, lambda z: 1.0 + eps * np.cos(k * z), cells=cells)


@pytest.mark.parametrize(("k", "oh"), [(0.7, 0.1), (0.9, 0.05)])
def test_linear_growth_rate_matches_dispersion_relation(k: float, oh: float) -> None:
    # omega^2 + 3 Oh k^2 omega = k^2 (1 - k^2) / 2 (dimensionless, full-curvature 1D model)
    omega = 0.5 * (-3 * oh * k * k + math.sqrt(9 * oh**2 * k**4 + 2 * k * k * (1 - k * k)))
    times = np.linspace(6.0 / omega, 9.0 / omega, 4)
    run = run_jet_euler(
        JetModel(ohnesorge=oh),
        initial=_perturbed_thread(k, 1e-5, 60),
        t_end=float(times[-1]),
        snapshot_times=times,
    )
    assert [s for s, _ in run.snapshots] == pytest.approx(times, rel=1e-14)
    amp = [math.sqrt(b[0].a[0]) - math.sqrt(b[0].a[-1]) for _, b in run.snapshots]
    rate = np.polyfit(times, np.log(np.abs(amp)), 1)[0]
    assert rate == pytest.approx(omega, rel=0.02)


def test_viscous_inertial_pinch_off_thins_at_0_0304_sigma_over_eta() -> None:
    # Eggers (1993): h_min = 0.0304 (sigma / eta) tau; dimensionless 0.0304 tau / Oh. The
    # fixed grid must resolve the neck over the whole thread: 393 cells (dz = 0.0133)
    # give 0.0338 (+11 %); 262 cells 0.0359, 524 cells 0.0326 (first-order approach).
    oh = 0.5
    run = run_jet_euler(
        JetModel(ohnesorge=oh),
        EulerNumerics(h_break=3e-4, film=1e-5),
        initial=_perturbed_thread(0.6, 0.05, 393),
        t_end=1e3,
        on_pinch="stop",
    )
    assert run.stop_reason == "pinch-off"
    tau = run.events[0].t - run.t
    h = run.neck_radius
    sel = (h > 1e-3) & (h < 1e-2)
    assert np.count_nonzero(sel) > 10
    slope = np.polyfit(tau[sel], h[sel], 1)[0]
    assert slope * oh == pytest.approx(0.0304, rel=0.15)


def test_oldroyd_b_thread_thins_exponentially_at_one_over_three_lambda() -> None:
    # 131 cells (dz = 0.04) give 0.952 / (3 De), 66 cells 0.913, 196 cells 0.965
    de = 10.0
    run = run_jet_euler(
        JetModel(ohnesorge=0.3, polymer_ohnesorge=3.0, deborah=de),
        EulerNumerics(h_break=1e-2),
        initial=_perturbed_thread(0.6, 0.05, 131),
        t_end=400.0,
        on_pinch="stop",
    )
    h, t = run.neck_radius, run.t
    sel = (h > 0.01) & (h < 0.1)
    assert np.count_nonzero(sel) > 10
    rate = -np.polyfit(t[sel], np.log(h[sel]), 1)[0]
    assert rate == pytest.approx(1.0 / (3.0 * de), rel=0.05)
    # closed ends: the volume is conserved to round-off
    assert np.ptp(run.volume) < 1e-12 * run.volume[0]


def test_newtonian_thread_does_not_thin_exponentially_like_a_polymer() -> None:
    run = run_jet_euler(
        JetModel(ohnesorge=0.3),
        EulerNumerics(h_break=1e-2),
        initial=_perturbed_thread(0.6, 0.05, 131),
        t_end=400.0,
        on_pinch="stop",
    )
    assert run.stop_reason == "pinch-off"
    assert run.t[-1] < 60.0


def test_mass_is_conserved_through_injection_suction_and_breakup(push_suck) -> None:
    pulse = push_suck
    run = run_jet_euler(
        JetModel(ohnesorge=0.05, polymer_ohnesorge=0.1, deborah=1.0),
        EulerNumerics(h_break=0.05, length=20.0),
        t_end=10.0,
        inflow=pulse,
        snapshot_times=[1.5, 5.0],
        on_pinch="split",
    )
    assert run.events  # the run went through at least one breakup
    vol0 = run.volume[0]
    err = np.abs(run.volume - vol0 - run.injected) / (vol0 + run.injected.max())
    assert err.max() < 1e-6
    # while the nozzle pushes, exactly the displaced volume goes in
    k = int(np.searchsorted(run.t, 1.5))
    assert run.t[k] == 1.5
    assert run.injected[k] == pytest.approx(pulse.displacement(1.5), rel=1e-9)
    assert run.injected.max() > 1e3 * vol0  # liquid really went through (vol0: film only)
    # the suction took some liquid back
    assert run.injected[-1] < run.injected[k]
    for _, bodies in run.snapshots:
        assert all(isinstance(b, Body) for b in bodies)


class _Push:
    """u = U sin(pi t / T) for t < T, then 0 (the nozzle pushes a column out and stops)."""

    def __init__(self, u: float, period: float) -> None:
        self.u, self.p = u, period

    def velocity(self, t: float) -> float:
        return self.u * math.sin(math.pi * t / self.p) if t < self.p else 0.0

    def displacement(self, t: float) -> float:
        return self.u * self.p / math.pi * (1.0 - math.cos(math.pi * min(t, self.p) / self.p))


# Oh 0.1 (4.0, 1.5) is left out: there the Lagrangian column's first pinch is chaotic in
# the last bit of its banded solve, 2.885 (OpenBLAS SkylakeX), 3.603 (SandyBridge) and
# 3.733 (Haswell, a front pinch) while the Eulerian one is 2.938 on all three. At Oh 0.05
# and 0.2 the Lagrangian times spread 1.4 % and 0.5 % across the same kernels (2.814-2.855
# and 4.482-4.505; Nehalem as SandyBridge), well inside the 10 % compared (issue 43).
@pytest.mark.parametrize(("oh", "u", "period"), [(0.05, 4.0, 1.5), (0.2, 3.0, 2.0)])
def test_drop_on_demand_breakup_agrees_with_the_lagrangian_solver(
    oh: float, u: float, period: float
) -> None:
    # A push of 2 u period / pi nozzle volumes from an empty nozzle, then nothing: the
    # column pinches near the exit. First breakup (t, tip), Lagrangian vs Eulerian at
    # dz 0.04 and 0.02:
    #   Oh 0.05: 2.855, 8.09 | 2.656, 7.65 | 2.632, 7.56
    #   Oh 0.1:  2.885, 8.25 | 2.939, 8.46 | 2.917, 8.38
    #   Oh 0.2:  4.505, 8.60 | 4.339, 8.44 | 4.325, 8.39
    # The Eulerian values converge with dz to within 2-8 % (time) and 1-7 % (length) of
    # the Lagrangian ones; the rest is the models' different start (flat meniscus vs a
    # 0.3 cap) and rim (a ghost cell of radius 1 vs a pinned volume cell; the Lagrangian
    # neck sits at the rim, the Eulerian one 0.7-1 radius out). Hence 10 % and 8 %.
    model = JetModel(ohnesorge=oh)
    lag = run_jet(
        [],
        model,
        Numerics(h_break=0.02, resolution=0.8, rtol=1e-3),
        t_end=40.0,
        inflow=_Push(u, period),
        on_pinch="stop",
    )
    eul = run_jet_euler(
        model,
        EulerNumerics(h_break=0.02, length=30.0),
        t_end=40.0,
        inflow=_Push(u, period),
        on_pinch="stop",
    )
    assert lag.stop_reason == eul.stop_reason == "pinch-off"
    el, ee = lag.events[0], eul.events[0]
    assert ee.t == pytest.approx(el.t, rel=0.10)
    assert ee.z_tip - ee.z_tail == pytest.approx(el.z_tip - el.z_tail, rel=0.08)
    assert ee.mode == el.mode == "exit"
    assert ee.attached


def test_numerics_and_inputs_reject_bad_values() -> None:
    with pytest.raises(ValueError, match=r"film radius .* must be below h_break"):
        EulerNumerics(film=0.05, h_break=0.02)
    with pytest.raises(ValueError, match="cfl"):
        EulerNumerics(cfl=1.5)
    with pytest.raises(ValueError, match="dz must be"):
        EulerNumerics(dz=0.0)
    with pytest.raises(ValueError, match="fewer than 8 cells"):
        EulerNumerics(dz=1.0, length=5.0)
    with pytest.raises(ValueError, match="limiter"):
        EulerNumerics(limiter="superbee")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="squared radius"):
        EulerInitial(length=1.0, a=np.r_[np.ones(9), -1.0])
    with pytest.raises(ValueError, match="one value per face"):
        EulerInitial(length=1.0, a=np.ones(10), u=np.zeros(10))
    thread = _perturbed_thread(0.7, 0.01, 20)
    model = JetModel(ohnesorge=0.1)
    with pytest.raises(ValueError, match="needs a nozzle"):
        run_jet_euler(model, initial=thread, t_end=1.0, inflow=_Push(1.0, 1.0))
    with pytest.raises(ValueError, match="t_end"):
        run_jet_euler(model, initial=thread, t_end=0.0)
    with pytest.raises(ValueError, match="on_pinch"):
        run_jet_euler(model, initial=thread, t_end=1.0, on_pinch="cut")  # type: ignore[arg-type]
