"""The meniscus in the bore (``jet_euler_meniscus``): its capillary oscillation against the
analytic frequency and decay, the spherical-cap law, the grid's bulge against that law, and
mass through the hand-over and back."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from microfab.process.inkjet.jet import JetModel
from microfab.process.inkjet.jet_euler import EulerNumerics, Upstream, run_jet_euler
from microfab.process.inkjet.jet_euler_meniscus import cap_depth, cap_pressure, static_meniscus


def _column(oh: float, length: float, dt: float = 1e-3) -> Upstream:
    """A liquid column of ``length`` radii in the bore: ``l du/dt = -p_m - 8 Oh l u``.

    Poiseuille friction ``8 Oh u`` per unit length (dimensionless), held exactly over a
    step (zero-order hold of ``p_m``).
    """
    k = 8.0 * oh
    phi = math.exp(-k * dt)
    gain = -(1.0 - phi) / (k * length) if k > 0 else -dt / length
    return Upstream(phi=[[phi]], g_drive=[0.0], g_pressure=[gain], c_row=[1.0], slopes=[0.0], dt=dt)


def _column_displacement(run) -> np.ndarray:
    """Mean displacement of the column: the meniscus plus what stands on the grid."""
    return run.meniscus_z + (run.volume - run.volume[0])


def _crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times where ``x`` changes sign upwards (linear interpolation)."""
    i = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def test_cap_law_is_the_lumped_compliance_for_small_depths_and_a_hemisphere_at_its_end() -> None:
    # mean depth delta = d (3 + d^2) / 6 and p = 4 d / (1 + d^2): p -> 8 delta for small
    # delta, i.e. C_m = pi R^4 / (8 sigma) of the acoustic model's lumped meniscus
    for delta in (1e-4, -1e-4):
        assert cap_pressure(delta) == pytest.approx(8.0 * delta, rel=1e-6)
    assert cap_depth(2.0 / 3.0) == pytest.approx(1.0, rel=1e-12)
    assert cap_pressure(-2.0 / 3.0) == pytest.approx(-2.0, rel=1e-12)
    assert cap_pressure(-5.0) == -2.0  # the contact line slides at the hemisphere
    d = cap_depth(0.3)
    assert d * (3.0 + d * d) / 6.0 == pytest.approx(0.3, rel=1e-12)


@pytest.mark.parametrize("oh", [0.0, 0.05])
def test_small_meniscus_oscillation_has_the_capillary_frequency_and_viscous_decay(
    oh: float,
) -> None:
    # column of length l on the meniscus spring p = 8 delta: l delta'' = -8 delta - 8 Oh l
    # delta', so omega = sqrt(8 / l - 16 Oh^2) and the amplitude decays as exp(-4 Oh t)
    # (SI: omega^2 = 8 sigma / (rho l R^2), the capillary oscillation of a meniscus in a tube)
    length, amp = 2.0, 0.02
    omega = math.sqrt(8.0 / length - 16.0 * oh * oh)
    t_end = 3.2 * 2.0 * math.pi / omega
    run = run_jet_euler(
        JetModel(ohnesorge=max(oh, 1e-3)),
        EulerNumerics(length=4.0),
        upstream=_column(oh, length),
        meniscus="retracting",
        meniscus_z0=-amp,
        t_end=t_end,
    )
    assert run.stop_reason == "end time reached"
    delta = _column_displacement(run)
    up = _crossings(run.t, delta)
    assert up.size >= 3
    assert np.diff(up).mean() == pytest.approx(2.0 * math.pi / omega, rel=0.01)
    # amplitude of the troughs against exp(-4 Oh t)
    troughs = [np.min(delta[(run.t >= a) & (run.t < b)]) for a, b in itertools.pairwise(up)]
    mids = [0.5 * (a + b) for a, b in itertools.pairwise(up)]
    rate = -np.polyfit(mids, np.log(-np.array(troughs)), 1)[0]
    assert rate == pytest.approx(4.0 * oh, abs=0.01)


def test_large_oscillation_through_the_grid_follows_the_cap_law() -> None:
    # amplitude 0.3: the bulge outgrows the lumped cap and is carried by the grid's free
    # surface (hand-over at 5 cells), then drawn back (take-back); the column follows the
    # nonlinear cap-law oscillator within 0.025 (measured 0.018: the grid's bulge is a
    # little stiffer than the spherical cap while it is on the grid)
    oh, length, amp = 0.05, 2.0, 0.3
    t_end = 2.5 * math.pi
    run = run_jet_euler(
        JetModel(ohnesorge=oh),
        EulerNumerics(length=6.0),
        upstream=_column(oh, length),
        meniscus="retracting",
        meniscus_z0=-amp,
        t_end=t_end,
    )
    delta = _column_displacement(run)
    assert delta.max() > 0.15  # the bulge went on the grid (hand-over height 0.1)
    assert np.any(run.meniscus_z == 0.0)

    def rhs(_t: float, y: list[float]) -> list[float]:
        return [y[1], (-cap_pressure(y[0]) - 8.0 * oh * length * y[1]) / length]

    sol = solve_ivp(rhs, (0.0, run.t[-1]), [-amp, 0.0], t_eval=run.t, rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(delta - sol.y[0])) < 0.025
    # mass: what is on the grid plus the meniscus is what the column moved, to round-off
    balance = run.volume - run.volume[0] - run.injected
    assert np.max(np.abs(balance)) < 1e-10


def test_a_retracting_meniscus_pulls_the_jet_root_into_the_bore() -> None:
    # a jet pushed out and then sucked back: the meniscus goes below the rim, the body on
    # the nozzle starts there, and positions are in the lab frame
    u_out, t_push = 3.0, 1.0
    slopes = np.zeros(4000)
    dt = 1e-3
    k_push = int(t_push / dt)
    slopes[0] = u_out / dt  # the drive steps the velocity: +3 at t = 0, -6 at t_push
    slopes[k_push] = -2.0 * u_out / dt
    up = Upstream(phi=[[1.0]], g_drive=[dt], g_pressure=[0.0], c_row=[1.0], slopes=slopes, dt=dt)
    run = run_jet_euler(
        JetModel(ohnesorge=0.1),
        EulerNumerics(length=8.0),
        upstream=up,
        meniscus="retracting",
        t_end=1.3,
        snapshot_times=[1.1],
    )
    assert run.meniscus_z is not None
    z_m = float(np.interp(1.1, run.t, run.meniscus_z))
    assert z_m == pytest.approx(-0.2, abs=0.01)  # 0.1 capillary times at -3 from the rim
    (root,) = run.snapshots[-1][1]
    assert root.left == "nozzle"
    assert root.z[0] == pytest.approx(z_m, abs=1e-3)
    # the thread drawn into the bore pinches there, near the meniscus: an exit pinch
    first = run.events[0]
    assert first.z < 0.0
    assert first.mode == "exit"
    balance = run.volume - run.volume[0] - run.injected
    assert np.max(np.abs(balance)) < 1e-10


class _ConstantPush:
    """The column pushed out of the bore at a constant speed ``u`` (dimensionless)."""

    def __init__(self, u: float) -> None:
        self.u = u

    def velocity(self, t: float) -> float:
        return self.u

    def displacement(self, t: float) -> float:
        return self.u * t


@pytest.mark.parametrize("u_push", [1.0, 5.46])  # 5.46: the 0.15 % NaAlg jet's column at 50 V
def test_a_growing_cap_is_handed_to_the_grid_at_its_height_whatever_the_steps(
    u_push: float,
) -> None:
    # the cap is handed over when it is exactly cap_cells high, whether snapshots cut the
    # steps or not, and the grid carries it at the speed of a growing cap: its apex moves
    # at 2 u / (1 + d^2) < 2 u. Before the fix the hand-over's height depended on where the
    # step sequence fell, and the sliver it put into one more cell was flung forward at
    # 11-137 times the column speed (measured with these runs; 1.12-1.35 u after it)
    nu = EulerNumerics(length=4.0)
    cap = nu.cap_cells * nu.dz
    t_cap = cap * (3.0 + cap * cap) / 6.0 / u_push  # mean height over the push speed
    for snaps in ((), np.arange(0.0, 1.0, 0.013), np.arange(0.0, 1.0, 0.0517)):
        run = run_jet_euler(
            JetModel(ohnesorge=0.05),
            nu,
            t_end=0.25,
            inflow=_ConstantPush(u_push),
            meniscus="retracting",
            snapshot_times=snaps,
        )
        assert run.meniscus_z is not None
        (k,) = np.flatnonzero((run.meniscus_z[:-1] > 0.0) & (run.meniscus_z[1:] == 0.0))
        # the step lands on the crossing, found exactly in the inflow table (round-off)
        assert run.t[k + 1] == pytest.approx(t_cap, rel=1e-9)
        assert float(np.max(run.tip_v)) < 2.0 * u_push
        assert not run.events
        balance = run.volume - run.volume[0] - run.injected
        assert np.max(np.abs(balance)) < 1e-10


def test_the_static_meniscus_balances_the_back_pressure_with_its_laplace_pressure() -> None:
    # the cap law inverted: a convex cap on the rim for p_b > 0, a concave one in the bore
    # for p_b < 0 (closed form; both are root-finding-free, so to round-off)
    assert static_meniscus(0.0) == 0.0
    for p in (-1.9, -0.8, -1e-3, 1e-3, 0.5, 1.9):
        z = static_meniscus(p)
        assert math.copysign(1.0, z) == math.copysign(1.0, p)
        assert cap_pressure(z) == pytest.approx(p, rel=1e-12)
    assert abs(static_meniscus(1.9999)) < 2.0 / 3.0  # short of the hemisphere


@pytest.mark.parametrize("p_b", [-0.8, 0.5])
def test_a_back_pressure_holds_the_meniscus_where_the_laplace_balance_puts_it(p_b: float) -> None:
    # a column in the bore under a static back pressure p_b (sigma / R): started flat at the
    # rim it swings about, and settles at, the cap whose Laplace pressure is p_b; started
    # there it stays (-0.8: concave, 0.106 radii deep; 0.5: convex, a lumped cap 0.064 high;
    # a cap taller than the hand-over is carried by the grid, a little stiffer than the cap
    # law: 1.5 settles at 0.222 against its 0.241)
    oh, length = 0.3, 2.0  # damped at 4 Oh = 1.2 per capillary time: 1e-5 left at t = 10
    z_eq = static_meniscus(p_b)
    up = _column(oh, length)
    kw = {"upstream": up, "meniscus": "retracting", "back_pressure": p_b, "t_end": 10.0}
    flat = run_jet_euler(JetModel(ohnesorge=oh), EulerNumerics(length=4.0), **kw)
    assert flat.stop_reason == "end time reached"
    delta = _column_displacement(flat)
    assert np.min(delta) < z_eq < np.max(delta)  # it swung about the balance
    # settled: measured 7e-7 (-0.8) and 2e-7 (0.5) radii off after 10 capillary times
    assert delta[-1] == pytest.approx(z_eq, abs=1e-5)
    held = run_jet_euler(JetModel(ohnesorge=oh), EulerNumerics(length=4.0), meniscus_z0=z_eq, **kw)
    # at rest: the cap law and its inverse agree to round-off (measured drift 0 and 1e-15)
    assert np.max(np.abs(_column_displacement(held) - z_eq)) < 1e-12
    assert held.events == ()


def test_bad_meniscus_and_upstream_inputs_are_refused() -> None:
    model = JetModel(ohnesorge=0.1)
    up = _column(0.1, 2.0)
    with pytest.raises(ValueError, match="meniscus must be one of"):
        run_jet_euler(model, t_end=0.1, meniscus="sliding")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="below the hemisphere"):
        run_jet_euler(model, t_end=0.1, meniscus="retracting", meniscus_z0=0.7)
    with pytest.raises(ValueError, match="needs meniscus='retracting'"):
        run_jet_euler(model, t_end=0.1, meniscus_z0=-0.1)
    with pytest.raises(ValueError, match="needs meniscus='retracting'"):
        run_jet_euler(model, t_end=0.1, meniscus_z0=0.05)
    with pytest.raises(ValueError, match=r"back_pressure must lie in \(-2, 2\)"):
        run_jet_euler(model, t_end=0.1, upstream=up, meniscus="retracting", back_pressure=2.0)
    with pytest.raises(ValueError, match="back pressure needs an upstream"):
        run_jet_euler(model, t_end=0.1, meniscus="retracting", back_pressure=0.5)
    with pytest.raises(ValueError, match="back pressure needs an upstream"):
        run_jet_euler(model, t_end=0.1, upstream=up, back_pressure=0.5)
    with pytest.raises(ValueError, match="Laplace pressure"):
        static_meniscus(-2.0)
    with pytest.raises(ValueError, match="either an inflow or an upstream"):
        run_jet_euler(model, t_end=0.1, upstream=up, inflow=_Still())
    with pytest.raises(ValueError, match="bore_length must be > 0"):
        run_jet_euler(model, t_end=0.1, bore_length=0.0)
    with pytest.raises(ValueError, match="square matrix"):
        Upstream(phi=[1.0, 2.0], g_drive=[0.0], g_pressure=[0.0], c_row=[1.0], slopes=[], dt=1.0)
    with pytest.raises(ValueError, match="g_pressure needs shape"):
        Upstream(phi=[[1.0]], g_drive=[0.0], g_pressure=[0.0, 1.0], c_row=[1.0], slopes=[],
                 dt=1.0)  # fmt: skip
    with pytest.raises(ValueError, match="NaN or inf"):
        Upstream(phi=[[np.nan]], g_drive=[0.0], g_pressure=[0.0], c_row=[1.0], slopes=[], dt=1.0)
    with pytest.raises(ValueError, match="dt must be"):
        Upstream(phi=[[1.0]], g_drive=[0.0], g_pressure=[0.0], c_row=[1.0], slopes=[], dt=0.0)
    with pytest.raises(ValueError, match="cap_cells"):
        EulerNumerics(cap_cells=0.5)


def test_a_meniscus_deeper_than_the_bore_stops_the_run_with_its_reason() -> None:
    run = run_jet_euler(
        JetModel(ohnesorge=0.1),
        upstream=_column(0.0, 2.0),
        meniscus="retracting",
        meniscus_z0=-0.3,
        bore_length=0.2,
        t_end=1.0,
    )
    assert run.stop_reason.startswith("the meniscus retracted deeper than the bore (0.2 radii)")


class _Still:
    def velocity(self, t: float) -> float:
        return 0.0

    def displacement(self, t: float) -> float:
        return 0.0
