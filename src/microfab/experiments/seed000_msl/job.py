"""The ``msl-ilc`` job kind and the ``msl-ilc`` reproduction of seed 000.

Job file (``examples/galvo_msl_default.toml``)::

    [job]
    kind = "msl-ilc"
    out = "report/msl-ilc"

    [scan]
    features_per_s = 400              # laps of the 0.6 mm square per second (seed 000 §4)
    iterations = 30                   # ILC trials; trial 1 is feedback only (u_1 = y_d)
    learning_rates = [100, 200, 400]  # rates whose learning transients are drawn (Fig. 6)

    [ilc]
    cutoff_hz = 8000.0                # highest learned harmonic (seed 000 §4)
    gain = 0.4                        # learning gain rho (seed 000 §4)
    snr_min = 3.0

    [twin]
    seed = 0                          # encoder-noise seed
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microfab.control.ilc import ILCConfig
from microfab.core.provenance import Shows, quantity
from microfab.experiments.kinds import (
    JobKind,
    Progress,
    Reproduction,
    ReproductionResult,
)
from microfab.experiments.seed000_msl import paper
from microfab.experiments.seed000_msl.keys import FS_HZ, ILC_CUTOFF_HZ, ILC_GAIN
from microfab.io.atomic import atomic_write_json
from microfab.io.job import Key
from microfab.machines.galvo import machine as galvo_machine
from microfab.report.provenance import labelled
from microfab.report.tables import Table, versus

if TYPE_CHECKING:  # the learning run is imported when a job runs
    from microfab.machines.galvo.ilc import BeamExposure, MSLRunResult
    from microfab.plants.galvo import GalvoAxis
    from microfab.plants.lti import DiscreteLTI

__all__ = [
    "MSL_ILC",
    "MSL_ILC_REPRODUCTION",
    "MSLConfig",
    "MSLJobResult",
    "comparison_tables",
    "reproduce_tables",
    "tables_from_runs",
]

MAX_ITERATIONS = 1000  # assumed bound: 30 trials take ~4 s per rate; 1000 about 2 minutes

SCHEMA = {
    "scan": (
        Key(
            name="features_per_s",
            alias="rate_hz",
            type="int",
            default=400,
            low=1,
            high=FS_HZ // 8,
            unit="features/s",
            help="laps of the square per second; must divide 1 MHz",
        ),
        Key(name="iterations", type="int", default=30, low=2, high=MAX_ITERATIONS),
        Key(
            name="learning_rates",
            type="int_list",
            default=None,
            low=1,
            high=FS_HZ // 8,
            unit="features/s",
        ),
    ),
    "ilc": (
        ILC_CUTOFF_HZ,  # shared with `ilc step --cutoff-hz`
        ILC_GAIN,  # shared with `ilc step --gain`
        Key(name="snr_min", type="float", default=3.0, low=0.0, high=1e6),
    ),
    "twin": (Key(name="seed", type="int", default=0, low=0, high=2**32 - 1),),
}


@dataclass(frozen=True, kw_only=True)
class MSLConfig:
    """A galvo-MSL ILC job.

    Parameters
    ----------
    features_per_s : int
        Main scan rate, features (laps of the square) per second; divides 1 MHz.
    iterations : int
        ILC trials per rate (trial 1 is feedback only).
    learning_rates : tuple of int
        Rates whose learning transients are run and drawn, features/s.
    ilc : ILCConfig
        Learning settings.
    seed : int
        Twin noise seed.
    """

    features_per_s: int = 400
    iterations: int = 30
    learning_rates: tuple[int, ...] = (400,)
    ilc: ILCConfig = field(default_factory=ILCConfig)
    seed: int = 0

    def __post_init__(self) -> None:
        for r in (self.features_per_s, *self.learning_rates):
            if r <= 0 or FS_HZ % r:
                raise ValueError(
                    f"features_per_s {r} must divide the 1 MHz sample rate (seed 000 §3.1), "
                    "e.g. 100, 200, 250, 400, 500"
                )
        if self.iterations < 2:
            raise ValueError(f"iterations must be >= 2, got {self.iterations}")

    @property
    def rates(self) -> list[int]:
        """Every rate run, features/s, ascending."""
        return sorted(set(self.learning_rates) | {self.features_per_s})


def _make_config(sec: dict[str, dict[str, Any]]) -> MSLConfig:
    scan = sec["scan"]
    rates = scan["learning_rates"] or (scan["features_per_s"],)
    return MSLConfig(
        features_per_s=scan["features_per_s"],
        iterations=scan["iterations"],
        learning_rates=tuple(rates),
        ilc=ILCConfig(**sec["ilc"]),
        seed=sec["twin"]["seed"],
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class MSLJobResult:
    """Runs of one msl-ilc job, by rate, with the numbers of seed Tables 1 and 2."""

    config: MSLConfig
    runs: dict[int, MSLRunResult]
    numbers: dict[str, Any]
    exposure: BeamExposure
    open_loops: dict[str, DiscreteLTI]

    def comparison(self) -> tuple[Table, ...]:
        """Tables 1 and 2 and the margins, ours / seed 000 (`comparison_tables`)."""
        return comparison_tables(self.numbers)

    def failures(self) -> tuple[str, ...]:
        """Nothing: a failing rate stops the job (its learning state is kept)."""
        return ()

    def summary(self) -> dict[str, Any]:
        """Main-rate Table 1 and 2 rows, the loop margins, ours beside the seed's."""
        main = self.runs[self.config.features_per_s]
        r = self.config.features_per_s
        return {
            "features_per_s": r,
            "iterations": self.config.iterations,
            "table1_mV": {a: main.table1_row(a) for a in main.axes},
            "velocity_mm_s": main.velocity_stats(),
            "margins": self.numbers["margins"],
            "seed": {
                "table1_mV": {a: paper.TABLE1_MV[a].get(r) for a in main.axes},
                "velocity_mm_s": paper.TABLE2_MM_S.get(r),
                "margins": paper.MARGINS,
            },
        }


def _run(config: MSLConfig, out: Path, progress: Progress) -> MSLJobResult:
    from microfab.machines.galvo.ilc import beam_exposure, run_msl_ilc

    axes = galvo_machine.calibrated_axes()
    runs = {}
    for r in config.rates:
        label = f"ILC at {r} features/s"
        runs[r] = run_msl_ilc(
            r,
            config.iterations,
            axes=axes,
            config=config.ilc,
            seed=config.seed,
            state_dir=out / "state" / f"rate_{r}",
            progress=lambda done, total, lab=label: progress(lab, done, total),
        )
    result = MSLJobResult(
        config=config,
        runs=runs,
        numbers=tables_from_runs(runs, axes),
        exposure=beam_exposure(runs[config.features_per_s]),
        open_loops={n: galvo_machine.open_loop(a) for n, a in axes.items()},
    )
    atomic_write_json(out / "summary.json", result.summary())
    return result


def _notes(config: MSLConfig) -> list[str]:
    return [
        "Digital twin: galvo x/y with eq. (1) lead-lag feedback at 1 MHz; rigid-body pole, "
        "gain ratio and encoder noise calibrated to seed 000 Table 1 "
        "(microfab/data/galvo_twin.toml, `microfab calibrate galvo`).",
        "Trial 1 is feedback only (u_1 = y_d); ILC learns every harmonic (the mean included) up to "
        f"{config.ilc.cutoff_hz:g} Hz with gain {config.ilc.gain:g}.",
        "Line width: quasi-steady working-curve model with the seed's 30 mW laser "
        "(seed 000 §4.3) and an assumed resin (D_p 100 um, E_c 10 mJ/cm^2) and spot "
        "radius 5 um; the seed gives neither (microfab/process/exposure.py).",
        "Learning state is saved under state/ (at most every 2 s and after the last trial); "
        "re-running resumes.",
    ]


def _write_report(result: MSLJobResult, out: Path, title: str) -> Path:
    from microfab.experiments.seed000_msl.report import write_report

    return write_report(
        out,
        result.runs,
        main_rate=result.config.features_per_s,
        tables=result.numbers,
        exposure=result.exposure,
        open_loops=result.open_loops,
        title=title,
        notes=_notes(result.config),
    )


def comparison_tables(tables: dict[str, Any]) -> tuple[Table, ...]:
    """Tables 1 and 2 and the margins as ``ours / seed`` cells.

    Parameters
    ----------
    tables : dict
        From `tables_from_runs` (rates as strings).
    """
    from microfab.machines.galvo.calibration import table1_quantity

    rates = sorted(int(r) for r in tables["table2"])
    t1_rows = []
    t1_shows = []
    for a in tables["table1"]:
        for c in ("fb", "ilc"):
            t1_shows.append(
                Shows(
                    tuple(table1_quantity(a, f"{c}_{k}", r) for r in rates for k in ("rms", "pp"))
                )
            )
            cells = []
            for r in rates:
                o, s = tables["table1"][a][str(r)], paper.TABLE1_MV[a].get(r, {})
                cells.append(
                    f"{versus(o[c + '_rms'], s.get(c + '_rms'), '{:.2f}'.format)} "
                    f"({versus(o[c + '_pp'], s.get(c + '_pp'), '{:.1f}'.format)})"
                )
            t1_rows.append((a, c.upper(), *cells))
    t2_rows = []
    for c in ("fb", "ilc"):
        cells = []
        for r in rates:
            o, s = tables["table2"][str(r)], paper.TABLE2_MM_S.get(r, {})
            cells.append(
                " ".join(
                    versus(o[f"{c}_{k}"], s.get(f"{c}_{k}"), "{:.0f}".format)
                    for k in ("mean", "std", "min", "max")
                )
            )
        t2_rows.append((c.upper(), *cells))
    t2_shows = [
        Shows(
            tuple(
                quantity("000", "Table 2", c, k, r)
                for r in rates
                for k in ("mean", "std", "min", "max")
            )
        )
        for c in ("fb", "ilc")
    ]
    m_shows = [
        Shows(
            (quantity("000", "§3.1", a, "gain margin"), quantity("000", "§3.1", a, "phase margin"))
        )
        for a in tables["margins"]
    ]
    m_rows = [
        (
            a,
            versus(m["gm_db"], paper.MARGINS.get(a, {}).get("gm_db"), "{:.1f}".format),
            f"{m['gm_freq_hz'] / 1e3:.1f}",
            versus(m["pm_deg"], paper.MARGINS.get(a, {}).get("pm_deg"), "{:.1f}".format),
            f"{m['pm_freq_hz'] / 1e3:.2f}",
        )
        for a, m in tables["margins"].items()
    ]
    heads = [f"{r} features/s" for r in rates]
    return (
        labelled(
            Table(
                title="Table 1: RMS (PP) tracking error [mV], ours / seed 000",
                columns=("axis", "control", *heads),
                rows=t1_rows,
            ),
            t1_shows,
        ),
        labelled(
            Table(
                title="Table 2: beam speed mean std min max [mm/s], ours / seed 000",
                columns=("control", *heads),
                rows=t2_rows,
            ),
            t2_shows,
        ),
        labelled(
            Table(
                title="Feedback-loop margins, ours / seed 000 §3.1",
                columns=("axis", "GM [dB]", "at [kHz]", "PM [deg]", "at [kHz]"),
                rows=m_rows,
                note="The seed's margins were measured on the real scanners; ours are those "
                "of the calibrated twin, whose resonances carry an assumed damping of 0.05.",
            ),
            m_shows,
        ),
    )


def tables_from_runs(
    runs: Mapping[int, MSLRunResult], axes: Mapping[str, GalvoAxis]
) -> dict[str, Any]:
    """Our numbers of seed Tables 1 and 2, the loop margins and the learning curves.

    Parameters
    ----------
    runs : mapping of int to MSLRunResult
        Runs by rate, features/s.
    axes : mapping of str to GalvoAxis
        The axes whose feedback-loop margins are computed (seed 000 §3.1).

    Returns
    -------
    dict
        JSON-ready: ``table1`` (mV), ``table2`` (mm/s), ``margins`` (dB, deg, Hz) and
        ``rms_history`` (mV), rates as string keys.
    """
    from microfab.machines.galvo.ilc import axis_margins

    rates = sorted(runs)
    names = runs[rates[0]].axes
    table1 = {a: {str(r): runs[r].table1_row(a) for r in rates} for a in names}
    table2 = {str(r): runs[r].velocity_stats() for r in rates}
    hist = {
        a: {str(r): (runs[r].rms_history[:, i] * 1e3).tolist() for r in rates}
        for i, a in enumerate(names)
    }
    return {
        "table1": table1,
        "table2": table2,
        "margins": axis_margins(axes),
        "rms_history": hist,
    }


def reproduce_tables(
    rates: tuple[int, ...] = paper.RATES,
    iterations: int = 30,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> tuple[dict[str, Any], dict[int, MSLRunResult]]:
    """Run every rate and collect Tables 1 and 2, margins and learning curves.

    Returns
    -------
    tables : dict
        `tables_from_runs` of the runs (values in mV and mm/s).
    runs : dict of int to MSLRunResult
        The runs by rate.
    """
    from microfab.machines.galvo.ilc import run_msl_ilc

    axes = galvo_machine.calibrated_axes()
    runs: dict[int, MSLRunResult] = {}
    for r in rates:
        if progress is not None:
            progress(f"{r} features/s")
        runs[r] = run_msl_ilc(r, iterations, axes=axes, seed=seed)
    return tables_from_runs(runs, axes), runs


def _reproduce(options: dict[str, Any], progress: Progress) -> ReproductionResult:
    n = len(paper.RATES)
    progress("seed 000 rates", 0, n)
    done = 0

    def step(label: str) -> None:
        nonlocal done
        progress(f"seed 000: {label}", done, n)
        done += 1

    tables, _ = reproduce_tables(
        iterations=options["iterations"], seed=options["seed"], progress=step
    )
    progress("seed 000 rates", n, n)
    return ReproductionResult(tables=comparison_tables(tables), data=tables)


MSL_ILC = JobKind(
    name="msl-ilc",
    schema=SCHEMA,
    make_config=_make_config,
    run=_run,
    write_report=_write_report,
    default_title="Galvo MSL: feedback vs ILC",
    data_files=galvo_machine.DATA_FILES,
)

MSL_ILC_REPRODUCTION = Reproduction(
    name="msl-ilc",
    run=_reproduce,
    options=(
        Key(name="iterations", type="int", default=30, low=2, high=MAX_ITERATIONS),
        Key(name="seed", type="int", default=0, low=0, high=2**32 - 1),
    ),
    data_files=galvo_machine.DATA_FILES,
)
