"""The ``slm-shaping`` job kind and the ``slm-shaper`` reproduction (seed 003 part 2).

Job file (``examples/slm_shaping.toml``)::

    [job]
    kind = "slm-shaping"
    out = "report/slm"

    [identify]   # the chirp (seed §1: 10 Hz-2 kHz, 100 bit, 1 s) and the model orders
    [shaper]     # the inverse shaper (seed §2: 4 poles at 4 kHz), ZOH or ZPETC, comparison
    [layer]      # source = "lattice:z=...,radius=..." or a drawing; hatch
    [scan]       # RTC speeds, delays (seed §4: 750 µs jump delay), settling band
    [build]      # layers > 0: a whole build, layer by layer on Dask, resumable
    [twin]       # seed, noise, mirror mode

Every key, its unit and its range is in `SCHEMA`; unknown keys are refused. The run
writes ``summary.json``, the fitted ``model.json`` and ``shaper.json`` (for ``microfab
slm scan-time --shaper``) atomically; the build saves each layer under ``OUT/build/`` and
skips finished layers when the job runs again.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from microfab.experiments.kinds import JobKind, Progress, Reproduction, ReproductionResult
from microfab.experiments.seed003_slm import keys
from microfab.experiments.seed003_slm.results import ShapingJob, ShapingResult
from microfab.experiments.seed003_slm.tables import NOTES, scan_table, seed_table
from microfab.identify.chirp import SWEEPS, ChirpDesign
from microfab.io.atomic import atomic_write_json
from microfab.io.job import Key
from microfab.machines.slm_galvo import machine as slm_galvo
from microfab.machines.slm_galvo.shapers import (
    CompareSettings,
    ShaperComparison,
    compare_shapers,
)
from microfab.machines.slm_galvo.shaping import (
    DISCRETIZATIONS,
    IdentifySettings,
    LayerSettings,
    ShaperSettings,
    ShapingSettings,
    TwinSettings,
    design_shapers,
    run_shaping,
)
from microfab.process.slm.build import BuildSettings, run_build
from microfab.process.slm.estimate import SettleTolerance
from microfab.process.slm.timing import TICK_S, RTCDelays, RTCSettings, ScanSpeeds

__all__ = [
    "SCHEMA",
    "SLM_SHAPER_REPRODUCTION",
    "SLM_SHAPING",
    "ShapingJob",
    "ShapingResult",
    "config_from_sections",
]

_F = "float"
SCHEMA: dict[str, tuple[Key, ...]] = {
    "identify": (
        Key(name="f0_hz", type=_F, default=10.0, low=0.0, unit="Hz",
            help="chirp start (seed 003 part 2 §1: 10 Hz)"),
        Key(name="f1_hz", type=_F, default=2000.0, low=0.0, unit="Hz",
            help="chirp stop (seed §1: 2 kHz)"),
        Key(name="amplitude_bit", type=_F, default=100.0, low=0.0, unit="bit",
            help="chirp amplitude (seed §1: 100 bit)"),
        Key(name="period_s", type=_F, default=1.0, low=0.0, unit="s",
            help="one sweep (seed §1: 1 s)"),
        Key(name="periods", type="int", default=4, low=1, high=100,
            help="sweeps played (assumed 4)"),
        Key(name="dropped", type="int", default=1, low=0, high=99,
            help="leading sweeps left out (assumed 1)"),
        Key(name="sweep", type="str", default="linear", choices=SWEEPS,
            help="linear or log (assumed linear)"),
        Key(name="poles", type="int", default=3, low=1, high=8, help="model poles (seed: 3)"),
        Key(name="zeros", type="int", default=0, low=0, high=8, help="model zeros (seed: 0)"),
        Key(name="band_hz", type="float_list", default=(), low=0.0, unit="Hz",
            allow_empty=True, help="[low, high] band fitted (empty: the chirp's)"),
    ),
    "shaper": (
        Key(name="discretization", type="str", default="zpetc", choices=DISCRETIZATIONS,
            help=f"filter used for the jump and the layer: {' or '.join(DISCRETIZATIONS)}"),
        keys.POLE_HZ,
        keys.SHAPER_ORDER,
        Key(name="compare", type="bool", default=True,
            help="side-by-side inverse and classic shapers on both twins"),
    ),
    "layer": (
        Key(name="source", type="str", default="lattice:z=8.2e-4,radius=8e-3", path=True,
            help="lattice:z=...,radius=...,strut=...,fraction=... or a drawing file/shape"),
        keys.HATCH_SPACING,
        keys.HATCH_ANGLE,
    ),
    "scan": (
        keys.MARK_SPEED,
        keys.JUMP_SPEED,
        keys.JUMP_DELAY,
        keys.MARK_DELAY,
        keys.POLYGON_DELAY,
        keys.LASER_ON_DELAY,
        keys.LASER_OFF_DELAY,
        Key(name="settle_band", type=_F, default=0.02, low=0.0, high=0.5,
            help="derived delays: error within this fraction of the jump (assumed 2 %)"),
        Key(name="jump_mm", type=_F, default=None, low=0.0, unit="mm",
            help="validation jump (default one lattice cell, 1.64 mm)"),
    ),
    "build": (
        Key(name="layers", type="int", default=0, low=0, high=keys.MAX_LAYERS,
            help="lattice layers of a whole build (0: no build)"),
        keys.LAYER_THICKNESS,
        keys.HATCH_ROTATION,
        keys.OUTLINE_RADIUS,
        keys.WORKERS,
        Key(name="scheduler", type="str", default=None,
            help="address of a running Dask scheduler (default: a local cluster)"),
    ),
    "twin": (
        keys.TWIN_SEED,
        Key(name="noise", type="bool", default=True, help="0.3 bit measurement noise on"),
        Key(name="mirror_mode", type="bool", default=False,
            help="add the mirror mode (assumed 3 kHz, ζ 0.02) to the truth"),
    ),
}  # fmt: skip


def config_from_sections(sec: dict[str, dict[str, Any]]) -> ShapingJob:
    """A `ShapingJob` from checked job-file sections (`SCHEMA`).

    Raises
    ------
    ValueError
        A value the settings refuse: a chirp band above Nyquist, a period that is no whole
        number of 10 µs ticks, delays that are not (naming the nearest), a band that is not
        two increasing frequencies, shaper poles at or above Nyquist, an unknown source.
    """
    i, sh, la, sc, bu, tw = (
        sec[k] for k in ("identify", "shaper", "layer", "scan", "build", "twin")
    )
    band = tuple(i["band_hz"])
    if band and (len(band) != 2 or not band[0] < band[1]):
        raise ValueError(f"[identify] band_hz must be [low, high] with low < high, got {band}")
    chirp = ChirpDesign(
        f0_hz=i["f0_hz"],
        f1_hz=i["f1_hz"],
        amplitude=i["amplitude_bit"],
        period_s=i["period_s"],
        n_periods=i["periods"],
        n_dropped=i["dropped"],
        sweep=i["sweep"],
    )
    identify = IdentifySettings(
        chirp=chirp,
        n_poles=i["poles"],
        n_zeros=i["zeros"],
        band_hz=band or None,  # type: ignore[arg-type]
    )
    shaper = ShaperSettings(
        discretization=sh["discretization"], pole_hz=sh["pole_hz"], order=sh["order"]
    )
    layer = LayerSettings(
        source=la["source"],
        hatch_spacing_m=la["hatch_spacing_um"] * 1e-6,
        hatch_angle_deg=la["hatch_angle_deg"],
    )
    rtc = RTCSettings(
        speeds=ScanSpeeds(mark_m_s=sc["mark_speed_m_s"], jump_m_s=sc["jump_speed_m_s"]),
        delays=RTCDelays(
            jump_s=sc["jump_delay_us"] * 1e-6,
            mark_s=sc["mark_delay_us"] * 1e-6,
            polygon_s=sc["polygon_delay_us"] * 1e-6,
            laser_on_s=sc["laser_on_delay_us"] * 1e-6,
            laser_off_s=sc["laser_off_delay_us"] * 1e-6,
        ),
    )
    twin = TwinSettings(seed=tw["seed"], noise=tw["noise"], mirror_mode=tw["mirror_mode"])
    extra: dict[str, Any] = {}
    if sc["jump_mm"] is not None:
        if not sc["jump_mm"] > 0:
            raise ValueError(f"[scan] jump_mm must be positive, got {sc['jump_mm']:g} mm")
        extra["jump_m"] = sc["jump_mm"] * 1e-3
    run = ShapingSettings(
        twin=twin,
        identify=identify,
        shaper=shaper,
        layer=layer,
        rtc=rtc,
        tolerance=SettleTolerance(relative=sc["settle_band"]),
        **extra,
    )
    build = None
    if bu["layers"] > 0:
        build = BuildSettings(
            n_layers=bu["layers"],
            layer_m=bu["layer_um"] * 1e-6,
            outline_radius_m=bu["outline_radius_mm"] * 1e-3,
            hatch_spacing_m=layer.hatch_spacing_m,
            hatch_angle_deg_per_layer=bu["hatch_rotation_deg"],
            mark_speed_m_s=rtc.speeds.mark_m_s,
            jump_speed_m_s=rtc.speeds.jump_m_s,
            shaper=shaper.discretization,
            mirror_mode=twin.mirror_mode,
        )
    return ShapingJob(
        run=run,
        compare=sh["compare"],
        build=build,
        workers=bu["workers"],
        scheduler=_scheduler(bu["scheduler"]),
    )


def _checked_config(sec: dict[str, dict[str, Any]]) -> ShapingJob:
    """`config_from_sections`, then the checks that need the twin.

    The layer's source is read, and the shaper is designed on the twin's own model
    (refusing poles not faster than it).
    """
    cfg = config_from_sections(sec)
    tf = cfg.run.twin.twin().transfer_function()
    design_shapers((tuple(tf.num[0][0]), tuple(tf.den[0][0])), cfg.run.shaper)
    if abs(cfg.run.identify.chirp.dt - TICK_S) > 1e-12:  # pragma: no cover - fixed by schema
        raise ValueError("the chirp must run on the 10 µs tick")
    cfg.run.layer.program()  # refuses an unknown source or an open contour
    return cfg


# ---------------------------------------------------------------------------- result


def _run(config: ShapingJob, out: Path, progress: Progress) -> ShapingResult:
    from microfab.control.shaper_io import shaper_to_dict

    run = run_shaping(config.run, progress)
    atomic_write_json(out / "model.json", run.identification.fit.to_dict())
    atomic_write_json(out / "shaper.json", shaper_to_dict(run.shaper))
    comparisons: list[ShaperComparison] = []
    errors: list[str] = []
    if config.compare:
        settings = CompareSettings(inverse=config.run.shaper.discretization)
        for name in ("seed", "mirror"):
            progress(f"shaper comparison, {name} twin", 0, None)
            try:
                comparisons.append(compare_shapers(name, settings, seed=config.run.twin.seed))
            except ValueError as exc:  # a refused design is reported, the rest goes on
                errors.append(f"shaper comparison on the {name} twin: {exc}")
    build = None
    if config.build is not None:
        build = run_build(
            config.build,
            out / "build",
            workers=config.workers,
            scheduler=config.scheduler,
            progress=lambda done, total: progress("whole build", done, total),
            twin=slm_galvo.twin,
        )
    result = ShapingResult(
        config=config,
        run=run,
        comparisons=tuple(comparisons),
        build=build,
        errors=tuple(errors),
    )
    atomic_write_json(out / "summary.json", result.summary())
    return result


def _write_report(result: ShapingResult, out: Path, title: str) -> Path:
    from microfab.experiments.seed003_slm.report import write_report

    return write_report(result, out, title)


# ---------------------------------------------------------------------------- reproduction
def _reproduce(options: dict[str, Any], progress: Progress) -> ReproductionResult:
    run = run_shaping(
        ShapingSettings(twin=TwinSettings(seed=options["seed"], noise=options["noise"])),
        progress,
    )
    return ReproductionResult(
        tables=(seed_table(run), scan_table(run)), notes=NOTES, data=run.summary()
    )


SLM_SHAPING = JobKind(
    name="slm-shaping",
    schema=SCHEMA,
    make_config=_checked_config,
    run=_run,
    write_report=_write_report,
    default_title="SLM galvo scanner: identification, input shaping and scan time",
    data_files=slm_galvo.DATA_FILES,
)

SLM_SHAPER_REPRODUCTION = Reproduction(
    name="slm-shaper",
    run=_reproduce,
    options=(
        Key(name="seed", type="int", default=0, low=0, help="noise seed"),
        Key(name="noise", type="bool", default=True, help="0.3 bit output noise on"),
    ),
    data_files=slm_galvo.DATA_FILES,
)


def _scheduler(address: str | None) -> str | None:
    """A job's scheduler address, checked when the job is read (``run --check`` too)."""
    from microfab.io.sweep import check_scheduler_address

    return None if address is None else check_scheduler_address(address)
