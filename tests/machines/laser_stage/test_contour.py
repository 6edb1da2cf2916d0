"""Seed 004 contour runs on the twin: Fig. 7's correction, feedforward, DOB, mass error."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation
from microfab.experiments.seed004_laser import paper
from microfab.machines.laser_stage.contour import dob_estimate, run_contour
from microfab.machines.laser_stage.machine import ContourJob, ControlSettings, TwinSettings
from microfab.machines.laser_stage.machine import controller as make_controller
from microfab.machines.laser_stage.machine import twin as make_stage
from microfab.trajectory.contour_laps import ContourMotion, contour_path


def _fig7(law: str, speed: float, radius: float = paper.FIG7_SIZE_M, noise: bool = False):
    return run_contour(
        ContourJob(
            drawing=f"circle:radius={radius!r}",
            motion=ContourMotion(speed_m_s=speed, laps=3),
            control=ControlSettings(law=law),
            twin=TwinSettings(noise=noise),
        )
    )


@pytest.mark.parametrize("radius", [100e-6, 50e-6])
def test_fig7_correction_halves_the_contour_error_after_lap_one(radius):
    # seed 004 §IV.D, Fig. 7: 100 µm circle at 10 mm/s (simulation, noise off); radius
    # read as the radius, 50 µm also run (issue 15)
    base = _fig7("preview-dob", paper.FIG7_SPEED_M_S, radius).contour.after_first_lap_max()
    comp = _fig7("contour", paper.FIG7_SPEED_M_S, radius).contour.after_first_lap_max()
    assert base >= paper.PROJECT_CHOICES["fig7_gain_min"] * comp, (base, comp)


def _low_speed_change(
    nonlinear: bool, friction_ff: bool = False, speed: float | None = None
) -> tuple[float, float]:
    v = paper.PROJECT_CHOICES["fig7_low_speed_m_s"] if speed is None else speed
    out = []
    for law in ("preview-dob", "contour"):
        run = run_contour(
            ContourJob(
                drawing="circle:radius=100e-6",
                motion=ContourMotion(speed_m_s=v, laps=3),
                control=ControlSettings(law=law, friction_ff=friction_ff),
                twin=TwinSettings(noise=False, nonlinear=nonlinear),
            )
        )
        out.append(run.contour.after_first_lap_max())
    return out[0], out[1]


def test_fig7_correction_barely_matters_at_low_speed_on_the_linear_twin():
    # seed 004 §IV.D: "almost no significant contribution ... at low speeds" (a simulation)
    base, comp = _low_speed_change(nonlinear=False)
    assert abs(base - comp) < paper.PROJECT_CHOICES["fig7_low_speed_change_m"], (base, comp)


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="with preview + DOB alone (the seed's eqs. 3-4) the calibrated twin's LuGre "
    "friction leaves quadrant glitches that the correction's normal stiffness removes: "
    "745 -> 251 nm after lap 1 at 1 mm/s (a 494 nm change, not < 50 nm; 531 -> 118 nm "
    "before issue 45's joint calibration). It is the friction: with the twin's friction "
    "off the change is 2.4 nm (5.7 -> 8.0 nm, experiments.seed004_laser.fig7), and with "
    "the friction feedforward on both laws 279 nm (next test)",
)
def test_fig7_correction_barely_matters_at_low_speed_on_the_full_twin():
    base, comp = _low_speed_change(nonlinear=True)
    assert abs(base - comp) < paper.PROJECT_CHOICES["fig7_low_speed_change_m"], (base, comp)


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="issue 45's joint calibration (a Stribeck velocity of 0.11 mm/s and 14 nm "
    "pre-sliding, fitted so that Fig. 3's glitches are short) leaves a friction the "
    "feedforward on the reference does not own: with it on both laws the 1 mm/s contour "
    "error goes 357 -> 78 nm with the correction (a 279 nm change, not < 50 nm; before "
    "the calibration 56.9 -> 15.0 nm); at 10 mm/s 183 -> 70 nm",
)
def test_fig7_on_the_full_twin_once_a_friction_feedforward_owns_the_friction():
    """Seed 004 §IV.D in direction on the calibrated twin: the friction feedforward
    (ControlSettings.friction_ff, the twin's own LuGre law) on both laws; the correction
    then changes the 1 mm/s contour error by < 50 nm and halves it at 10 mm/s."""
    base, comp = _low_speed_change(nonlinear=True, friction_ff=True)
    assert abs(base - comp) < paper.PROJECT_CHOICES["fig7_low_speed_change_m"], (base, comp)
    # measured 56.9 -> 15.0 nm; without the feedforward 530.9 nm
    assert base < 0.2 * _low_speed_change(nonlinear=True)[0]
    fast_base, fast_comp = _low_speed_change(nonlinear=True, friction_ff=True,
                                             speed=paper.FIG7_SPEED_M_S)  # fmt: skip
    assert fast_base >= paper.PROJECT_CHOICES["fig7_gain_min"] * fast_comp  # 220 -> 77 nm


def _feedforward_gain(nonlinear: bool) -> float:
    job = ContourJob(
        drawing="circle:radius=100e-6",
        motion=ContourMotion(speed_m_s=10e-3, laps=2),
        control=ControlSettings(law="preview-dob"),
        twin=TwinSettings(noise=False, nonlinear=nonlinear),
    )
    with_ff = run_contour(job).axis.peak_m
    without = run_contour(job.with_(control=ControlSettings(law="preview-dob", k_a=0.0))).axis
    return min(without.peak_m) / max(with_ff)


def test_acceleration_feedforward_cuts_the_error_twentyfold_on_the_linear_twin():
    assert _feedforward_gain(nonlinear=False) >= 20.0  # measured 36x


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="on the calibrated twin the friction left with K_a = 1 caps the gain at 15.5x "
    "on the 100 µm circle at 10 mm/s (9.3x before issue 45's joint calibration)",
)
def test_acceleration_feedforward_cuts_the_error_twentyfold_on_the_full_twin():
    assert _feedforward_gain(nonlinear=True) >= 20.0


def test_fig3_peak_is_the_seeds_on_the_calibrated_twin():
    # fitted (calibration.problem, with the share below): a regression check of the shipped file
    run = run_contour(ContourJob(control=ControlSettings(law="preview-dob")))
    peak = max(run.axis.peak_m)
    assert abs(peak / paper.FIG3_PEAK_ERROR_M - 1) <= paper.PROJECT_CHOICES["fig3_peak_tolerance"]


def test_fig3_errors_are_generally_below_half_a_micron():
    # fitted jointly with the peak (calibration.problem): 96.4 / 95.4 % (x / y), peak 0.800 µm
    run = run_contour(ContourJob(control=ControlSettings(law="preview-dob")))
    assert min(run.axis.fraction_below) >= paper.PROJECT_CHOICES["fig3_fraction_below_typical"]


@pytest.mark.parametrize(
    "mass_error",
    [
        pytest.param(
            -0.3,
            marks=pytest.mark.xfail(
                raises=AssertionError,
                strict=True,
                reason="a controller mass 30 % low raises the Fig. 3 peak 1.41x on the "
                "calibrated twin (0.800 -> 1.129 µm; 1.42x before issue 45's joint "
                "calibration); +30 % lowers it (0.622 µm)",
            ),
        ),
        0.3,
    ],
)
def test_a_thirty_percent_mass_error_raises_the_fig3_peak_by_at_most_a_fifth(mass_error):
    job = ContourJob(control=ControlSettings(law="preview-dob"))
    nominal = max(run_contour(job).axis.peak_m)
    off = max(run_contour(job.with_(twin=TwinSettings(mass_error=mass_error))).axis.peak_m)
    assert off <= 1.2 * nominal, (nominal, off)


def test_the_force_stays_within_table_one():
    run = run_contour(ContourJob())
    assert np.abs(run.force).max() <= paper.PEAK_FORCE_N * (1 + 1e-12)
    # the replayed plant holds the disturbance the twin saw: finite and not all zero
    assert np.all(np.isfinite(run.disturbance)) and np.abs(run.disturbance).max() > 0


def test_a_reference_beyond_the_stage_is_refused_before_running():
    with pytest.raises(LimitViolation, match="velocity"):
        run_contour(ContourJob(drawing="circle:radius=5e-3",
                               motion=ContourMotion(speed_m_s=0.2, laps=1)))  # fmt: skip


def test_drawings_without_the_contour_are_refused():
    with pytest.raises(ValueError, match="contour = 3 does not exist"):
        contour_path("circle:radius=1e-4", 3)


def test_a_dxf_circle_runs_as_the_shape_circle(tmp_path):
    ezdxf = pytest.importorskip("ezdxf")
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 13  # micrometres
    doc.modelspace().add_circle((0.0, 0.0), 30.0)
    path = tmp_path / "circle.dxf"
    doc.saveas(path)
    job = ContourJob(motion=ContourMotion(laps=1), twin=TwinSettings(nonlinear=False))
    a = run_contour(job)
    b = run_contour(job.with_(drawing=str(path)))
    np.testing.assert_allclose(b.reference.trajectory.position, a.reference.trajectory.position,
                               rtol=0, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(b.output, a.output, rtol=0, atol=1e-9)  # true positions, 1 nm
    # With the 10 nm encoder on, a 1e-20 m difference of the references can flip one count
    # (measured: true positions then differ by up to 3.5 nm): the run is compared without it.


def test_the_dob_estimate_follows_the_true_load_force():
    """The figure 'estimated vs true disturbance': the replayed DOB on the Fig. 3 run."""
    run = run_contour(ContourJob(control=ControlSettings(law="preview-dob")))
    est = run.dob  # its replayed currents equal the run's (checked inside the run)
    assert est is not None and est.shape == run.disturbance.shape
    for k in range(2):
        true = run.disturbance[:, k]
        gap = np.sqrt(np.mean((est[:, k] - true) ** 2))
        assert gap <= 0.25 * np.sqrt(np.mean(true**2))  # measured 12 %
        assert np.corrcoef(est[:, k], true)[0, 1] >= 0.95
    other = run_contour(ContourJob(control=ControlSettings(law="contour"), drawing=run.job.drawing))
    assert other.dob is None  # a run with an add-on: its currents are not the DOB's alone
    # the replay refuses currents it does not reproduce
    stage = make_stage(run.job.twin)
    ctrl = make_controller(run.job.control, stage, run.job.twin.mass_error)
    traj = run.reference.trajectory
    with pytest.raises(ValueError, match="replayed currents differ"):
        dob_estimate(ctrl, traj, run.measured, run.command + 1e-6)
