"""Speed of the seed 004 loop and of the exact contour error.

Prints, in one run on this machine:

1. The stage twin (`microfab.plants.lmw_stage`, LuGre friction, 10 kHz) under preview +
   DOB with the contour compensator (`microfab.control.contour`), over a DXF part (a
   4 mm x 2 mm rounded rectangle, 0.5 mm corner radius, written to a temporary file and
   read back) at 10 mm/s, two laps: compiled `simulate` in steps per second and multiples
   of real time (goal >= 50x), and the pure-Python loop (`simulate_python`) on 2000
   samples of the same run from the same state (goal: compiled >= 100x Python).
2. The exact contour error of those positions (`microfab.geometry.project.project_points`,
   vectorised) against the per-point scalar minimisation (`project_points_scalar`) on a
   subset: the speed ratio (goal >= 50x) and the largest difference (goal <= 1e-10 m).

numba compilation is excluded (every path runs once first); timings are the best of a
few repeats. No asserts: figures are printed next to their goals.

Run: ``make bench`` or ``python benchmarks/bench_laser.py``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import best, timed

from microfab.geometry.project import project_points, project_points_scalar
from microfab.machines.laser_stage.machine import ControlSettings, TwinSettings, controller, twin
from microfab.sim.loop import LoopState, simulate, simulate_python
from microfab.trajectory.contour_laps import ContourMotion, contour_path, contour_reference

SPEED_M_S = 10e-3  # the seed's Fig. 7 speed
RT_GOAL = 50.0
PY_GOAL = 100.0
PROJ_GOAL = 50.0


def write_part(folder: Path) -> Path:
    """A 4 mm x 2 mm rectangle with 0.5 mm round corners as a DXF polyline (bulges)."""
    import ezdxf

    w, h, r = 4.0, 2.0, 0.5  # mm
    b = float(np.tan(np.pi / 8))  # bulge of a 90° arc
    pts = [
        (r, 0, 0), (w - r, 0, b), (w, r, 0), (w, h - r, b), (w - r, h, 0), (r, h, b),
        (0, h - r, 0), (0, r, b),
    ]  # fmt: skip
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4  # mm
    doc.modelspace().add_lwpolyline(pts, format="xyb", close=True)
    path = folder / "part.dxf"
    doc.saveas(path)
    return path


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        dxf = write_part(Path(tmp))
        path = contour_path(str(dxf))
    stage = twin(TwinSettings())
    ctrl = controller(ControlSettings(law="contour"), stage)
    ref = contour_reference(path, ContourMotion(speed_m_s=SPEED_M_S, laps=2))
    traj = ref.trajectory
    pos = np.asarray(traj.position)
    n = pos.shape[0]
    noise = stage.noise(n, seed=0)
    der = (traj.velocity, traj.acceleration)
    s0 = LoopState(
        plant=stage.state_at((float(pos[0, 0]), float(pos[0, 1]))),
        controller=ctrl.init(),
        observer=np.zeros(0),
        command=np.zeros(2),
    )
    simulate(stage, ctrl, pos[:50], noise[:50], s0, derivatives=(der[0][:50], der[1][:50]))
    t_c, _ = best(lambda: simulate(stage, ctrl, pos, noise, s0, derivatives=der))
    sim_s = n * float(traj.dt)
    print(
        f"seed 004 loop: stage twin + preview/DOB + contour compensator, DXF part "
        f"({path.length * 1e3:.2f} mm contour) at {SPEED_M_S * 1e3:g} mm/s, 2 laps, "
        f"{n} samples ({sim_s:.2f} s)"
    )
    print(f"  compiled simulate   {t_c:7.3f} s   {n / t_c:10.3g} steps/s   "
          f"{sim_s / t_c:6.1f}x real time")  # fmt: skip
    head = simulate(stage, ctrl, pos[:3000], noise[:3000], s0,
                    derivatives=(der[0][:3000], der[1][:3000]))  # fmt: skip
    sl = slice(3000, 5000)
    part = (pos[sl], noise[sl])
    dpart = (der[0][sl], der[1][sl])
    st = head.final_state
    t_cp, _ = best(lambda: simulate(stage, ctrl, *part, st, derivatives=dpart), 5)
    t_py, _ = best(lambda: simulate_python(stage, ctrl, *part, st, derivatives=dpart), 1)
    ratio_py = t_py / t_cp
    print(f"  2000 samples: Python {t_py:.3f} s, compiled {t_cp * 1e3:.2f} ms: {ratio_py:.0f}x")
    res = simulate(stage, ctrl, pos, noise, s0, derivatives=der)
    pts = res.measured
    project_points(path, pts[:100])
    t_v, _ = best(lambda: project_points(path, pts))
    m = min(400, pts.shape[0])
    idx = np.linspace(0, pts.shape[0] - 1, m).astype(int)
    t_s, slow = timed(lambda: project_points_scalar(path, pts[idx]))
    t_s *= pts.shape[0] / m
    diff = float(np.max(np.abs(project_points(path, pts[idx]).distance - slow.distance)))
    ratio_p = t_s / t_v
    print(
        f"\ncontour error of {pts.shape[0]} points: vectorised {t_v * 1e3:.1f} ms; scalar "
        f"{t_s:.2f} s (timed on {m} points, scaled); {ratio_p:.0f}x; max difference "
        f"{diff:.2e} m"
    )
    rows = [
        ("loop, x real time", f">= {RT_GOAL:.0f}x", f"{sim_s / t_c:.1f}x", sim_s / t_c >= RT_GOAL),
        ("loop, compiled / Python", f">= {PY_GOAL:.0f}x", f"{ratio_py:.0f}x", ratio_py >= PY_GOAL),
        ("contour error, vectorised / scalar", f">= {PROJ_GOAL:.0f}x", f"{ratio_p:.0f}x",
         ratio_p >= PROJ_GOAL),
        ("contour error, max difference", "<= 1e-10 m", f"{diff:.1e} m", diff <= 1e-10),
    ]  # fmt: skip
    print(f"\n{'figure':<38} {'goal':>11} {'measured':>10}  met")
    for name, goal, got, met in rows:
        print(f"  {name:<36} {goal:>11} {got:>10}  {'yes' if met else 'NO'}")


if __name__ == "__main__":
    main()
