"""Cured lines of a nanomanipulator job (seed 001 §4.2, Figs. 14-15): three prints per circle.

What the nanomanipulator-msl job (`microfab run`) prints. For every circle of a
`microfab.machines.nanomanipulator.job.JobRun` the spot follows the twin's *true*
position (the resin sees the stage, not the sensor) and the laser diode of the job (dead
time plus first-order rise, `microfab.process.laser.LaserDiode`) writes three prints,
each one loop long:

* **gated**: the gate's own switch command (seed 001: the laser switches on at a
  contour start once the error is sub-micron) with the warm-up left as it is, the
  seed's situation behind the open circles of Fig. 14;
* **compensated**: the same command with its switch-on advanced by the warm-up
  (`microfab.process.laser.advance_gate`), the software fix the seed leaves for later;
* **ungated**: the laser switched on at the first period's start, before the loop has
  converged, with the same warm-up compensation (so the comparison isolates the gate).

The cure threshold makes the nominal line (straight, at the circle's speed, full power)
2.5 µm wide (seed 001 Fig. 15; `microfab.process.dose.calibrate_threshold`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from microfab.machines.nanomanipulator.job import JobRun
from microfab.process.cured_line import LoopMeasures, measure_loop
from microfab.process.dose import DoseMap, calibrate_threshold, exposure_map
from microfab.process.laser import advance_gate

__all__ = ["PRINTS", "CircleCure", "Print", "cure_circles"]

#: The three prints per circle, in report order.
PRINTS = ("gated", "compensated", "ungated")


@dataclass(frozen=True, kw_only=True, eq=False)
class Print:
    """One loop written on one circle.

    Attributes
    ----------
    name : str
        One of `PRINTS`.
    switch_on : int
        Job sample of the (possibly advanced) switch-on command.
    loop : LoopMeasures
        Width, closure, gap and closing-point width along the contour.
    dose : DoseMap
        The dose, J/m².
    """

    name: str
    switch_on: int
    loop: LoopMeasures
    dose: DoseMap


@dataclass(frozen=True, kw_only=True, eq=False)
class CircleCure:
    """The prints of one circle and the cure threshold, J/m²."""

    circle: int
    threshold_j_m2: float
    prints: dict[str, Print]


def _write(run: JobRun, name: str, on: int, off: int, switch: int, threshold: float) -> Print:
    """Dose and loop measures of a laser command on ``[switch, off)`` for the loop at ``on``."""
    cfg = run.config
    n = run.reference.period_samples
    dt = run.dt
    pad = max(int(0.02 * n), 10)
    lo, hi = max(switch - pad, 0), min(off + pad, run.reference.n_samples)
    gate = np.zeros(hi - lo, dtype=bool)
    gate[switch - lo : off - lo] = True
    t = np.arange(lo, hi) * dt
    xy = run.output[lo:hi] * 1e-3  # mm -> m
    dmap = exposure_map(t, xy[:, 0], xy[:, 1], gate, cfg.laser, settings=cfg.dose)
    contour = run.reference.position[on : on + n] * 1e-3
    loop = measure_loop(dmap, contour, threshold, closing_index=0)
    return Print(name=name, switch_on=switch, loop=loop, dose=dmap)


def cure_circles(run: JobRun) -> tuple[CircleCure, ...]:
    """The three prints of every circle (module notes); gated prints need an open gate.

    Parameters
    ----------
    run : JobRun
        A finished job.

    Returns
    -------
    tuple of CircleCure
        One per circle; ``prints`` lacks "gated" and "compensated" where the gate never
        opened.
    """
    cfg = run.config
    n = run.reference.period_samples
    dt = run.dt
    speed_m_s = math.pi * cfg.pattern.diameter_mm * 1e-3 / cfg.pattern.period_s
    threshold = calibrate_threshold(
        power_w=cfg.laser.power_w, speed_m_s=speed_m_s, settings=cfg.dose
    )
    n_adv = round(cfg.laser.warmup_s / dt)
    out = []
    for c in run.circles:
        prints: dict[str, Print] = {}
        if c.gate_opened is not None and c.gate_closed is not None:
            on, off = c.gate_opened, c.gate_closed
            prints["gated"] = _write(run, "gated", on, off, on, threshold)
            g = np.zeros(run.reference.n_samples, dtype=bool)
            g[on:off] = True
            adv = advance_gate(g, dt, cfg.laser, period_s=cfg.pattern.period_s)
            prints["compensated"] = _write(
                run, "compensated", on, off, int(np.flatnonzero(adv)[0]), threshold
            )
        first = c.start
        prints["ungated"] = _write(
            run, "ungated", first, first + n, max(first - n_adv, 0), threshold
        )
        out.append(CircleCure(circle=c.index, threshold_j_m2=threshold, prints=prints))
    return tuple(out)
