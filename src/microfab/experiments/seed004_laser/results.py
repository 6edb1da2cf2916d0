"""Results of the seed004_laser job kind: what its run returns and its report reads.

The job module (`job.py`) builds and returns them; the report module reads them and
never imports the job module.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.control.margins import AxisMargins
from microfab.core.provenance import Shows, quantity
from microfab.experiments.seed004_laser import paper
from microfab.machines.laser_stage.calibration import FIG3_JOB
from microfab.machines.laser_stage.contour import ContourRun
from microfab.machines.laser_stage.focus import FocusStudy
from microfab.machines.laser_stage.machine import ContourJob
from microfab.report.contour import (
    acceleration_table,
    contour_table,
    margins_table,
    slowdown_table,
    speed_table,
)
from microfab.report.provenance import OURS, labelled
from microfab.report.tables import Table, versus

__all__ = [
    "DOF_QUANTITY",
    "FIG3_JOB",
    "FocusSettings",
    "LaserJob",
    "LaserResult",
    "focus_table",
    "focus_targets",
    "seed_fig3_setup",
]

# FIG3_JOB: the seed's Fig. 3 run as the project reads it (seed 004 §IV.A: the 30 µm
# circle under preview control with DOB, eqs. 3-4; speed assumed): the run `microfab
# calibrate laser` fits, and the one `microfab reproduce laser-micromachining` reports.


def seed_fig3_setup(job: ContourJob) -> bool:
    """Whether ``job`` is the seed's Fig. 3 set-up, so its axis errors compare with §IV.A.

    The drawing, contour, speed, laps, knots, profile (the auto profile counts when it
    plays the constant one), sample rate, controller (``preview-dob`` with the default
    gains) and twin (noise and nonlinear parts on, the data file's disturbance scale and
    parameters, no mass error) must be `FIG3_JOB`'s; the noise seed may differ.
    """
    ref = FIG3_JOB
    m, r = job.motion, ref.motion
    profile_ok = m.profile == r.profile or m.profile == "auto"
    motion_ok = profile_ok and dataclasses.replace(m, profile=r.profile) == r
    twin_ok = dataclasses.replace(job.twin, seed=ref.twin.seed) == ref.twin
    return (
        job.drawing == ref.drawing
        and job.contour == ref.contour
        and motion_ok
        and job.control == ref.control
        and twin_ok
    )


@dataclass(frozen=True, kw_only=True)
class LaserJob:
    """A ``laser-micromachining`` job: the main run, the comparison, the speed sweep."""

    run: ContourJob
    compare: bool = True
    speeds_mm_s: tuple[float, ...] = (0.1, 1.0, 10.0)
    focus: FocusSettings | None = None


@dataclass(frozen=True, kw_only=True)
class FocusSettings:
    """The autofocus study of a job (`microfab.machines.laser_stage.focus.focus_study`)."""

    duration_s: float = 3.0
    tilt_mrad: float = 1.0
    part_speed_mm_s: float = 10.0

    def __post_init__(self) -> None:
        if not self.duration_s > 1.0:
            raise ValueError(
                f"focus duration_s must exceed 1 s (the steady window), got {self.duration_s:g} s"
            )
        if self.tilt_mrad > 0 and not self.part_speed_mm_s > 0:
            raise ValueError(
                f"focus part_speed_mm_s must be positive for a tilted part, got "
                f"{self.part_speed_mm_s:g} mm/s"
            )


#: Seed 004 §II.A's depth of focus (54 µm), as a compared quantity.
DOF_QUANTITY = quantity("004", "§II.A", "depth of focus")


def focus_targets(study: FocusStudy) -> dict[str, Any]:
    """The autofocus study against the project's targets (Fig. 6 has no numbers), JSON-ready.

    Returns
    -------
    dict
        ``ptp_um`` (continuous law's steady peak-to-peak) and ``ptp_max_um``, ``ratio``
        (discontinuous over continuous) and ``ratio_min``, ``ptp_met``, ``ratio_met``.
    """
    ptp = study.continuous.steady_ptp_m
    ptp_max = paper.PROJECT_CHOICES["autofocus_ptp_max_m"]
    ratio_min = paper.PROJECT_CHOICES["autofocus_ratio_min"]
    return {
        "ptp_um": ptp * 1e6,
        "ptp_max_um": ptp_max * 1e6,
        "ptp_met": bool(ptp <= ptp_max),
        "ratio": study.ptp_ratio,
        "ratio_min": ratio_min,
        "ratio_met": bool(study.ptp_ratio >= ratio_min),
    }


def focus_table(study: FocusStudy) -> Table:
    """The autofocus figures beside the project's targets (seed 004 gives no numbers)."""
    s = study.summary()
    g = focus_targets(study)

    def met(ok: bool) -> str:
        return "met" if ok else "NOT met"

    def t(v: float | None) -> str:
        return "never (for good)" if v is None else f"{v:.3f}"

    rows = [
        ("depth of focus [µm]", versus(s["depth_of_focus_um"], paper.DEPTH_OF_FOCUS_M * 1e6,
                                       "{:.1f}".format)),
        ("inside ±DOF/2 for good from, continuous / discontinuous [s]",
         f"{t(s['continuous_entered_s'])} / {t(s['discontinuous_entered_s'])}"),
        ("steady peak-to-peak z, continuous / discontinuous [µm]",
         f"{s['continuous_steady_ptp_um']:.2f} / {s['discontinuous_steady_ptp_um']:.2f} "
         f"(target: continuous <= {g['ptp_max_um']:g}: {met(g['ptp_met'])})"),
        ("ratio discontinuous / continuous",
         f"{s['ptp_ratio']:.2f} (target >= {g['ratio_min']:g}: {met(g['ratio_met'])})"),
        ("law's h against the detector at focus [ln q]",
         f"h = {s['h_lnq']:.3g}; noise rms {s['noise_lnq']:.2g}, one count "
         f"{s['count_lnq']:.2g} (h = {s['h_over_noise']:.0f}x the noise)"),
    ]  # fmt: skip
    if study.tilted is not None:
        err = s["tilted_max_error_um"]
        rows.append((
            f"tilted part {s['tilt_mrad']:g} mrad at {s['part_speed_mm_s']:g} mm/s: max "
            "|z − focus| (steady) [µm]",
            f"{err:.2f}"
            + f" (DOF/2 = {s['depth_of_focus_um'] / 2:.1f})",
        ))  # fmt: skip
    table = Table(
        title="Autofocus (seed 004 §III.B, eqs. 16-17) on the focus twin",
        columns=("figure", "ours"),
        rows=rows,
        note=f"Start {s['start_um']:.0f} µm off focus (assumed); steady = last 1 s. The "
        "seed shows Fig. 6 without numbers; the targets are the project's (issues 15, 33, "
        "45), not met where it says so: the law's constants come from a design rule on the "
        "twin's assumed stage (2 mm/s, 5 ms lag) and the seed's beam (10.8 µm waist), never "
        "from these targets. The band does not depend on the noise seed: the noise and the "
        "converter count lie hundreds of times below h, so they never trigger a reversal, "
        "and the band is the law's own stall-reversal cycle (V, τ, ρ, h), the same for any "
        "seed to the z encoder's 0.1 µm count.",
    )
    return labelled(table, [Shows((DOF_QUANTITY,))] + [OURS] * (len(rows) - 1))


@dataclass(frozen=True, kw_only=True, eq=False)
class LaserResult:
    """A finished job: the main run, the uncorrected comparison, the sweep rows."""

    config: LaserJob
    main: ContourRun
    baseline: ContourRun | None
    sweep: tuple[dict[str, Any], ...]
    sweep_failures: tuple[str, ...] = ()
    margins: tuple[AxisMargins, ...] = ()
    focus: FocusStudy | None = None

    def fig3_run(self) -> ContourRun | None:
        """The run to set beside seed 004 Fig. 3: the ``preview-dob`` run of the seed's set-up.

        The main run if it is one, else the uncorrected comparison run (Fig. 3 is the
        preview controller with DOB; the contour compensator was only simulated, §IV.D);
        ``None`` when neither is the seed's set-up (`seed_fig3_setup`).
        """
        for run in (self.main, self.baseline):
            if run is not None and seed_fig3_setup(run.job):
                return run
        return None

    def axis_table(self) -> Table:
        """Axis tracking: beside seed 004 §IV.A for the seed's set-up, else ours alone."""
        fig3 = self.fig3_run()
        m = fig3 or self.main
        if fig3 is not None:
            rows = [
                (f"within ±0.5 µm, {ax} [%]",
                 versus(m.axis.fraction_below[k] * 100, 95.0, "{:.1f}".format))
                for k, ax in enumerate("xy")
            ] + [
                (f"peak |e_{ax}| [µm]", versus(m.axis.peak_m[k] * 1e6, 0.8, "{:.2f}".format))
                for k, ax in enumerate("xy")
            ]  # fmt: skip
            return Table(
                title=f"Axis tracking ({m.job.control.law}), ours / seed 004 §IV.A (Fig. 3)",
                columns=("figure", "ours / seed"),
                rows=rows,
                note="Seed: 'errors are generally lower than 0.5 µm, reaching 0.8 µm at the "
                "peak points' (30 µm circle, preview control with DOB; speed not given, "
                "1 mm/s assumed). '95 %' is our reading of 'generally'. The same run as "
                "`microfab reproduce laser-micromachining`'s Fig. 3 row.",
            )
        rows = [
            (f"within ±0.5 µm, {ax} [%]", f"{m.axis.fraction_below[k] * 100:.1f}")
            for k, ax in enumerate("xy")
        ] + [(f"peak |e_{ax}| [µm]", f"{m.axis.peak_m[k] * 1e6:.2f}") for k, ax in enumerate("xy")]
        return Table(
            title=f"Axis tracking ({m.job.control.law}), ours: not seed 004's Fig. 3 set-up, "
            "not compared with it",
            columns=("figure", "ours"),
            rows=rows,
            note="Not seed 004's Fig. 3 set-up (30 µm circle at 1 mm/s, preview + DOB, the "
            "full twin): the seed's 0.5 / 0.8 µm are not set beside these.",
        )

    def comparison(self) -> tuple[Table, ...]:
        """Axis tracking (beside seed 004 §IV.A when it is Fig. 3's set-up), contour runs."""
        m = self.main
        t1 = self.axis_table()
        runs = {"main: " + m.job.control.law: m}
        if self.baseline is not None:
            runs["without correction"] = self.baseline
        tables = [t1, contour_table(runs)]
        if m.reference.motion.profile == "limited":
            tables.append(slowdown_table(self._slowdowns(), m.job.motion.speed_m_s,
                                         len(m.reference.corner_positions())))  # fmt: skip
        lowered = self._acceleration_lowered()
        if lowered is not None:
            tables.append(acceleration_table(lowered))
        if self.margins:
            tables.append(margins_table(self.margins))
        if self.focus is not None:
            tables.append(focus_table(self.focus))
        if self.sweep:
            tables.append(speed_table(self.sweep))
        return tuple(tables)

    def _fig3_summary(self) -> dict[str, Any] | None:
        """Fig. 3's row beside the seed's numbers, or ``None`` off the seed's set-up."""
        fig3 = self.fig3_run()
        if fig3 is None:
            return None
        return {
            "law": fig3.job.control.law,
            "fraction_below_0p5um": list(fig3.axis.fraction_below),
            "peak_um": [v * 1e6 for v in fig3.axis.peak_m],
            "seed_typical_error_um": paper.FIG3_TYPICAL_ERROR_M * 1e6,
            "seed_peak_error_um": paper.FIG3_PEAK_ERROR_M * 1e6,
        }

    def _slowdowns(self) -> list[dict[str, Any]]:
        """Lap 1's slow-downs of the main run (`ContourReference.slowdowns`), JSON-ready."""
        ref = self.main.reference
        where = ref.corner_positions()
        return [
            {"at_mm": d.at_m * 1e3, "speed_mm_s": d.speed_m_s * 1e3,
             "corners": list(d.corners), "corner_at_mm": [where[c - 1] * 1e3 for c in d.corners],
             "from_rest": d.from_rest}
            for d in ref.slowdowns()
        ]  # fmt: skip

    def _acceleration_lowered(self) -> dict[str, Any] | None:
        """What the main run's plan lowered for the continuous force, or ``None``."""
        low = self.main.reference.acceleration_lowered
        return None if low is None else dataclasses.asdict(low)

    def failures(self) -> tuple[str, ...]:
        """Sweep points that failed (the rest ran)."""
        return self.sweep_failures

    def summary(self) -> dict[str, Any]:
        """The numbers of the tables, JSON-ready."""
        m = self.main
        out: dict[str, Any] = {
            "law": m.job.control.law,
            "axis": {
                "fraction_below_0p5um": list(m.axis.fraction_below),
                "peak_um": [v * 1e6 for v in m.axis.peak_m],
                "rms_um": [v * 1e6 for v in m.axis.rms_m],
            },
            "contour_lap_max_nm": (m.contour.lap_max_m * 1e9).tolist(),
            "force_peak_n": float(np.abs(m.force).max()),
            "fig3": self._fig3_summary(),
            "sweep": list(self.sweep),
            "failures": list(self.failures()),
            "profile": m.reference.motion.profile,
            "slowdowns": self._slowdowns(),
            "corners": len(m.reference.corner_positions()),
            "acceleration_lowered": self._acceleration_lowered(),
        }
        out["margins"] = [
            {
                "axis": m.axis,
                "crossover_hz": m.margins.pm_freq_hz,
                "phase_margin_deg": m.margins.pm_deg,
                "gain_margin_db": m.margins.gm_db,
                "sensitivity_peak_db": m.sensitivity_peak_db,
            }
            for m in self.margins
        ]
        if self.focus is not None:
            out["focus"] = self.focus.summary()
            out["focus_targets"] = focus_targets(self.focus)
        if self.baseline is not None:
            out["baseline_contour_lap_max_nm"] = (self.baseline.contour.lap_max_m * 1e9).tolist()
        return out
