"""Seed 004 Fig. 7 on the stage twin: what the contour compensator does, and at which speed.

Seed 004 §IV.D: the contour compensator (eqs. 5-15) "has almost no significant
contribution to the contour tracking at low speeds. However at high speeds its effect is
significant" (simulation, 100 µm circle at 10 mm/s). `fig7_study` measures the contour
error against speed with the compensator off (``preview-dob``, "Response1") and on
(``contour``, "Response2") on several drawings, each with the twin's LuGre friction on and
off (noise off, as in the seed's simulation), so that the two things the compensator acts
on are told apart:

* **friction** (quadrant glitches at the velocity reversals): present only with friction
  on, largest at low speed, where the glitch lasts longest; the compensator's normal
  stiffness removes most of it. The seed's architecture gives these to the DOB (eq. 4).
* **contouring error proper** (the loop's dynamic lag on a curved path): present with
  friction off too, growing with speed; this is what the compensator exists for.

`path_frame_errors` splits a run's tracking error into its normal and tangential parts at
the reference point (the compensator's own frame), and `rotating_frame_prediction`
explains the case where the compensator does not help: on a curve the path frame turns at
``Ω = κ v`` (rad/s). For a loop ``ë + K_v ė + K_p e = f`` (``e = p − p_d``, ``f`` the
residual acceleration the feedforward and DOB leave) a steady error in that frame obeys

``[[K_p − Ω², K_v Ω], [−K_v Ω, K_p − Ω²]] [e_n, e_t]ᵀ = [f_n, f_t]ᵀ``

(``ṫ = Ω n``, ``ṅ = −Ω t``). The compensator adds ``k_pc`` to the normal row only (its
``ε̇`` is the path-frame derivative, zero in the steady state). When ``Ω`` approaches the
axis bandwidth ``ω_c`` (``K_p = ω_c²``), ``K_p − Ω²`` vanishes and the two rows are held
together by ``K_v Ω`` alone: a tangential residual makes a normal error, and stiffening
the normal direction moves the error into the tangential one, which feeds the normal one
again through ``K_v Ω``. The 30 µm circle of Fig. 3 at 10 mm/s turns at 333 rad/s against
``ω_c`` = 314 rad/s (50 Hz): there the normal row alone cannot help (1112 → 1253 nm,
friction off). The seed's law has two more parts that act there
(`microfab.control.contour`): row 2 of eq. 13 (the tangential speed) and eq. 15's ``J̇ v``
(which cancels the ``−Ω²`` of the rotating frame); with them the same circle goes
1112 → 249 nm. The 100 µm circle of Fig. 7 at 10 mm/s turns at 100 rad/s: there either
law helps. `fig7_cause` measures these three runs.

**On the paper's own model** (`fig7_paper_model`, issue 45): §IV.D is a simulation of
eqs. (2)-(15), so it is run first on the model the seed states (`TwinSettings.paper_model`:
eq. (2) with ``M = M_n`` = Table I's 0.6 kg, ``K_f = K_fn``, ``F_l = 0``, no friction,
cogging or cable; noise off), preview + DOB ("Response1") against the same with the
compensator ("Response2"), on the 100 µm circle. Without a disturbance the loop is linear
and its contouring error is the dynamic lag on the curve, which grows about as ``v⁴``
(``Ω = v/R``); the compensator cuts that lag by a near-constant factor (5-6x at 2-20
mm/s). At 0.5 mm/s the lag is below the reference's own picometre rounding (the spline
through the knots, `microfab.trajectory.contour_laps`), which no controller removes: both
runs show that floor and the ratio is about 1. So the ratio rises with speed, and the
change the compensator makes is below 0.05 nm up to 2 mm/s and 20-190 nm at 10-20 mm/s:
the seed's "almost no significant contribution ... at low speeds", "significant" at high.
The same model with Table I's 10 nm encoder resolution (``nonlinear`` on) is run beside it:
there the floor is the count (5-8 nm) and up to 5 mm/s the compensator moves the error by
less than a count either way (ratio 0.7-1.1), from 10 mm/s on it cuts it 3-5x. The
calibrated twin (`fig7_study`, friction on) is a prediction beside these: there the error
at low speed is the LuGre friction's quadrant glitches, which the compensator's normal
stiffness removes best where they last longest, so its ratio *falls* with speed (the
notes above).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.control.contour import ContourConfig
from microfab.core.limits import LimitViolation
from microfab.machines.laser_stage.machine import (
    ContourJob,
    ContourPlay,
    ControlSettings,
    TwinSettings,
    check_job,
    controller,
    play_contour,
    twin,
)
from microfab.measure.contour import contour_errors
from microfab.trajectory.contour_laps import ContourMotion

__all__ = [
    "FIG7_DRAWINGS",
    "FIG7_MODES",
    "FIG7_PAPER_DRAWING",
    "FIG7_SPEEDS_MM_S",
    "PathFrameErrors",
    "fig7_cause",
    "fig7_paper_direction",
    "fig7_paper_model",
    "fig7_point",
    "fig7_study",
    "path_frame_errors",
    "rotating_frame_prediction",
    "turn_rate",
]

#: Drawings of the study: the seed's Fig. 7 circle (100 µm read as the radius, seed 004
#: §IV.D), and two of the project's (assumed: a rounded square whose 100 µm corners and an
#: ellipse whose 133 µm tightest radius keep 20 mm/s within Table I's 5 m/s²).
FIG7_DRAWINGS = (
    "circle:radius=1e-4",
    "square:side=4e-4,corner_radius=1e-4",
    "ellipse:a=3e-4,b=2e-4",
)

#: Speeds of the study, mm/s (assumed: the seed names only 10 mm/s; 0.5-20 mm/s spans
#: "low" and "high" around it).
FIG7_SPEEDS_MM_S = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)

_LAWS = ("preview-dob", "contour")


@dataclass(frozen=True, kw_only=True)
class PathFrameErrors:
    """Tracking error ``p − p_d`` (true position) in the reference's path frame.

    Attributes
    ----------
    normal_mean_m, tangential_mean_m : float
        Means of ``e_n = nᵀ e`` and ``e_t = tᵀ e`` over the laps after the first, m
        (``t = ṙ/|ṙ|``, ``n`` = ``t`` turned +90°).
    normal_rms_m, tangential_rms_m : float
        Their RMS, m.
    """

    normal_mean_m: float
    tangential_mean_m: float
    normal_rms_m: float
    tangential_rms_m: float


def _after_first_lap(play: ContourPlay) -> slice:
    ref = play.reference
    first = 1 if len(ref.lap_starts) > 1 else 0
    return slice(int(ref.lap_starts[first]), int(ref.lap_ends[-1]))


def path_frame_errors(play: ContourPlay) -> PathFrameErrors:
    """`PathFrameErrors` of a played contour job (laps after the first; the only lap if one)."""
    sl = _after_first_lap(play)
    tr = play.reference.trajectory
    pd = np.asarray(tr.position)[sl]
    vd = np.asarray(tr.velocity)[sl]
    t = vd / np.linalg.norm(vd, axis=1)[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    e = play.trace.output[sl] - pd
    en = np.einsum("ij,ij->i", e, n)
    et = np.einsum("ij,ij->i", e, t)
    return PathFrameErrors(
        normal_mean_m=float(en.mean()),
        tangential_mean_m=float(et.mean()),
        normal_rms_m=float(np.sqrt(np.mean(en**2))),
        tangential_rms_m=float(np.sqrt(np.mean(et**2))),
    )


def turn_rate(play: ContourPlay) -> float:
    """Largest ``|Ω| = |κ| |ṙ| = |ẋÿ − ẏẍ| / |ṙ|²`` of the reference over its laps, rad/s."""
    sl = _after_first_lap(play)
    tr = play.reference.trajectory
    v = np.asarray(tr.velocity)[sl]
    a = np.asarray(tr.acceleration)[sl]
    return float(np.max(np.abs(v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / np.sum(v * v, axis=1)))


def _stiffness(k_p: float, k_v: float, omega: float) -> np.ndarray:
    """The path-frame steady-state matrix of the module notes, 1/s², shape (2, 2)."""
    d = k_p - omega * omega
    return np.array([[d, k_v * omega], [-k_v * omega, d]])


def rotating_frame_prediction(
    without: PathFrameErrors, omega: float, cfg: ContourConfig
) -> tuple[float, float]:
    """Predict the compensator's steady ``(e_n, e_t)`` on a circle from the run without it.

    The residual ``f`` is read off the uncorrected run's mean path-frame error through the
    axis loop's matrix (module notes), and the loop with ``k_pc`` added to the normal row
    is solved for it. Continuous-time gains, filters and DOB left out: an explanation, to
    a tenth or so, not a simulation.

    Parameters
    ----------
    without : PathFrameErrors
        The ``preview-dob`` run's errors on a circle.
    omega : float
        The circle's turn rate ``v / R``, rad/s.
    cfg : ContourConfig
        The compensator (its inner axis gains and ``k_pc``).

    Returns
    -------
    tuple of float
        Predicted ``(e_n, e_t)`` with the compensator, m.
    """
    inner = cfg.inner
    a0 = _stiffness(inner.k_p, inner.k_v, omega)
    f = a0 @ np.array([without.normal_mean_m, without.tangential_mean_m])
    a1 = a0 + np.array([[cfg.k_pc, 0.0], [0.0, 0.0]])
    e = np.linalg.solve(a1, f)
    return float(e[0]), float(e[1])


#: The twin and controller variants of the study, ``(friction, friction_ff)``: the full
#: twin, the full twin with the friction feedforward on both laws
#: (`ControlSettings.friction_ff`), the twin without friction.
FIG7_MODES = ((True, False), (True, True), (False, False))


def _job(
    drawing: str, speed_mm_s: float, law: str, friction: bool, laps: int, friction_ff: bool
) -> ContourJob:
    return ContourJob(
        drawing=drawing,
        motion=ContourMotion(speed_m_s=speed_mm_s * 1e-3, laps=laps),
        control=ControlSettings(law=law, friction_ff=friction_ff),
        twin=TwinSettings(noise=False, friction=friction),
    )


def fig7_point(
    drawing: str,
    speed_mm_s: float,
    friction: bool,
    *,
    friction_ff: bool = False,
    laps: int = 2,
) -> dict[str, Any]:
    """Both laws on one drawing at one speed and mode: one row of `fig7_study`.

    ``friction`` is the twin's LuGre friction, ``friction_ff`` the friction feedforward
    under both laws.

    Returns
    -------
    dict
        ``drawing``, ``speed_mm_s``, ``friction``, ``friction_ff``; ``without_nm`` and
        ``with_nm`` (largest contour error of the true positions after lap 1,
        ``preview-dob`` and ``contour``), ``gain`` (their ratio), ``turn_rate_ratio``
        (largest ``Ω`` over the axis loop's ``ω_c``), and the path-frame mean errors
        ``normal_nm`` / ``tangential_nm`` of each law (dicts by law). A reference beyond
        Table I is not run: the row then has ``refused`` (the limit's message) and no
        numbers.
    """
    out: dict[str, Any] = {
        "drawing": drawing,
        "speed_mm_s": speed_mm_s,
        "friction": friction,
        "friction_ff": friction_ff,
    }
    try:
        check_job(_job(drawing, speed_mm_s, "preview-dob", friction, laps, friction_ff))
    except LimitViolation as err:
        out["refused"] = str(err)
        return out
    normal: dict[str, float] = {}
    tangential: dict[str, float] = {}
    for law in _LAWS:
        p = play_contour(_job(drawing, speed_mm_s, law, friction, laps, friction_ff))
        laps_ = [p.reference.lap(i) for i in range(laps)]
        c = contour_errors(p.path, p.trace.output, laps_).steady_max()
        out["without_nm" if law == "preview-dob" else "with_nm"] = c * 1e9
        pf = path_frame_errors(p)
        normal[law] = pf.normal_mean_m * 1e9
        tangential[law] = pf.tangential_mean_m * 1e9
        if law == "preview-dob":
            omega_c = 2.0 * np.pi * p.job.control.bandwidth_hz
            out["turn_rate_ratio"] = turn_rate(p) / omega_c
    out["gain"] = out["without_nm"] / out["with_nm"]
    out["normal_nm"] = normal
    out["tangential_nm"] = tangential
    return out


def fig7_study(
    drawings: Sequence[str] = FIG7_DRAWINGS,
    speeds_mm_s: Sequence[float] = FIG7_SPEEDS_MM_S,
    modes: Sequence[tuple[bool, bool]] = FIG7_MODES,
    *,
    laps: int = 2,
) -> list[dict[str, Any]]:
    """`fig7_point` for every drawing, mode and speed (in that order).

    Parameters
    ----------
    drawings : sequence of str
        Drawing sources (`microfab.geometry.load.load_drawing`), m.
    speeds_mm_s : sequence of float
        Tangential speeds, mm/s.
    modes : sequence of (bool, bool)
        ``(friction, friction_ff)``: the twin's LuGre friction on / off
        (`TwinSettings.friction`), the friction feedforward on / off
        (`ControlSettings.friction_ff`).
    laps : int
        Full-speed laps per run (the error is taken after the first).

    Returns
    -------
    list of dict
        The rows (`fig7_point`).
    """
    return [
        fig7_point(d, v, fr, friction_ff=ff, laps=laps)
        for d in drawings
        for fr, ff in modes
        for v in speeds_mm_s
    ]


def _circle_run(
    radius_m: float, speed_mm_s: float, cs: ControlSettings
) -> tuple[PathFrameErrors, float]:
    """Path-frame errors and max contour error after lap 1 (m) of a friction-free circle."""
    job = _job(f"circle:radius={radius_m!r}", speed_mm_s, cs.law, False, 2, cs.friction_ff)
    p = play_contour(job.with_(control=cs))
    laps = [p.reference.lap(i) for i in range(2)]
    return path_frame_errors(p), contour_errors(p.path, p.trace.output, laps).steady_max()


def fig7_cause(
    radius_m: float = 30e-6, speed_mm_s: float = 10.0, control: ControlSettings | None = None
) -> dict[str, Any]:
    """Why a normal-only correction does not help on a circle turning near the bandwidth.

    Runs the circle friction-free without the compensator (``preview-dob``), with its
    normal row alone (``normal_only``, the law before issue 33) and with the full law (both
    rows of eq. 13 and eq. 15's ``J̇`` term), and predicts the normal-only law's path-frame
    errors from the uncorrected run (`rotating_frame_prediction`).

    Returns
    -------
    dict
        ``radius_um``, ``speed_mm_s``, ``turn_rate_rad_s``, ``bandwidth_rad_s`` (``ω_c``);
        per variant (``preview-dob``, ``normal-only``, ``contour``) the mean path-frame
        ``normal_nm`` / ``tangential_nm`` and the largest contour error after lap 1
        ``contour_nm``; ``predicted_nm``: ``(e_n, e_t)`` of the normal-only law by the
        path-frame model.
    """
    cs = control or ControlSettings()
    variants = {
        "preview-dob": dataclasses.replace(cs, law="preview-dob"),
        "normal-only": dataclasses.replace(cs, law="contour", normal_only=True),
        "contour": dataclasses.replace(cs, law="contour", normal_only=False),
    }
    runs = {k: _circle_run(radius_m, speed_mm_s, v) for k, v in variants.items()}
    plant = twin(TwinSettings(noise=False, friction=False))
    comp = controller(variants["normal-only"], plant)
    omega = speed_mm_s * 1e-3 / radius_m
    en, et = rotating_frame_prediction(runs["preview-dob"][0], omega, comp.config)
    return {
        "radius_um": radius_m * 1e6,
        "speed_mm_s": speed_mm_s,
        "turn_rate_rad_s": omega,
        "bandwidth_rad_s": 2.0 * np.pi * cs.bandwidth_hz,
        "normal_nm": {k: r[0].normal_mean_m * 1e9 for k, r in runs.items()},
        "tangential_nm": {k: r[0].tangential_mean_m * 1e9 for k, r in runs.items()},
        "contour_nm": {k: r[1] * 1e9 for k, r in runs.items()},
        "predicted_nm": (en * 1e9, et * 1e9),
    }


#: The drawing of `fig7_paper_model`: seed 004 §IV.D's "circle with 100 µm", read as the
#: radius (`paper.PROJECT_CHOICES`).
FIG7_PAPER_DRAWING = "circle:radius=1e-4"


def fig7_paper_model(
    speeds_mm_s: Sequence[float] = FIG7_SPEEDS_MM_S,
    *,
    resolution: bool = False,
    drawing: str = FIG7_PAPER_DRAWING,
    laps: int = 2,
) -> list[dict[str, Any]]:
    """Seed 004 Fig. 7 on the paper's model: both laws on the circle at each speed.

    Parameters
    ----------
    speeds_mm_s : sequence of float
        Tangential speeds, mm/s.
    resolution : bool
        Table I's 10 nm encoder resolution in the measured position (off: the equations
        alone, eq. (3)'s ``x_fb`` exact).
    drawing : str
        The drawing (default the seed's circle, 100 µm radius), m.
    laps : int
        Full-speed laps per run (the error is taken after the first).

    Returns
    -------
    list of dict
        Per speed: ``speed_mm_s``, ``without_nm`` (``preview-dob``, "Response1") and
        ``with_nm`` (``contour``, "Response2"): the largest contour error of the true
        positions after lap 1, nm; ``ratio`` (without / with) and ``change_nm`` (without
        − with), ``reference_nm`` (the reference's own largest contour error after lap
        1: the spline's rounding, the floor no controller removes). A speed beyond
        Table I is not run: its row has ``refused`` instead.
    """
    tw = TwinSettings(paper_model=True, noise=False, nonlinear=resolution)
    rows: list[dict[str, Any]] = []
    for v in speeds_mm_s:
        motion = ContourMotion(speed_m_s=v * 1e-3, laps=laps)
        row: dict[str, Any] = {"speed_mm_s": float(v)}
        err: dict[str, float] = {}
        try:
            for law in _LAWS:
                p = play_contour(ContourJob(drawing=drawing, motion=motion,
                                            control=ControlSettings(law=law), twin=tw))  # fmt: skip
                laps_ = [p.reference.lap(i) for i in range(laps)]
                err[law] = contour_errors(p.path, p.trace.output, laps_).steady_max() * 1e9
                ref = np.asarray(p.reference.trajectory.position)
                err["reference"] = contour_errors(p.path, ref, laps_).steady_max() * 1e9
        except LimitViolation as exc:
            row["refused"] = str(exc)
            rows.append(row)
            continue
        row["without_nm"] = err["preview-dob"]
        row["with_nm"] = err["contour"]
        row["ratio"] = err["preview-dob"] / err["contour"]
        row["change_nm"] = err["preview-dob"] - err["contour"]
        row["reference_nm"] = err["reference"]
        rows.append(row)
    return rows


def fig7_paper_direction(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Whether `fig7_paper_model`'s rows have the seed's direction (issue 45's target).

    The target: the ratio (largest contour error without / with the compensator) rises
    with speed (every step up in speed gives a ratio at least as large) and is at most
    ``paper.PROJECT_CHOICES["fig7_ratio_low_max"]`` (1.2) at the lowest speed.

    Returns
    -------
    dict
        ``speeds_mm_s`` and ``ratios`` of the rows that ran (in speed order),
        ``lowest_ratio``, ``rises`` (bool), ``first_fall_mm_s`` (the speed where the
        ratio first fell, or None).
    """
    ran = sorted((r for r in rows if "refused" not in r), key=lambda r: r["speed_mm_s"])
    ratios = [float(r["ratio"]) for r in ran]
    fall = next((ran[i]["speed_mm_s"] for i in range(1, len(ran)) if ratios[i] < ratios[i - 1]),
                None)  # fmt: skip
    return {
        "speeds_mm_s": [r["speed_mm_s"] for r in ran],
        "ratios": ratios,
        "lowest_ratio": ratios[0] if ratios else None,
        "rises": fall is None,
        "first_fall_mm_s": fall,
    }
