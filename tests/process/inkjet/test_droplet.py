"""Drop-on-demand pipeline: waveform -> acoustics -> jet; volume balance; images round trip."""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

from microfab.measure.imaging import analyze
from microfab.measure.shadowgraph import Camera, render_sequence
from microfab.process.inkjet.droplet import Scales, simulate_droplet
from microfab.process.inkjet.fluids import naalg


@pytest.fixture(scope="module")
def early_jet():
    # 80 µs: the jet is out and still whole (fast enough for the suite)
    # the Lagrangian model: the one fed the part of the acoustic flow that leaves the nozzle
    return simulate_droplet(
        naalg(0.15, model="lagrangian"), duration_s=80e-6, frame_interval_s=5e-6,
        model="lagrangian",
    )  # fmt: skip


def test_liquid_out_of_the_nozzle_matches_the_acoustic_displacement(early_jet) -> None:
    run = early_jet.run
    vol = run.volume - run.volume[0]
    assert np.max(np.abs(vol - run.injected)) < 1e-6 * max(run.injected.max(), 1.0)
    # the jet holds the most the acoustics ever pushed out: when the flow reverses, the
    # meniscus in the bore takes the retraction (jet_inflow)
    sc = early_jet.scales
    t = np.linspace(0.0, run.t[-1] * sc.time_s, 2000)
    pushed = float(np.max(early_jet.flow.displacement(t))) / sc.length_m
    assert run.volume[-1] == pytest.approx(pushed, rel=0.02)


def test_head_moves_at_a_few_metres_per_second(early_jet) -> None:
    assert early_jet.outcome == "no breakup within the simulated time"
    assert 2.0 < early_jet.head_speed_m_s < 8.0


def test_analyser_recovers_the_simulated_head_speed(early_jet) -> None:
    sil = [s for s in early_jet.silhouettes if s.bodies and s.time_s >= 55e-6]
    cam = Camera(pixel_size_m=2e-6, width_px=120, height_px=400, noise_std=0.02, blur_px=1.0)
    frames = render_sequence(sil, cam, seed=1)
    res = analyze(
        frames,
        pixel_size_m=cam.pixel_size_m,
        frame_interval_s=5e-6,
        nozzle_row=cam.nozzle_row,
        t0_s=sil[0].time_s,
    )
    tips = [float(max(b[0][-1] for b in s.bodies)) for s in sil]
    times = [s.time_s for s in sil]
    truth = np.polyfit(times, tips, 1)[0]
    assert res.head_speed_m_s == pytest.approx(truth, rel=0.05)
    assert res.breakup_frame is None


def test_the_frame_spacing_does_not_move_the_eulerian_breakup() -> None:
    # the Eulerian steps land on the frames; before the fix the 0.15 % jet at 50 V broke at
    # 88.25 µs 90 µm inside the bore with 2 µs frames and at 49.28 µs 18 µm out with 5 µs
    # frames (the meniscus cap handed to the grid flung forward). Measured after it over 1,
    # 2, 2.5, 3, 4, 5, 7 and 10 µs frames and none: 88.2164-88.2201 µs, z -89.94 to -90.00
    # µm (with the ink law before the calibration core's; the test compares the runs with
    # each other, whatever the law). Tolerances: one solver step (49.7 ns, ten times that
    # spread) and half a grid cell (1.2 µm, twenty times it)
    runs = [
        simulate_droplet(
            naalg(0.15), duration_s=92e-6, after_breakup_s=1e-6, frame_interval_s=frames
        )
        for frames in (2e-6, 5e-6, 1.0)  # 1 s: no frame after the first
    ]
    for res in runs:
        assert res.model == "eulerian"
        assert res.breakup_time_s is not None and res.breakup_z_m is not None
        assert res.breakup_time_s == pytest.approx(runs[0].breakup_time_s, abs=50e-9)
        assert res.breakup_z_m == pytest.approx(runs[0].breakup_z_m, abs=1.2e-6)
        assert res.breakup_mode == runs[0].breakup_mode


def test_fluid_without_relaxation_time_keeps_its_full_viscosity() -> None:
    fluid = naalg(1.0, relaxation_time_s=0.0)
    sc = Scales.of(fluid, 60e-6)
    visc = (fluid.density_kg_m3 * fluid.surface_tension_n_m * 60e-6) ** 0.5
    model = sc.model(fluid)
    assert model.ohnesorge == pytest.approx(fluid.zero_shear_viscosity_pa_s / visc)
    assert model.polymer_ohnesorge == 0.0


def test_scales_and_model_numbers() -> None:
    fluid = naalg(1.0)
    sc = Scales.of(fluid, 60e-6)
    assert sc.time_s == pytest.approx(
        math.sqrt(fluid.density_kg_m3 * (60e-6) ** 3 / fluid.surface_tension_n_m)
    )
    m = sc.model(fluid)
    oh = fluid.solvent_viscosity_pa_s / math.sqrt(
        fluid.density_kg_m3 * fluid.surface_tension_n_m * 60e-6
    )
    assert m.ohnesorge == pytest.approx(oh)
    assert m.deborah == pytest.approx(fluid.relaxation_time_s / sc.time_s)


def test_bad_setup_is_refused() -> None:
    with pytest.raises(ValueError, match="duration_s"):
        simulate_droplet(naalg(0.15), duration_s=-1.0)
    with pytest.raises(ValueError, match="breakup radius"):
        simulate_droplet(naalg(0.15), breakup_radius_m=1e-3)
    with pytest.raises(ValueError, match="outside the table"):
        naalg(-0.1)
    # the back pressure: below the bore's Laplace pressure 2 sigma / R (2.39 kPa for the
    # 0.15 % ink in the 60 µm bore), and only where the meniscus feels it
    with pytest.raises(ValueError, match="Laplace pressure"):
        simulate_droplet(naalg(0.15), model="eulerian", back_pressure_pa=2400.0)
    with pytest.raises(ValueError, match="Laplace pressure"):
        simulate_droplet(naalg(0.15), model="eulerian", back_pressure_pa=math.nan)
    with pytest.raises(ValueError, match="needs the Eulerian model"):
        simulate_droplet(naalg(0.15, model="lagrangian"), model="lagrangian", back_pressure_pa=10.0)
    with pytest.raises(ValueError, match="needs the Eulerian model"):
        simulate_droplet(naalg(0.15), model="eulerian", meniscus="pinned", back_pressure_pa=-10.0)


def test_a_drop_pinched_at_the_exit_stays_in_the_silhouettes() -> None:
    """After an exit pinch the nozzle's meniscus is dormant, but the drop flies on: every
    silhouette after the breakup shows it, farther from the nozzle each time."""
    from microfab.process.inkjet.droplet import simulate_droplet
    from microfab.process.inkjet.fluids import naalg
    from microfab.trajectory.waveform import seed003_waveform

    res = simulate_droplet(naalg(0.15), seed003_waveform(50.0), duration_s=200e-6)
    assert res.breakup_mode == "exit"
    after = [s for s in res.silhouettes if s.time_s > res.breakup_time_s]
    assert len(after) >= 3
    reach = [max(float(b[0][-1]) for b in s.bodies) for s in after]  # all non-empty
    assert all(b > a for a, b in itertools.pairwise(reach))


def test_a_shorter_run_is_the_prefix_of_a_longer_one() -> None:
    # issue 19: the orifice flow's FFT rounding used to depend on the record length, and a
    # 300 µs and a 400 µs run of the same point parted after 51 µs
    short = simulate_droplet(naalg(1.5), duration_s=60e-6, after_breakup_s=20e-6)
    long = simulate_droplet(naalg(1.5), duration_s=90e-6, after_breakup_s=20e-6)
    n = short.run.t.size - 1  # the last step of the short run is cut at its end time
    np.testing.assert_allclose(short.run.t[:n], long.run.t[:n], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(short.run.tip_z[:n], long.run.tip_z[:n], rtol=1e-12, atol=1e-12)
    # the flow is the one the coupled acoustics produced over the run
    assert short.flow.t_s[-1] == pytest.approx(60e-6, abs=1e-7)
    np.testing.assert_array_equal(
        short.flow.velocity_m_s, long.flow.velocity_m_s[: short.flow.velocity_m_s.size]
    )


def _inside_the_bore(c: float, reason: str) -> Any:
    """An Eulerian case whose thread breaks inside the bore, out of the camera's sight."""
    mark = pytest.mark.xfail(raises=AssertionError, strict=True, reason=reason)
    return pytest.param("eulerian", c, marks=mark)


# The Lagrangian 1 % jet is left out: it is chaotic near its pinch, in the last bit of
# its banded solve. With OpenBLAS's Haswell and SandyBridge kernels it exit-pinches at
# 122 µs, which the camera sees; with SkylakeX it hangs on a thread thinner than the 2 µm
# pixel resolves for 53 µs before it breaks at 338 µs, and the camera sees the gap at
# 285 µs (issue 43: a check that holds on some kernels only is no check).
@pytest.mark.parametrize(
    ("model", "c"),
    [
        ("lagrangian", 0.15),
        _inside_the_bore(
            0.15,
            "by design: the 0.15 % thread breaks at the retracted meniscus, 61 µm inside the "
            "bore, where a camera outside the nozzle cannot see it",
        ),
        _inside_the_bore(
            1.0,
            "with the core's ink law (issue 46) the 1 % thread breaks at 238.5 µs 43.5 µm "
            "inside the bore; the camera outside the nozzle sees the gap at 250 µs",
        ),
    ],
)
def test_the_camera_sees_the_breakup_the_solver_reports(model: str, c: float) -> None:
    # issue 19: frames of either model through the image analyser give the solver's mode,
    # and its time to within one frame
    dt = 5e-6
    res = simulate_droplet(naalg(c, model=model), duration_s=400e-6, after_breakup_s=20e-6,
                           frame_interval_s=dt, model=model)  # fmt: skip
    assert res.breakup_time_s is not None
    sil = [s for s in res.silhouettes if s.bodies]
    reach = max(float(b[0][-1]) for s in sil for b in s.bodies)
    cam = Camera(pixel_size_m=2e-6, width_px=120, height_px=int(reach / 2e-6) + 40)
    frames = render_sequence(sil, cam, seed=0)
    seen = analyze(frames, pixel_size_m=2e-6, frame_interval_s=dt,
                   nozzle_row=cam.nozzle_row, t0_s=sil[0].time_s)  # fmt: skip
    assert seen.breakup_time_s is not None
    assert abs(seen.breakup_time_s - res.breakup_time_s) <= dt + 1e-9
    assert seen.breakup_mode == res.breakup_mode


def test_the_default_model_keeps_mass_through_the_meniscus_in_the_bore() -> None:
    # the Eulerian default: the meniscus retracts (the fill, then after the jet), bulges
    # are handed to the grid and taken back; what is on the grid is what crossed the
    # meniscus, to round-off, and the coupled flow is the acoustics' own record
    res = simulate_droplet(naalg(0.15), duration_s=120e-6, after_breakup_s=20e-6)
    assert res.model == "eulerian" and res.meniscus == "retracting"
    run = res.run
    balance = run.volume - run.volume[0] - run.injected
    assert np.max(np.abs(balance)) < 1e-10
    assert res.meniscus_depth_m > 60e-6  # it went well into the bore
    assert res.flow.dt_s == pytest.approx(50e-9)
    assert 4.0 < res.flow.peak_velocity_m_s < 8.0
