"""Time-optimal parameterisation: our LP planner against TOPP-RA on the same path.

Prints, for N = 1000 grid points on a rounded rectangle (40 × 30 mm, 5 mm corner radius;
``microfab.geometry.shapes.rectangle`` when available, else a local line/arc path), the
wall time (best of 3) and the trajectory duration of

(a) ``time_optimal`` with velocity and acceleration limits only,
(b) TOPP-RA (``toppra.algorithm.TOPPRA``, seidel solver) with the same limits, scaled by
    ``1 - margin`` as our planner plans with, on the same grid,
(c) ``time_optimal`` with a jerk limit as well,

and the ratio of the wall times (a)/(b). Limits: the stage of seed 002 Table I (1.5 m/s,
40 m/s², ``MachineLimits.seed002_stage``); the jerk 2e4 m/s³ is an assumed value.

Run: ``python benchmarks/bench_topp.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _timing import best

from microfab.core.limits import MachineLimits
from microfab.trajectory.optimal import time_optimal

N_GRID = 1000
MARGIN = 0.01
JERK = 2e4  # m/s³, assumed (no paper gives one)


class _RoundedRectangle:
    """Fallback path (lines and quarter arcs, counter-clockwise), the Path interface."""

    def __init__(self, w: float, h: float, r: float) -> None:
        self.closed = True
        c = [(w / 2 - r, -h / 2 + r), (w / 2 - r, h / 2 - r), (-w / 2 + r, h / 2 - r)]
        c.append((-w / 2 + r, -h / 2 + r))
        starts = [
            (-w / 2 + r, -h / 2),
            (w / 2, -h / 2 + r),
            (w / 2 - r, h / 2),
            (-w / 2, h / 2 - r),
        ]
        dirs = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]
        lens = [w - 2 * r, h - 2 * r, w - 2 * r, h - 2 * r]
        self.segs: list[tuple[Any, ...]] = []
        for k in range(4):
            self.segs.append(("line", np.array(starts[k]), np.array(dirs[k]), lens[k]))
            a0 = -np.pi / 2 + k * np.pi / 2
            self.segs.append(("arc", np.array(c[k]), r, a0, np.pi / 2 * r))
        seg_len = [float(sg[-1]) for sg in self.segs]
        self.starts = np.concatenate([[0.0], np.cumsum(seg_len)])
        self.length = float(self.starts[-1])

    def evaluate(self, s: np.ndarray, order: int = 3) -> list[np.ndarray]:
        sv = np.asarray(s, dtype=float)
        idx = np.clip(np.searchsorted(self.starts, sv, side="right") - 1, 0, len(self.segs) - 1)
        out = [np.zeros((sv.size, 2)) for _ in range(4)]
        for j, sg in enumerate(self.segs):
            m = idx == j
            u = (sv[m] - self.starts[j])[:, None]
            if sg[0] == "line":
                out[0][m] = sg[1] + u * sg[2]
                out[1][m] = sg[2]
            else:
                ph = sg[3] + u[:, 0] / sg[2]
                cs, sn = np.cos(ph)[:, None], np.sin(ph)[:, None]
                out[0][m] = sg[1] + sg[2] * np.hstack([cs, sn])
                out[1][m] = np.hstack([-sn, cs])
                out[2][m] = -np.hstack([cs, sn]) / sg[2]
                out[3][m] = np.hstack([sn, -cs]) / sg[2] ** 2
        return out[: order + 1]

    def corners(self, angle_tol: float = 1e-3) -> np.ndarray:
        return np.array([])

    def junctions(self) -> np.ndarray:
        return self.starts[1:-1].copy()


def make_path() -> Any:
    try:
        from microfab.geometry.shapes import rectangle
    except ImportError:
        return _RoundedRectangle(0.04, 0.03, 0.005)
    return rectangle(0.04, 0.03, corner_radius=0.005)


def toppra_duration(path: Any, limits: MachineLimits, grid: np.ndarray) -> float:
    import toppra.algorithm as algo
    import toppra.constraint as constraint
    from toppra.interpolator import AbstractGeometricPath

    class Wrapped(AbstractGeometricPath):
        def __call__(self, s: np.ndarray, order: int = 0) -> np.ndarray:
            return path.evaluate(np.atleast_1d(np.asarray(s, dtype=float)), 2)[order]

        @property
        def dof(self) -> int:
            return 2

        @property
        def path_interval(self) -> np.ndarray:
            return np.array([0.0, path.length])

    v = (1 - MARGIN) * np.asarray(limits.velocity)
    a = (1 - MARGIN) * np.asarray(limits.acceleration)
    inst = algo.TOPPRA(
        [
            constraint.JointVelocityConstraint(v),
            constraint.JointAccelerationConstraint(np.column_stack([-a, a])),
        ],
        Wrapped(),
        gridpoints=grid,
        solver_wrapper="seidel",
        # the default spline parametrizer fails on SciPy >= 1.15; constant acceleration
        # per grid interval is the same time law as ours
        parametrizer="ParametrizeConstAccel",
    )
    traj = inst.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise RuntimeError("TOPP-RA found no parameterisation")
    return float(traj.duration)


def main() -> None:
    path = make_path()
    limits = MachineLimits.seed002_stage()
    print(f"path: rounded rectangle 40 x 30 mm, r = 5 mm, length {path.length * 1e3:.2f} mm")
    print(f"N = {N_GRID} grid points, margin {MARGIN}, best of 3 wall times\n")

    wall_a, res_a = best(lambda: time_optimal(path, limits, n_grid=N_GRID, margin=MARGIN))
    print(
        f"(a) ours, v/a only : wall {wall_a * 1e3:8.1f} ms   "
        f"duration {res_a.duration * 1e3:8.3f} ms   ({res_a.iterations} LP, {res_a.rounds} rounds)"
    )
    try:
        grid = np.asarray(res_a.s)
        wall_b, dur_b = best(lambda: toppra_duration(path, limits, grid))
    except ImportError:
        wall_b, dur_b = float("nan"), float("nan")
        print("(b) TOPP-RA        : toppra not installed")
    else:
        print(f"(b) TOPP-RA, v/a   : wall {wall_b * 1e3:8.1f} ms   duration {dur_b * 1e3:8.3f} ms")
    jl = limits.with_jerk(JERK)
    wall_c, res_c = best(lambda: time_optimal(path, jl, n_grid=N_GRID, margin=MARGIN))
    print(
        f"(c) ours, + jerk   : wall {wall_c * 1e3:8.1f} ms   "
        f"duration {res_c.duration * 1e3:8.3f} ms   ({res_c.iterations} LP, {res_c.rounds} rounds, "
        f"jerk {JERK:g} m/s^3)"
    )
    print(
        f"\nwall time ratio (a)/(b) = {wall_a / wall_b:.2f}; "
        f"duration ratio (a)/(b) = {res_a.duration / dur_b:.4f}; (c)/(a) = {wall_c / wall_a:.1f}"
    )


if __name__ == "__main__":
    main()
