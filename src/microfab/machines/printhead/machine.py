"""The piezo drop-on-demand printhead of seed 003 part 1 as a machine: a drive in, a droplet out.

The machine is a MicroFab 120 µm squeeze-tube dispenser jetting sodium alginate (NaAlg)
(seed 003 part 1, ``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al.). Its twin is
the acoustic printhead (`microfab.plants.printhead.Printhead`) with the gain calibrated
to the seed's drive and water (`microfab.process.inkjet.dispenser.default_printhead`),
built once per process (`twin`, a `microfab.machines.twins.TwinCache`); the inks are the
NaAlg property table ``naalg.toml`` (`microfab.process.inkjet.fluids.naalg`).

`play` is the machine: a drive (a waveform, or a voltage for the seed's bipolar waveform
of Table 1) and a fluid in, what the camera would film out: the droplet simulation
(`microfab.process.inkjet.droplet.simulate_droplet`), with its frames (silhouettes) and
its first breakup (time, position, mode). `run_point` is the one path from a
(concentration, voltage) point to a droplet: the Fig. 4 sweep (`droplet_sweep`, on the
project's runner `microfab.io.sweep.run_sweep`), the ``droplet-sweep`` job, the
calibration, the sensitivity study and ``microfab droplet simulate|render|sweep`` all run
it, so one point gives one answer whichever command runs it.

A sweep saves every finished point at once (atomically) in its results directory; one
started again with the same directory and settings skips the points already there, so an
interrupted sweep loses at most the points in progress. `model_sweep` runs the points
once per jet model (the ``droplet-sweep`` job and the ``droplet-fig4`` reproduction),
each model's points saved apart.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microfab.core.validate import check_positive
from microfab.io.sweep import SweepResult, run_sweep
from microfab.machines.twins import TwinCache
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL
from microfab.process.inkjet.fluids import SEED_CONCENTRATIONS_PCT
from microfab.trajectory.waveform import SEED003_VOLTAGES_V

if TYPE_CHECKING:
    from distributed import Client

    from microfab.plants.printhead import Printhead
    from microfab.process.inkjet.droplet import DropletResult
    from microfab.process.inkjet.fluids import Fluid
    from microfab.trajectory.waveform import Waveform

__all__ = [
    "DATA_FILES",
    "EULER_SWEEP_MAX_STEPS",
    "FIG4_VOLTAGE_V",
    "SWEEP_MAX_STEPS",
    "DropletSettings",
    "PrintheadLimits",
    "SweepPoint",
    "droplet_sweep",
    "limits",
    "model_sweep",
    "play",
    "run_point",
    "simulate_point",
    "sweep_points",
    "twin",
]

#: The packaged data file the machine reads: the NaAlg property table (every value with
#: its source). The printhead itself reads none: its geometry is `Printhead`'s defaults
#: and its gain is calibrated from the seed's drive (`default_printhead`).
DATA_FILES = ("naalg.toml",)

#: Voltage of the concentration series, V.
FIG4_VOLTAGE_V = 50.0  # seed 003 part 1, Fig. 4

#: Step budget per sweep point, a safeguard: the seed's points take 1 200 to 11 600 steps
#: each (1 % at 65 V the most). Before a cut removed the thin thread beside the neck
#: (`microfab.process.inkjet.jet.Numerics.cut_radius_factor`), the 1 % run at 45 V
#: ground on for more than 10 minutes; a point that runs out ends with its
#: ``solver_stop_reason`` in the row instead of holding up the sweep.
SWEEP_MAX_STEPS = 60_000
#: The same safeguard for the Eulerian model, whose explicit steps are many and cheap: the
#: 1 % NaAlg run to breakup + 20 µs takes about 16 000 steps and 1.3 s; 400 000 steps are
#: about 30 s.
EULER_SWEEP_MAX_STEPS = 400_000


def _build(_: None) -> Printhead:
    from microfab.process.inkjet.dispenser import default_printhead

    return default_printhead()


# Keyed, like every twin, on the machine's data file: a rewritten naalg.toml (a
# calibration) builds the same head again (about 25 ms).
_TWINS: TwinCache[None, Printhead] = TwinCache(lambda path: None, _build, DATA_FILES[0])


def twin() -> Printhead:
    """The calibrated printhead (`default_printhead`), built once and shared.

    Returns
    -------
    microfab.plants.printhead.Printhead
        Immutable: every run of a process plays on the same object.
    """
    return _TWINS()


@dataclass(frozen=True)
class PrintheadLimits:
    """What the printhead model is calibrated for.

    Attributes
    ----------
    voltage_v : (float, float)
        Lowest and highest drive amplitude, V.
    """

    voltage_v: tuple[float, float]


def limits() -> PrintheadLimits:
    """The drive amplitudes the model is calibrated for: 40 to 70 V (seed 003 Table 1)."""
    return PrintheadLimits(voltage_v=(min(SEED003_VOLTAGES_V), max(SEED003_VOLTAGES_V)))


@dataclass(frozen=True)
class SweepPoint:
    """One simulation of a sweep: NaAlg concentration (% w/v) and drive amplitude (V)."""

    concentration_pct: float
    voltage_v: float


@dataclass(frozen=True, kw_only=True)
class DropletSettings:
    """What every run of a study shares; a saved sweep is resumed only with the same.

    Parameters
    ----------
    duration_s : float
        Simulated time per point, s.
    after_breakup_s : float
        How long the bodies are followed after the first breakup, s.
    max_steps : int or None
        Solver step budget per point; None: the model's (`SWEEP_MAX_STEPS`,
        `EULER_SWEEP_MAX_STEPS`).
    model : {"lagrangian", "eulerian"}
        The jet model (:func:`microfab.process.inkjet.droplet.simulate_droplet`).
    """

    duration_s: float = 400e-6
    after_breakup_s: float = 20e-6
    max_steps: int | None = None
    model: str = DEFAULT_JET_MODEL

    def __post_init__(self) -> None:
        from microfab.process.inkjet.droplet import JET_MODELS

        if self.model not in JET_MODELS:
            raise ValueError(f"model must be one of {JET_MODELS}, got {self.model!r}")
        check_positive("duration_s", self.duration_s, "s")
        check_positive("after_breakup_s", self.after_breakup_s, "s")
        if self.max_steps is not None and (isinstance(self.max_steps, bool) or self.max_steps < 1):
            raise ValueError(f"max_steps must be a positive integer, got {self.max_steps}")

    @property
    def step_budget(self) -> int:
        """``max_steps``, or the model's default budget."""
        if self.max_steps is not None:
            return int(self.max_steps)
        return SWEEP_MAX_STEPS if self.model == "lagrangian" else EULER_SWEEP_MAX_STEPS

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready settings (what `run_sweep` checks on resume)."""
        return dataclasses.asdict(self)


def _numerics(settings: DropletSettings) -> Any:
    """The chosen model's drop-on-demand settings with the settings' step budget."""
    from microfab.process.inkjet.droplet import DOD_NUMERICS, EULER_DOD_NUMERICS

    base = DOD_NUMERICS if settings.model == "lagrangian" else EULER_DOD_NUMERICS
    return dataclasses.replace(base, max_steps=settings.step_budget)


def play(
    drive: Waveform | float,
    fluid: Fluid,
    settings: DropletSettings | None = None,
    *,
    frame_interval_s: float = 10e-6,
    progress: Callable[[float], None] | None = None,
    back_pressure_pa: float | None = None,
) -> DropletResult:
    """Drive the printhead (`twin`) with ``drive`` and ``fluid``: the droplet it ejects.

    Parameters
    ----------
    drive : Waveform or float
        Drive voltage against time, or an amplitude in V for the seed's bipolar waveform
        (`microfab.trajectory.waveform.seed003_waveform`, seed 003 part 1, Table 1). Not
        checked against `limits`: the job and the commands that take a voltage do that.
    fluid : Fluid
        The ink (e.g. `microfab.process.inkjet.fluids.naalg`).
    settings : DropletSettings, optional
        Simulated time, time after the first breakup, step budget and jet model.
    frame_interval_s : float, optional
        Spacing of the stored silhouettes, s. The Lagrangian model does not cut its steps
        to them; the Eulerian one lands its steps on them, which does not move its
        breakup: at 50 V the 0.15 % jet broke at 88.216-88.220 µs, 89.94-90.00 µm inside
        the bore, with 1 to 10 µs frames or none (measured with the ink law before the
        calibration core's; the default is 10 µs).
    progress : callable, optional
        Called with the simulated time in s.
    back_pressure_pa : float, optional
        Static back pressure of the reservoir, Pa (the seed's pneumatic controller; the
        Eulerian model only). None: the packaged table's ``[jetting]`` value for the
        Eulerian model, 0 for the Lagrangian one (its meniscus is held at the rim).

    Returns
    -------
    microfab.process.inkjet.droplet.DropletResult
        What the machine measures: the silhouettes (frames every ``frame_interval_s``),
        the first breakup (time, position, mode), satellites, head speed, drop volume.
    """
    from microfab.process.inkjet.droplet import simulate_droplet
    from microfab.trajectory.waveform import seed003_waveform

    settings = settings or DropletSettings()
    if back_pressure_pa is None:
        eulerian = settings.model == "eulerian"
        back_pressure_pa = _packaged_back_pressure_pa() if eulerian else 0.0
    waveform = seed003_waveform(drive) if isinstance(drive, int | float) else drive
    return simulate_droplet(
        fluid,
        waveform,
        printhead=twin(),
        duration_s=settings.duration_s,
        after_breakup_s=settings.after_breakup_s,
        frame_interval_s=frame_interval_s,
        numerics=_numerics(settings),
        model=settings.model,  # type: ignore[arg-type]
        progress=progress,
        back_pressure_pa=back_pressure_pa,
    )


@functools.cache
def _packaged_back_pressure_pa() -> float:
    """The packaged table's ``[jetting] back_pressure_pa``, Pa (read once)."""
    from microfab.process.inkjet.fluids import load_table

    return load_table().back_pressure_pa


def run_point(
    point: SweepPoint,
    settings: DropletSettings | None = None,
    *,
    fluid: Fluid | None = None,
    frame_interval_s: float = 10e-6,
    progress: Callable[[float], None] | None = None,
    back_pressure_pa: float | None = None,
) -> DropletResult:
    """Simulate one point with the seed's bipolar waveform (Table 1): `play` it.

    The one path from a (concentration, voltage) point to a droplet: the sweep, the job and
    ``microfab droplet simulate`` all run it, so one point gives one answer whichever
    command runs it (and a shorter run is the prefix of a longer one,
    `microfab.process.inkjet.droplet.FLOW_RECORD_S`).

    Parameters
    ----------
    point : SweepPoint
        Concentration (% w/v) and drive amplitude (V).
    settings : DropletSettings, optional
        Simulated time, time after the first breakup, step budget (defaults: the sweep's).
    fluid : Fluid, optional
        The ink, if not the table's NaAlg at the point's concentration with the relaxation
        law calibrated for the chosen jet model (a sensitivity run).
    frame_interval_s : float, optional
        Spacing of the stored silhouettes, s (`play`).
    progress : callable, optional
        Called with the simulated time in s.
    back_pressure_pa : float, optional
        Static back pressure of the reservoir, Pa (`play`; None: the table's).

    Returns
    -------
    microfab.process.inkjet.droplet.DropletResult
    """
    from microfab.process.inkjet.fluids import naalg

    settings = settings or DropletSettings()
    return play(
        point.voltage_v,
        fluid if fluid is not None else naalg(point.concentration_pct, model=settings.model),
        settings,
        frame_interval_s=frame_interval_s,
        progress=progress,
        back_pressure_pa=back_pressure_pa,
    )


def simulate_point(point: SweepPoint, settings: DropletSettings) -> dict[str, Any]:
    """Simulate one point (:func:`run_point`); the summary row.

    Returns
    -------
    dict
        :meth:`microfab.process.inkjet.droplet.DropletResult.to_dict`.
    """
    return run_point(point, settings).to_dict()


def sweep_points(
    concentrations_pct: Sequence[float] = SEED_CONCENTRATIONS_PCT,
    voltages_v: Sequence[float] = SEED003_VOLTAGES_V,
    *,
    voltage_concentration_pct: float = 1.0,
) -> list[SweepPoint]:
    """The concentration series at 50 V (Fig. 4), then the voltage series at one concentration.

    Parameters
    ----------
    concentrations_pct : sequence of float
        Concentrations of the 50 V series, % w/v (default: the seed's six, "Materials").
    voltages_v : sequence of float
        Voltages of the voltage series, V (may be empty; default: Table 1's 40-70 V).
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


def droplet_sweep(
    points: Sequence[SweepPoint],
    *,
    settings: DropletSettings | None = None,
    results_dir: str | Path | None = None,
    simulate: Callable[[SweepPoint, DropletSettings], Mapping[str, Any]] = simulate_point,
    progress: Callable[[int, int, SweepPoint, bool], None] | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    client: Client | None = None,
    raise_on_failure: bool = True,
) -> SweepResult[SweepPoint]:
    """Simulate every point, saving each as it finishes and resuming from ``results_dir``.

    Parameters
    ----------
    points : sequence of SweepPoint
        What to run (:func:`sweep_points`); duplicates run once.
    settings : DropletSettings, optional
        Shared by every point; default ``DropletSettings()``.
    results_dir : str or Path, optional
        Folder of the saved points (:mod:`microfab.io.sweep`); a rerun with the
        same settings skips the points found there, one with other settings is refused.
    simulate : callable, optional
        ``(point, settings) -> summary dict``; default :func:`simulate_point`. Off the
        in-process path it must be picklable (a module-level function).
    progress : callable, optional
        ``progress(done, total, point, ok)`` as each point that runs completes.
    workers : int, optional
        Worker processes of a local Dask cluster; ``1`` runs in this process.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``) to run on instead.
    client : distributed.Client, optional
        A Dask client to run on (left open).
    raise_on_failure : bool, optional
        Raise `microfab.io.sweep.SweepError` if a point failed (default), or
        return the failures in the result.

    Returns
    -------
    SweepResult
        Rows (point fields, then the summary) of the finished points in point order.

    Raises
    ------
    ValueError
        ``workers < 1``, or ``results_dir`` holds a sweep with other settings.
    microfab.io.sweep.SweepError
        A point failed (the others are saved; a rerun retries it).
    """
    settings = settings or DropletSettings()
    return run_sweep(
        functools.partial(simulate, settings=settings),
        points,
        results_dir=results_dir,
        settings=settings.to_dict(),
        workers=workers,
        scheduler=scheduler,
        client=client,
        progress=progress,
        raise_on_failure=raise_on_failure,
    )


def model_sweep(
    points: Sequence[SweepPoint],
    models: Sequence[str],
    *,
    settings: DropletSettings | None = None,
    results_dir: str | Path | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> tuple[list[dict[str, Any]], list[str]]:
    """`droplet_sweep` of every point once per jet model; failed points do not stop it.

    Parameters
    ----------
    points : sequence of SweepPoint
        What to run (`sweep_points`).
    models : sequence of str
        Jet models (`microfab.process.inkjet.droplet.JET_MODELS`), run in this order.
    settings : DropletSettings, optional
        Shared by every point; its ``model`` is replaced by each of ``models``.
    results_dir : str or Path, optional
        Each model's points are saved (and resumed) under ``results_dir/sweep-<model>``.
    workers, scheduler
        As `droplet_sweep`.
    progress : callable, optional
        ``progress(model, done, total)``: once with ``done = 0`` before each model, then
        as each of its points completes.

    Returns
    -------
    rows : list of dict
        The finished points' rows, ``jet_model`` added, model by model in point order.
    failed : list of str
        ``"<c> %, <v> V: <error>"`` per failed point, prefixed ``"<model>: "`` when more
        than one model runs.
    """
    settings = settings or DropletSettings()
    rows: list[dict[str, Any]] = []
    failed: list[str] = []
    for model in models:
        if progress is not None:
            progress(model, 0, len(points))
        res = droplet_sweep(
            points,
            settings=dataclasses.replace(settings, model=model),
            results_dir=None if results_dir is None else Path(results_dir) / f"sweep-{model}",
            workers=workers,
            scheduler=scheduler,
            progress=None
            if progress is None
            else lambda done, total, p, ok, model=model: progress(model, done, total),
            raise_on_failure=False,
        )
        rows += [{**r, "jet_model": model} for r in res.rows]
        prefix = f"{model}: " if len(models) > 1 else ""
        failed += [
            f"{prefix}{f.point.concentration_pct:g} %, {f.point.voltage_v:g} V: {f.error}"
            for f in res.failed
        ]
    return rows, failed
