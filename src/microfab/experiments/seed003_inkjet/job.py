"""The ``droplet-sweep`` job kind and the ``droplet-fig4`` reproduction of seed 003 part 1.

Job file (``examples/droplet_sweep.toml``)::

    [job]
    kind = "droplet-sweep"
    out = "report/droplet-sweep"

    [sweep]
    concentrations_pct = [0.15, 0.2, 0.25, 1.0, 1.5, 2.0]  # at 50 V (seed Fig. 4)
    voltages_v = [40, 45, 50, 55, 60, 65, 70]             # seed Table 1 ([] = none)
    voltage_concentration_pct = 1.0                       # of the voltage series
    duration_us = 400.0
    after_breakup_us = 20.0
    models = "lagrangian,eulerian"                        # jet models to run and compare

    [run]
    workers = 1                  # local worker processes (Dask) side by side
    # scheduler = "tcp://host:8786"   # or a running Dask scheduler

Every finished point is saved under ``OUT/sweep-<model>/`` as it comes back; running the
same job again skips them. The report puts the seed's two quoted breakups (0.15 % and 1 % at
50 V, "Typical droplet formation process") and its Fig. 4 trend (breakup time rises
with concentration) beside ours. What runs is the machine's
(`microfab.machines.printhead.model_sweep`) and the tables are
`microfab.report.inkjet_tables.breakup_tables`; here the job file becomes its settings,
and the report and the reproduction are assembled.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from microfab.experiments.kinds import JobKind, Progress, Reproduction, ReproductionResult
from microfab.experiments.seed003_inkjet.keys import (
    AFTER_BREAKUP,
    CONCENTRATION,
    DURATION,
    VOLTAGE,
    VOLTAGE_CONCENTRATION,
    WORKERS,
)
from microfab.experiments.seed003_inkjet.paper import (
    FIG4_VOLTAGE_V,
    SEED_BREAKUP,
    SEED_CONCENTRATIONS_PCT,
    SEED_VOLTAGES_V,
)
from microfab.io.atomic import atomic_write_json
from microfab.io.job import Key
from microfab.machines.printhead import machine as printhead
from microfab.machines.printhead.machine import (
    DropletSettings,
    SweepPoint,
    model_sweep,
    sweep_points,
)
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL
from microfab.process.inkjet.fluids import load_table
from microfab.report.inkjet_tables import breakup_tables, breakup_trend, row_model
from microfab.report.tables import Table

__all__ = [
    "DROPLET_FIG4_REPRODUCTION",
    "DROPLET_SWEEP",
    "DropletSweepConfig",
    "DropletSweepResult",
]

# fmt: off
# The ranges and the keys the `microfab droplet` options share live in `keys` (light).
_CONCENTRATIONS = dataclasses.replace(CONCENTRATION, name="concentrations_pct",
                                      type="float_list", default=SEED_CONCENTRATIONS_PCT,
                                      help="concentrations of the 50 V series (seed Fig. 4)")
_DURATION = DURATION  # shared with `droplet sweep|render --duration`
_AFTER = AFTER_BREAKUP  # shared with `droplet simulate --after-breakup`
_MODELS = Key(name="models", type="str", default=DEFAULT_JET_MODEL,
              help="jet models, comma-separated: lagrangian, eulerian (each runs every point)")
#: The reproduction shows both models beside the seed by default.
_REPRO_MODELS = dataclasses.replace(_MODELS, default="lagrangian,eulerian")
_WORKERS = WORKERS  # shared with `droplet sweep|sensitivity --jobs`

SCHEMA = {
    "sweep": (
        _CONCENTRATIONS,
        # each voltage as `droplet simulate|render --voltage` and `droplet sweep --voltages`
        dataclasses.replace(VOLTAGE, name="voltages_v", type="float_list",
                            default=SEED_VOLTAGES_V, allow_empty=True,
                            help="voltages of the voltage series (seed Table 1); [] for none"),
        VOLTAGE_CONCENTRATION,  # shared with `droplet sweep --voltage-concentration`
        _DURATION,
        _AFTER,
        _MODELS,
    ),
    "run": (
        _WORKERS,
        Key(name="scheduler", type="str", default=None,
            help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786"),
    ),
}
# fmt: on


@dataclass(frozen=True, kw_only=True)
class DropletSweepConfig:
    """A droplet-sweep job.

    Parameters
    ----------
    concentrations_pct : tuple of float
        Concentrations of the 50 V series, % w/v.
    voltages_v : tuple of float
        Voltages of the voltage series, V (may be empty).
    voltage_concentration_pct : float
        Concentration of the voltage series, % w/v.
    settings : DropletSettings
        Simulated time, time after breakup, step budget (shared by every point); its
        ``model`` is replaced by each of ``models`` in turn.
    models : tuple of str
        Jet models to run (`microfab.process.inkjet.droplet.JET_MODELS`), each on every
        point.
    workers : int
        Local worker processes; 1 runs in this process.
    scheduler : str or None
        Address of a running Dask scheduler (then ``workers`` is not used).
    """

    concentrations_pct: tuple[float, ...] = SEED_CONCENTRATIONS_PCT
    voltages_v: tuple[float, ...] = SEED_VOLTAGES_V
    voltage_concentration_pct: float = 1.0
    settings: DropletSettings = field(default_factory=DropletSettings)
    models: tuple[str, ...] = (DEFAULT_JET_MODEL,)
    workers: int = 1
    scheduler: str | None = None

    def __post_init__(self) -> None:
        from microfab.process.inkjet.droplet import JET_MODELS

        if not self.concentrations_pct and not self.voltages_v:
            raise ValueError("the sweep has no points: give concentrations_pct or voltages_v")
        bad = [m for m in self.models if m not in JET_MODELS]
        if bad or not self.models:
            raise ValueError(
                f"[sweep] models must name one or more of {', '.join(JET_MODELS)}, "
                f"got {', '.join(self.models) or 'none'}"
            )

    @property
    def points(self) -> list[SweepPoint]:
        """The points in run order (`sweep_points`)."""
        return sweep_points(
            self.concentrations_pct,
            self.voltages_v,
            voltage_concentration_pct=self.voltage_concentration_pct,
        )


def _make_config(sec: dict[str, dict[str, Any]]) -> DropletSweepConfig:
    sweep, run = sec["sweep"], sec["run"]
    return DropletSweepConfig(
        concentrations_pct=tuple(sweep["concentrations_pct"]),
        voltages_v=tuple(sweep["voltages_v"]),
        voltage_concentration_pct=sweep["voltage_concentration_pct"],
        settings=DropletSettings(
            duration_s=sweep["duration_us"] / 1e6,
            after_breakup_s=sweep["after_breakup_us"] / 1e6,
        ),
        models=parse_models(sweep["models"]),
        workers=run["workers"],
        scheduler=_scheduler(run["scheduler"]),
    )


def parse_models(text: str) -> tuple[str, ...]:
    """``"lagrangian, eulerian"`` -> ``("lagrangian", "eulerian")`` (duplicates dropped)."""
    return tuple(dict.fromkeys(m.strip() for m in text.split(",") if m.strip()))


@dataclass(frozen=True, kw_only=True, eq=False)
class DropletSweepResult:
    """Rows of a droplet sweep and the points that failed.

    Attributes
    ----------
    config : DropletSweepConfig
        The job.
    rows : tuple of dict
        Finished points in run order (point fields, then the droplet summary).
    failed : tuple of str
        ``"<c> %, <v> V: <error>"`` per failed point.
    """

    config: DropletSweepConfig
    rows: tuple[dict[str, Any], ...]
    failed: tuple[str, ...] = ()

    def comparison(self) -> tuple[Table, ...]:
        """`breakup_tables` of the rows."""
        return breakup_tables(self.rows)

    def failures(self) -> tuple[str, ...]:
        """One line per failed point."""
        return self.failed

    def summary(self) -> dict[str, Any]:
        """Breakups by point, the seed's beside them, the trend, the failures."""
        models = self.config.models
        return {
            "settings": self.config.settings.to_dict(),
            "models": list(models),
            "points": [
                {
                    k: r.get(k)
                    for k in (
                        "jet_model",
                        "concentration_pct",
                        "voltage_v",
                        "breakup_time_s",
                        "breakup_mode",
                        "breakup_z_m",
                        "head_speed_m_s",
                        "satellites",
                        "drop_diameter_m",
                        "head_radius_m",
                        "tail_length_at_breakup_m",
                        "distinct_head",
                        "ligament_thinning_m_s",
                        "solver_stop_reason",
                    )
                }
                for r in self.rows
            ],
            "trend_rises_with_concentration": {
                m: breakup_trend(
                    [r for r in self.rows if row_model(r) == m and r["voltage_v"] == FIG4_VOLTAGE_V]
                )
                for m in models
            },
            "failed": list(self.failed),
            "seed": {
                "breakup_at_50V": {
                    str(c): {"time_s": t, "mode": m} for c, (t, m) in SEED_BREAKUP.items()
                },
                "trend_rises_with_concentration": "yes",
            },
        }


def _sweep(
    config: DropletSweepConfig, out: Path | None, label: str, progress: Progress
) -> tuple[list[dict[str, Any]], list[str]]:
    """`printhead.model_sweep` of the job (``OUT/sweep-<model>/``), progress under ``label``."""
    many = len(config.models) > 1
    return model_sweep(
        config.points,
        config.models,
        settings=config.settings,
        results_dir=out,
        workers=config.workers,
        scheduler=config.scheduler,
        progress=lambda m, done, total: progress(f"{label} ({m})" if many else label, done, total),
    )


def _run(config: DropletSweepConfig, out: Path, progress: Progress) -> DropletSweepResult:
    rows, failed = _sweep(config, out, "droplet sweep", progress)
    result = DropletSweepResult(config=config, rows=tuple(rows), failed=tuple(failed))
    atomic_write_json(out / "summary.json", result.summary())
    return result


def _findings(rows: Sequence[dict[str, Any]], model: str) -> str:
    """What one model says about the seed's two quoted breakups and its trend."""
    parts = []
    for c, (t_seed, mode_seed) in SEED_BREAKUP.items():
        r = next((r for r in rows if r["concentration_pct"] == c
                  and r["voltage_v"] == FIG4_VOLTAGE_V), None)  # fmt: skip
        if r is None:
            continue
        t = r["breakup_time_s"]
        ours = "no breakup" if t is None else f"{r['breakup_mode']} at {t * 1e6:.0f} µs"
        parts.append(f"{c:g} %: {ours} (seed {mode_seed} at {t_seed * 1e6:.0f} µs)")
    at50 = [r for r in rows if r["voltage_v"] == FIG4_VOLTAGE_V]
    parts.append(f"time rises with concentration: {breakup_trend(at50)}")
    return f"{model} model: " + "; ".join(parts) + "."


def _fitted(model: str) -> str:
    """The parameters fitted to the seed for ``model``: its relaxation law."""
    law = load_table().law(model)
    return (
        f"Fitted ({model} model, microfab droplet calibrate --model {model}): the relaxation "
        f"law λ(c) = λ_ref (c / {law.reference_pct:g} %)^m, λ_ref = "
        f"{law.lambda_ref_s * 1e6:.3g} µs, m = {law.exponent:.3g} ({law.status}), to the "
        "seed's 0.15 % and 1 % breakup times at 50 V; every other number is a prediction."
    )


def _notes(result: DropletSweepResult) -> list[str]:
    s = result.config.settings
    notes = [
        "Model: acoustic printhead (calibrated to the seed's drop speed) driving a "
        "one-dimensional slender jet with FENE-P polymer stress, Eulerian (fixed grid, TVD, a "
        "thin film through pinch-offs; the meniscus retracts into the bore and the acoustics "
        "feel its pressure) or Lagrangian (moving nodes, bodies split at each pinch, the "
        "meniscus held at the rim); NaAlg properties from microfab/data/naalg.toml (a source "
        "for every value, all assumed or calibrated; microfab droplet sensitivity shows what "
        "each one does).",
        *(_fitted(m) for m in result.config.models),
        f"Each point simulates {s.duration_s * 1e6:g} µs (then {s.after_breakup_s * 1e6:g} µs "
        "after the first breakup), at most "
        + ", ".join(
            f"{dataclasses.replace(s, model=m).step_budget} solver steps ({m})"
            for m in result.config.models
        )
        + ".",
        *(
            _findings([r for r in result.rows if row_model(r) == m], m)
            for m in result.config.models
        ),
        "Finished points are saved under sweep-<model>/; running the job again resumes.",
    ]
    notes += [f"Failed point: {f}" for f in result.failed]
    return notes


def _write_report(result: DropletSweepResult, out: Path, title: str) -> Path:
    from microfab.report.canvas import render_png
    from microfab.report.inkjet import fig_sweep
    from microfab.report.page import Figure, page_html, write_page

    figures = []
    for m in result.config.models:
        rows = [r for r in result.rows if row_model(r) == m]
        if not rows:
            continue
        single = len(result.config.models) == 1
        figures.append(
            Figure(
                name="breakup_time.png" if single else f"breakup_time_{m}.png",
                png=render_png(fig_sweep(rows, seed_points=SEED_BREAKUP)),
                caption=f"{m.capitalize()} jet model. Redraws seed 003 Fig. 4: first breakup "
                f"time against NaAlg concentration at {FIG4_VOLTAGE_V:g} V (open squares: the "
                "seed's two quoted breakups), and against drive voltage; crosses: no breakup "
                "in the simulated time; labels: breakup mode.",
            )
        )
    text = page_html(
        title,
        intro=f"{len(result.rows)} point(s) simulated"
        + (f", {len(result.failed)} failed" if result.failed else "")
        + ". Seed 003 part 1: drop-on-demand printing of sodium alginate (NaAlg) through a "
        "120 µm MicroFab nozzle with a bipolar waveform.",
        notes=_notes(result),
        figures=figures,
        tables=result.comparison(),
    )
    return write_page(out, text, figures)


def _reproduce(options: dict[str, Any], progress: Progress) -> ReproductionResult:
    config = DropletSweepConfig(
        concentrations_pct=SEED_CONCENTRATIONS_PCT,
        voltages_v=(),
        settings=DropletSettings(duration_s=options["duration_us"] / 1e6),
        models=parse_models(options["models"]),
        workers=options["workers"],
    )
    rows, failed = _sweep(config, None, "seed 003 Fig. 4", progress)
    return ReproductionResult(
        tables=breakup_tables(rows),
        notes=(*(_fitted(m) for m in config.models), *(f"failed: {f}" for f in failed)),
        data={"rows": rows, "failed": failed},
    )


DROPLET_SWEEP = JobKind(
    name="droplet-sweep",
    schema=SCHEMA,
    make_config=_make_config,
    run=_run,
    write_report=_write_report,
    default_title="Inkjet: breakup time over concentration and voltage",
    data_files=printhead.DATA_FILES,
)


def _fig4_preflight(options: dict[str, Any]) -> None:
    """Refuse unknown jet models before a run (``--check`` too).

    make fuzz found ``--set models=/`` called valid by ``reproduce droplet-fig4 --check``.
    """
    from microfab.process.inkjet.droplet import JET_MODELS

    models = parse_models(options["models"])
    bad = [m for m in models if m not in JET_MODELS]
    if bad or not models:
        raise ValueError(
            f"reproduce droplet-fig4: --set models must name one or more of "
            f"{', '.join(JET_MODELS)}, comma-separated; got {options['models']!r}"
        )


DROPLET_FIG4_REPRODUCTION = Reproduction(
    name="droplet-fig4",
    run=_reproduce,
    options=(_DURATION, _REPRO_MODELS, _WORKERS),
    data_files=printhead.DATA_FILES,
    preflight=_fig4_preflight,
)


def _scheduler(address: str | None) -> str | None:
    """A job's scheduler address, checked when the job is read (``run --check`` too)."""
    from microfab.io.sweep import check_scheduler_address

    return None if address is None else check_scheduler_address(address)
