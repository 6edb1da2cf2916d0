"""Breakup time over concentration and voltage: the seed's Fig. 4 and its voltage trend.

A sweep runs :func:`microfab.process.inkjet.droplet.simulate_droplet` once per point:
the six NaAlg concentrations of seed 003 part 1
(``../shared/seeds/003_4915b267b12a78d4.txt``, "Materials") at 50 V (its Fig. 4), and the
Table 1 voltages 40-70 V at one concentration (numbers in :mod:`.paper`). Every finished
point is written at once (atomically) to a JSON file, and a sweep started
again with the same file and settings skips the points already there, so an interrupted
sweep loses at most the point in progress. The figure is
:func:`microfab.experiments.seed003_inkjet.figures.fig_sweep`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from microfab.core.validate import check_positive
from microfab.experiments.seed003_inkjet.paper import (
    FIG4_VOLTAGE_V,
    SEED_CONCENTRATIONS_PCT,
    SEED_VOLTAGES_V,
)
from microfab.io.atomic import atomic_write_json

__all__ = [
    "SWEEP_MAX_STEPS",
    "SweepPoint",
    "run_sweep",
    "sweep_points",
]

#: Step budget per sweep point, a safeguard: the seed's points take 1 200 to 11 600 steps
#: each (1 % at 65 V the most). Before a cut removed the thin thread beside the neck
#: (`microfab.process.inkjet.jet.Numerics.cut_radius_factor`), the 1 % run at 45 V
#: ground on for more than 10 minutes; a point that runs out ends with its
#: ``solver_stop_reason`` in the row instead of holding up the sweep.
SWEEP_MAX_STEPS = 60_000


@dataclass(frozen=True)
class SweepPoint:
    """One simulation of a sweep."""

    concentration_pct: float
    voltage_v: float


def sweep_points(
    concentrations_pct: Sequence[float] = SEED_CONCENTRATIONS_PCT,
    voltages_v: Sequence[float] = SEED_VOLTAGES_V,
    *,
    voltage_concentration_pct: float = 1.0,
) -> list[SweepPoint]:
    """The concentration series at 50 V, then the voltage series at one concentration.

    Parameters
    ----------
    concentrations_pct : sequence of float
        Concentrations of the 50 V series, % w/v.
    voltages_v : sequence of float
        Voltages of the voltage series, V (may be empty).
    voltage_concentration_pct : float, optional
        Concentration of the voltage series, % w/v.

    Returns
    -------
    list of SweepPoint
        Without duplicates, in run order.

    Examples
    --------
    >>> [(p.concentration_pct, p.voltage_v) for p in sweep_points([0.15, 1.0], [50, 60])]
    [(0.15, 50.0), (1.0, 50.0), (1.0, 60.0)]
    """
    out: list[SweepPoint] = []
    for c in concentrations_pct:
        out.append(SweepPoint(float(c), FIG4_VOLTAGE_V))
    for v in voltages_v:
        out.append(SweepPoint(float(voltage_concentration_pct), float(v)))
    return list(dict.fromkeys(out))


def run_sweep(
    points: Sequence[SweepPoint],
    *,
    duration_s: float = 400e-6,
    results_path: str | Path | None = None,
    simulate: Callable[[SweepPoint, float], dict[str, Any]] | None = None,
    progress: Callable[[int, SweepPoint], None] | None = None,
    jobs: int = 1,
) -> list[dict[str, Any]]:
    """Simulate every point, saving and resuming through ``results_path``.

    Parameters
    ----------
    points : sequence of SweepPoint
        What to run (:func:`sweep_points`).
    duration_s : float, optional
        Simulated time per point, s.
    results_path : str or Path, optional
        JSON file holding ``{"settings": ..., "rows": [...]}``. Rows already there for
        the same settings are reused; the file is rewritten atomically after each point.
    simulate : callable, optional
        ``(point, duration_s) → summary dict``; default:
        :func:`microfab.process.inkjet.droplet.simulate_droplet` with the seed's bipolar
        waveform, ``DropletResult.to_dict()``. With ``jobs > 1``
        it must be picklable (a module-level function).
    progress : callable, optional
        Called with (number of points finished, point) after each simulation that is
        actually run.
    jobs : int, optional
        Worker processes. ``1`` runs the points one after another in this process; more
        run them side by side, each finished point saved as soon as it comes back.

    Returns
    -------
    list of dict
        One summary per point, in the order of ``points``.

    Raises
    ------
    ValueError
        If ``duration_s`` is not positive, ``jobs`` is below 1, or ``results_path`` holds
        a sweep with other settings (remove it or choose another file).
    """
    check_positive("duration_s", duration_s, "s")
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    sim = simulate or _simulate
    settings = {"duration_s": duration_s}
    done: dict[tuple[float, float], dict[str, Any]] = {}
    path = Path(results_path) if results_path is not None else None
    if path is not None and path.exists():
        saved = json.loads(path.read_text(encoding="utf-8"))
        if saved.get("settings") != settings:
            raise ValueError(
                f"{path} holds a sweep with settings {saved.get('settings')}, not {settings}; "
                "remove it or choose another file"
            )
        for row in saved.get("rows", []):
            done[(row["concentration_pct"], row["voltage_v"])] = row
    unique = list(dict.fromkeys(points))
    todo = [p for p in unique if (p.concentration_pct, p.voltage_v) not in done]
    finished = len(unique) - len(todo)

    def keep(p: SweepPoint, result: dict[str, Any]) -> None:
        nonlocal finished
        row = dict(result)
        row.update(asdict(p))
        done[(p.concentration_pct, p.voltage_v)] = row
        if path is not None:
            atomic_write_json(path, {"settings": settings, "rows": list(done.values())})
        finished += 1
        if progress is not None:
            progress(finished, p)

    if jobs == 1 or len(todo) <= 1:
        for p in todo:
            keep(p, sim(p, duration_s))
    else:
        with ProcessPoolExecutor(max_workers=min(jobs, len(todo))) as pool:
            running: dict[Future[dict[str, Any]], SweepPoint] = {
                pool.submit(sim, p, duration_s): p for p in todo
            }
            failed: BaseException | None = None
            while running:
                ready, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in ready:
                    p = running.pop(fut)
                    try:
                        result = fut.result()
                    except Exception as exc:  # keep what the other workers finish
                        failed = failed or exc
                        continue
                    keep(p, result)
            if failed is not None:
                raise failed
    return [done[(p.concentration_pct, p.voltage_v)] for p in points]


def _simulate(point: SweepPoint, duration_s: float) -> dict[str, Any]:
    from microfab.process.inkjet.droplet import DOD_NUMERICS, simulate_droplet
    from microfab.process.inkjet.fluids import naalg
    from microfab.trajectory.waveform import seed003_waveform

    res = simulate_droplet(
        naalg(point.concentration_pct),
        seed003_waveform(point.voltage_v),
        duration_s=duration_s,
        after_breakup_s=20e-6,
        numerics=dataclasses.replace(DOD_NUMERICS, max_steps=SWEEP_MAX_STEPS),
    )
    return res.to_dict()
