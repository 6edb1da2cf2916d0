"""A whole SLM build estimated layer by layer on Dask (seed 003 part 2 §4, issue 16 §4).

The seed times a whole lattice "Stanford Bunny", 4686 s without its input shaper and 4219 s
with it (§4). No bunny mesh is shipped, so the build here is a stack of the lattice layers
of `microfab.process.slm.lattice` (simple cubic, strut 250 µm, 5 % volume fraction) in the
disc of the ``slm-shaping`` reproduction's lattice layer, each layer's section at its own
height and its hatch turned by a fixed angle per layer (`BuildSettings`).

Each layer is one point (`BuildLayer`) of `microfab.io.sweep.run_sweep`: in this
process (``workers=1``), on a local Dask cluster of ``workers`` processes, or on a running
cluster (``scheduler``); each layer's row is saved as it finishes under ``results_dir`` and
a rerun skips the finished layers (`run_build`). Per layer (`layer_task`), on the SLM galvo
twin (`microfab.plants.galvo_slm`):

* ``naive``: ``Σ L / v`` (PySLM-like);
* ``fixed``: the RTC timing with fixed delays, the seed's 750 µs jump delay (§4);
* ``dynamics``: dynamics-aware, each jump waiting its own shortest delay on the twin;
* ``shaped_fixed``: fixed delays, with the jump delay derived for the shaped axis (one
  lattice cell at the jump speed, 2 % band: the seed's procedure, 750 -> 250 µs);
* ``shaped``: dynamics-aware on the shaped axis (the input shaper in front of the twin).

The shaper is designed once in `run_build` from the twin's model (the seed's ``G``; with
``mirror_mode`` the twin has a mode the shaper does not know), and its discrete filter
travels to the workers as coefficients with the settings; the derived jump delays are
computed once there too. Workers are spawned processes: `layer_task` rebuilds the twin
and the shaped axis from the settings alone (cached per process).

**The twin.** ``run_build(..., twin=factory)`` takes the twin as a factory
``factory(mirror_mode=bool) -> GalvoSLMPlant``: ``microfab.machines.slm_galvo.twin`` (the
cached machine twin; what ``microfab slm build`` and the ``slm-shaping`` job pass) or, by
default, `microfab.plants.galvo_slm.galvo_slm_twin` (the same packaged data file, built
here). The factory must be a module-level function: it travels to the workers by name.
The report of a build (its table) is `microfab.report.slm_tables.build_table`.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from microfab.control.shaping import InverseShaperConfig, design_inverse_shaper
from microfab.core.validate import check_finite, check_int, check_positive
from microfab.io.sweep import run_sweep
from microfab.plants.galvo_slm import GalvoSLMPlant, galvo_slm_twin
from microfab.plants.lti import DiscreteLTI
from microfab.process.slm.estimate import (
    SEED_JUMP_DELAY_UNSHAPED_S,
    SEED_TOTAL_SHAPED_S,
    SEED_TOTAL_UNSHAPED_S,
    ScanTimeEstimate,
    SettleTolerance,
    dynamics_estimate,
    fixed_delay_estimate,
    jump_delay,
    naive_estimate,
    series,
)
from microfab.process.slm.lattice import LatticeSpec, lattice_layer
from microfab.process.slm.source import MAX_HEIGHT_M
from microfab.process.slm.timing import CATEGORIES, TICK_S, RTCSettings, ScanSpeeds

__all__ = [
    "ESTIMATES",
    "LABELS",
    "BuildLayer",
    "BuildResult",
    "BuildSettings",
    "TwinFactory",
    "build_layers",
    "layer_task",
    "run_build",
]

#: The per-layer estimates (module doc), in report order.
ESTIMATES = ("naive", "fixed", "dynamics", "shaped_fixed", "shaped")
#: How a table names each estimate.
LABELS = {
    "naive": "naive Σ L/v",
    "fixed": "fixed delays (seed's jump delay)",
    "dynamics": "dynamics-aware",
    "shaped_fixed": "shaped, fixed delays (derived jump delay)",
    "shaped": "shaped, dynamics-aware",
}
_FORMAT = 1  # of the rows: a change of what a row holds must not resume old rows
Shaper = Literal["none", "zoh", "zpetc"]
#: ``factory(mirror_mode=bool) -> GalvoSLMPlant``: where the build's twin comes from.
TwinFactory = Callable[..., GalvoSLMPlant]

#: Layer thickness accepted, m. Assumed: SLM layers are tens of µm (seed 003 part 2 §1:
#: "typically 20 to 40 µm"); a value outside 1 µm to 1 mm is a mistake in the unit.
LAYER_RANGE_M = (1e-6, 1e-3)
#: Most hatch lines across one layer. Assumed bound of one layer's work (a 16 mm disc at
#: 0.16 µm); a finer hatch is a mistake in the unit and would not fit in memory.
MAX_HATCH_LINES = 100_000


@dataclass(frozen=True, kw_only=True)
class BuildSettings:
    """What a whole build is: its layers, the lattice, the scan and the shaper.

    Parameters
    ----------
    n_layers : int
        Layers in the build (>= 1). 500 layers of 30 µm are 15 mm, 9.2 lattice cells.
    layer_m : float
        Layer thickness, m (30 µm: seed 003 part 2 §1 "in SLM typically 20 to 40 µm", the
        middle; the seed gives no value for its bunny).
    outline_radius_m : float
        Radius of the disc the lattice is clipped to, m (8 mm, as the ``slm-shaping`` layer;
        assumed: no bunny mesh is shipped).
    hatch_spacing_m : float
        Hatch distance, m (100 µm, assumed as `microfab.process.slm.lattice.LatticeSpec`).
    hatch_angle_deg_per_layer : float
        Turn of the hatch direction from one layer to the next, deg (67°, assumed: a
        common SLM scan strategy, so that no direction repeats for many layers; the seed
        gives no strategy).
    mark_speed_m_s, jump_speed_m_s : float
        Mark and jump speeds, m/s (0.6 and 5, assumed as
        `microfab.process.slm.timing.ScanSpeeds`).
    shaper : {"none", "zoh", "zpetc"}
        The input shaper of the shaped estimates: none (the shaped estimates then equal the
        unshaped ones), the seed's model inverse discretised by ZOH (the seed's), or by
        ZPETC (an inverse of the sampled axis, default: the ``slm-shaping`` run shows it keeps the
        continuous design's gain on the 10 µs axis where ZOH loses it).
    mirror_mode : bool
        Give the twin its optional 3 kHz mirror mode (assumed, `microfab.plants.galvo_slm`);
        the shaper is still designed from the seed's model, which lacks it.
    """

    n_layers: int = 500
    layer_m: float = 30e-6  # seed 003 part 2 §1: "typically 20 to 40 µm"; the middle
    outline_radius_m: float = 8e-3  # assumed, as the slm-shaping run's lattice layer
    hatch_spacing_m: float = 100e-6  # assumed, as LatticeSpec
    hatch_angle_deg_per_layer: float = 67.0  # assumed: a common SLM rotation per layer
    mark_speed_m_s: float = 0.6  # assumed, as ScanSpeeds
    jump_speed_m_s: float = 5.0  # assumed, as ScanSpeeds
    shaper: Shaper = "zpetc"
    mirror_mode: bool = False

    def __post_init__(self) -> None:
        check_int("n_layers", self.n_layers, 1, "layers")
        check_positive("layer thickness layer_m", self.layer_m, "m")
        check_positive("outline_radius_m", self.outline_radius_m, "m")
        check_positive("hatch_spacing_m", self.hatch_spacing_m, "m")
        check_finite("hatch_angle_deg_per_layer", self.hatch_angle_deg_per_layer, "deg")
        ScanSpeeds(mark_m_s=self.mark_speed_m_s, jump_m_s=self.jump_speed_m_s)
        lo, hi = LAYER_RANGE_M
        if not lo <= self.layer_m <= hi:
            raise ValueError(
                f"layer thickness layer_m = {self.layer_m:g} m is outside {lo:g} to {hi:g} m "
                "(SLM layers are tens of µm); check the unit"
            )
        height = self.n_layers * self.layer_m
        if height > MAX_HEIGHT_M:
            raise ValueError(
                f"{self.n_layers} layers of {self.layer_m:g} m make a part {height:g} m tall, "
                f"taller than {MAX_HEIGHT_M:g} m; choose at most "
                f"{int(MAX_HEIGHT_M / self.layer_m)} layers"
            )
        width = 2.0 * self.outline_radius_m
        if self.outline_radius_m < self.hatch_spacing_m:
            raise ValueError(
                f"outline_radius_m = {self.outline_radius_m:g} m is smaller than one hatch "
                f"spacing ({self.hatch_spacing_m:g} m): a layer would have nothing to mark"
            )
        if width / self.hatch_spacing_m > MAX_HATCH_LINES:
            raise ValueError(
                f"hatch_spacing_m = {self.hatch_spacing_m:g} m gives "
                f"{width / self.hatch_spacing_m:.3g} hatch lines across the {width:g} m disc, "
                f"more than {MAX_HATCH_LINES}; choose at least {width / MAX_HATCH_LINES:g} m"
            )
        if self.shaper not in ("none", "zoh", "zpetc"):
            raise ValueError(
                f"shaper must be 'none', 'zoh' (the seed's discretisation) or 'zpetc', "
                f"got {self.shaper!r}"
            )
        if not isinstance(self.mirror_mode, bool):
            raise ValueError(f"mirror_mode must be true or false, got {self.mirror_mode!r}")

    def to_dict(self) -> dict[str, Any]:
        """The settings as JSON values (field name -> value)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> BuildSettings:
        """Settings from `to_dict`'s form; keys that are no field are ignored."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})

    def lattice_spec(self, angle_deg: float = 0.0) -> LatticeSpec:
        """The lattice, outline and hatch of a layer hatched at ``angle_deg``."""
        return LatticeSpec(
            outline_radius_m=self.outline_radius_m,
            hatch_spacing_m=self.hatch_spacing_m,
            hatch_offset_m=0.5 * self.hatch_spacing_m,  # as LatticeSpec: half the spacing
            hatch_angle_rad=math.radians(angle_deg),
        )

    def rtc_settings(self, jump_delay_s: float = SEED_JUMP_DELAY_UNSHAPED_S) -> RTCSettings:
        """The RTC settings: these speeds, the default delays with ``jump_delay_s``."""
        speeds = ScanSpeeds(mark_m_s=self.mark_speed_m_s, jump_m_s=self.jump_speed_m_s)
        return RTCSettings(speeds=speeds).with_delays(jump_s=jump_delay_s)


@dataclass(frozen=True)
class BuildLayer:
    """One layer of the build: a sweep point.

    Attributes
    ----------
    index : int
        0 for the first layer.
    z_m : float
        Height of the section, m: the layer's middle, ``(index + 1/2) layer_m`` (assumed;
        the lattice's node planes lie at multiples of the cell).
    angle_deg : float
        Hatch direction, deg from +x, in [0, 360).
    """

    index: int
    z_m: float
    angle_deg: float


def build_layers(settings: BuildSettings) -> tuple[BuildLayer, ...]:
    """The layers of a build, bottom to top (`BuildLayer`).

    Layer ``i`` is cut at ``(i + 1/2) layer_m`` and hatched at ``i · angle per layer``
    modulo 360°.
    """
    step = settings.hatch_angle_deg_per_layer
    return tuple(
        BuildLayer(index=i, z_m=(i + 0.5) * settings.layer_m, angle_deg=(i * step) % 360.0)
        for i in range(settings.n_layers)
    )


# ------------------------------------------------------------------------- the task
def _lti_dict(lti: DiscreteLTI) -> dict[str, Any]:
    return {k: np.asarray(getattr(lti, k)).tolist() for k in ("A", "B", "C", "D")} | {"dt": lti.dt}


@functools.lru_cache(maxsize=8)
def _models(
    twin: TwinFactory, mirror_mode: bool, shaper_json: str
) -> tuple[DiscreteLTI, DiscreteLTI]:
    """The twin's axis and the shaped axis, built once per process (JSON of the filter)."""
    axis = twin(mirror_mode=mirror_mode).axis_model
    f = json.loads(shaper_json)
    if f is None:
        return axis, axis
    arrays = [np.array(f[k], dtype=float) for k in ("A", "B", "C", "D")]
    return axis, series(DiscreteLTI(*arrays, f["dt"]), axis)


def _estimate_row(name: str, est: ScanTimeEstimate) -> dict[str, float]:
    row = {f"{name}_s": est.total_s}
    row.update({f"{name}_{c}_s": float(est.breakdown_s[c]) for c in CATEGORIES})
    return row


def _laser_error(est: ScanTimeEstimate) -> float:
    errs = [e for e in (est.laser_on_error_bit, est.laser_off_error_bit) if e is not None]
    errs = [e for e in errs if e.size]
    return max((float(np.hypot(*e.T).max()) for e in errs), default=0.0)


def layer_task(
    point: BuildLayer, settings_dict: Mapping[str, Any], twin: TwinFactory = galvo_slm_twin
) -> dict[str, Any]:
    """Estimate one layer of a build five ways (module doc); a row of JSON values.

    Parameters
    ----------
    point : BuildLayer
        The layer.
    settings_dict : mapping
        What `run_build` hands the task: the `BuildSettings` fields (``n_layers`` may be
        missing), ``jump_delay_ticks`` (``{"unshaped": n, "shaped": n}``, derived once per
        build) and ``shaper_filter`` (the discrete shaper as ``A, B, C, D, dt``, or None).
    twin : callable
        The twin factory (module doc).

    Returns
    -------
    dict
        ``n_vectors``, ``n_marks``, ``n_jumps``; ``<estimate>_s`` and
        ``<estimate>_<category>_s`` for each of `ESTIMATES` and
        `microfab.process.slm.timing.CATEGORIES`, s; ``mean_jump_delay_s`` and
        ``shaped_mean_jump_delay_s`` (dynamics-aware, s); ``laser_error_bit`` and
        ``shaped_laser_error_bit`` (largest position error at a laser switch,
        dynamics-aware, bit); ``compute_s`` (wall time of this task, s).
    """
    t0 = time.perf_counter()
    s = BuildSettings.from_dict(settings_dict)
    jd = settings_dict["jump_delay_ticks"]
    axis, shaped_axis = _models(twin, s.mirror_mode, json.dumps(settings_dict["shaper_filter"]))
    path = lattice_layer(point.z_m, s.lattice_spec(point.angle_deg))
    rtc = s.rtc_settings()  # the seed's 750 µs jump delay (fixed estimate)
    rtc_shaped = s.rtc_settings(int(jd["shaped"]) * TICK_S)
    dyn = dynamics_estimate(path, axis, rtc)
    shaped = dynamics_estimate(path, shaped_axis, rtc_shaped)
    row: dict[str, Any] = {"n_vectors": len(path), "n_marks": path.n_marks,
                           "n_jumps": path.n_jumps}  # fmt: skip
    row |= _estimate_row("naive", naive_estimate(path, rtc.speeds))
    row |= _estimate_row("fixed", fixed_delay_estimate(path, rtc))
    row |= _estimate_row("dynamics", dyn)
    row |= _estimate_row("shaped_fixed", fixed_delay_estimate(path, rtc_shaped))
    row |= _estimate_row("shaped", shaped)
    for name, est in (("", dyn), ("shaped_", shaped)):
        delays = est.jump_delay_s
        row[f"{name}mean_jump_delay_s"] = (
            float(delays.mean()) if delays is not None and delays.size else 0.0
        )
        row[f"{name}laser_error_bit"] = _laser_error(est)
    row["compute_s"] = time.perf_counter() - t0
    return row


# ------------------------------------------------------------------------ the result
@dataclass(frozen=True, kw_only=True)
class BuildResult:
    """A whole build's estimates (`run_build`).

    Attributes
    ----------
    settings : BuildSettings
        The build.
    layers : tuple of dict
        One row per finished layer, by index: ``index``, ``z_m``, ``angle_deg`` and the
        entries of `layer_task`.
    failed : tuple of str
        Layers whose task failed, ``"layer i (z ... mm, ...°): Error: message"``.
    jump_delay_s : mapping of str to float
        Jump delays derived once for the build (one cell at the jump speed, 2 % band):
        ``"unshaped"`` and ``"shaped"``, s.
    skipped : int
        Layers loaded from the results directory, not run again.
    wall_s : float
        Wall time of `run_build`, s.
    """

    settings: BuildSettings
    layers: tuple[dict[str, Any], ...]
    failed: tuple[str, ...] = ()
    jump_delay_s: Mapping[str, float] = field(default_factory=dict)
    skipped: int = 0
    wall_s: float = 0.0

    def per_layer(self, key: str) -> np.ndarray:
        """One entry of every layer's row, by layer index, shape (n_done,).

        Raises
        ------
        ValueError
            When ``key`` is no entry of the rows (names the known ones).
        """
        if self.layers and key not in self.layers[0]:
            raise ValueError(f"unknown per-layer entry {key!r}; known: {', '.join(self.layers[0])}")
        return np.array([row[key] for row in self.layers], dtype=float)

    def breakdown(self, estimate: str) -> dict[str, float]:
        """Build time per category of one of `ESTIMATES`, s (sums to its total)."""
        if estimate not in ESTIMATES:
            raise ValueError(f"unknown estimate {estimate!r}; known: {', '.join(ESTIMATES)}")
        return {c: float(self.per_layer(f"{estimate}_{c}_s").sum()) for c in CATEGORIES}

    def totals(self) -> dict[str, float]:
        """Build times of the finished layers, s, and the cuts the shaper gives.

        Returns
        -------
        dict
            ``<estimate>_s`` for each of `ESTIMATES`; ``cut_fraction``
            ``1 - shaped / dynamics`` and ``cut_fraction_fixed`` ``1 - shaped_fixed /
            fixed`` (seed 003 part 2 §4: 1 - 4219 / 4686 = 9.97 %).
        """
        out = {f"{e}_s": float(self.per_layer(f"{e}_s").sum()) for e in ESTIMATES}
        for name, (after, before) in (("", ("shaped", "dynamics")),
                                      ("_fixed", ("shaped_fixed", "fixed"))):  # fmt: skip
            b = out[f"{before}_s"]
            out[f"cut_fraction{name}"] = 1.0 - out[f"{after}_s"] / b if b > 0 else 0.0
        return out

    def category_totals(self) -> dict[str, dict[str, float]]:
        """Dynamics-aware build time per category, ``{"unshaped": {...}, "shaped": {...}}``."""
        return {"unshaped": self.breakdown("dynamics"), "shaped": self.breakdown("shaped")}

    def summary(self) -> dict[str, Any]:
        """JSON-ready: settings, totals, categories, per-layer spread, failures, times."""
        spread = {}
        for e in ESTIMATES:
            v = self.per_layer(f"{e}_s")
            spread[f"{e}_s"] = (
                {"mean": float(v.mean()), "min": float(v.min()), "max": float(v.max())}
                if v.size
                else {}
            )
        compute = self.per_layer("compute_s") if self.layers else np.zeros(0)
        return {
            "settings": self.settings.to_dict(),
            "n_layers": self.settings.n_layers,
            "n_done": len(self.layers),
            "n_skipped": self.skipped,
            "failed": list(self.failed),
            "jump_delay_s": dict(self.jump_delay_s),
            "totals_s": self.totals(),
            "category_totals_s": {e: self.breakdown(e) for e in ESTIMATES},
            "per_layer_s": spread,
            "n_vectors": int(self.per_layer("n_vectors").sum()) if self.layers else 0,
            "compute_s": float(compute.sum()),
            "wall_s": self.wall_s,
            "seed": {
                "total_unshaped_s": SEED_TOTAL_UNSHAPED_S,
                "total_shaped_s": SEED_TOTAL_SHAPED_S,
                "cut_fraction": 1.0 - SEED_TOTAL_SHAPED_S / SEED_TOTAL_UNSHAPED_S,
            },
        }


# ----------------------------------------------------------------------- the runner
def _check_twin(settings: BuildSettings, twin: TwinFactory) -> None:
    c = twin(mirror_mode=False).config
    field_m = c.field_bit * c.bit_size_m
    if settings.outline_radius_m > field_m:
        raise ValueError(
            f"outline_radius_m = {settings.outline_radius_m} m lies outside the scanner "
            f"field (±{field_m:g} m: {c.field_bit:g} bit of {c.bit_size_m:g} m); choose at "
            f"most {field_m:g} m"
        )
    for name in ("mark_speed_m_s", "jump_speed_m_s"):
        v = getattr(settings, name)
        if v > c.velocity_limit_m_s:
            raise ValueError(
                f"{name} = {v} m/s exceeds the twin's velocity limit "
                f"{c.velocity_limit_m_s:g} m/s; choose at most that"
            )


def _task_settings(
    settings: BuildSettings, twin: TwinFactory = galvo_slm_twin
) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(sweep settings, task settings)``: the shaper designed and jump delays derived once."""
    axis = twin(mirror_mode=settings.mirror_mode).axis_model
    shaper_filter = None
    shaped_axis = axis
    if settings.shaper != "none":
        # the seed's G: what was identified
        nominal = twin(mirror_mode=False).transfer_function()
        design = design_inverse_shaper(nominal, InverseShaperConfig(discretization=settings.shaper))
        lti = design.to_lti()
        shaper_filter = _lti_dict(lti)
        shaped_axis = series(lti, axis)
    cell = settings.lattice_spec().cell_m
    rtc = settings.rtc_settings()
    tol = SettleTolerance()
    delays = {
        name: round(jump_delay(model, cell, settings=rtc, tolerance=tol) / TICK_S)
        for name, model in (("unshaped", axis), ("shaped", shaped_axis))
    }
    sweep = {k: v for k, v in settings.to_dict().items() if k != "n_layers"}
    sweep |= {
        "build_format": _FORMAT,
        "settle_tolerance": {"relative": tol.relative, "absolute_bit": tol.absolute_bit},
        "jump_delay_ticks": delays,
    }
    return sweep, {**sweep, "shaper_filter": shaper_filter}


def _failure(point: BuildLayer, error: str) -> str:
    return f"layer {point.index} (z {point.z_m * 1e3:.4f} mm, {point.angle_deg:g}°): {error}"


def run_build(
    settings: BuildSettings,
    results_dir: Path | None = None,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    twin: TwinFactory = galvo_slm_twin,
) -> BuildResult:
    """Estimate every layer of a build, saving each as it finishes (module doc).

    Parameters
    ----------
    settings : BuildSettings
        The build.
    results_dir : Path, optional
        Where each layer's row is saved and resumed from (`microfab.io.sweep`):
        a rerun skips the finished layers, and may add layers (``n_layers`` is not part of
        the saved settings); a directory holding a build with other settings is refused.
    workers : int
        ``1``: in this process; more: a local Dask cluster of that many processes.
    scheduler : str, optional
        Address of a running Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"`` (its workers
        must import ``microfab``).
    progress : callable, optional
        ``progress(done, total)`` after each layer that ran (``done`` counts the skipped).
    twin : callable
        The twin factory, ``twin(mirror_mode=bool)`` (module doc); a module-level function.

    Returns
    -------
    BuildResult
        Rows of the finished layers; the failed ones listed (a rerun retries them).

    Raises
    ------
    ValueError
        ``results_dir`` holds a build with other settings; the outline outside the field
        or a speed above the twin's limit; ``workers < 1``.
    """
    t0 = time.perf_counter()
    _check_twin(settings, twin)
    sweep_settings, task_settings = _task_settings(settings, twin)
    res = run_sweep(
        functools.partial(layer_task, settings_dict=task_settings, twin=twin),
        build_layers(settings),
        results_dir=results_dir,
        settings=sweep_settings,
        workers=workers,
        scheduler=scheduler,
        progress=None if progress is None else lambda d, t, _p, _ok: progress(d, t),
        raise_on_failure=False,
    )
    ticks = sweep_settings["jump_delay_ticks"]
    return BuildResult(
        settings=settings,
        layers=tuple(sorted(res.rows, key=lambda r: r["index"])),
        failed=tuple(_failure(f.point, f.error) for f in res.failed),
        jump_delay_s={k: n * TICK_S for k, n in ticks.items()},
        skipped=len(res.skipped),
        wall_s=time.perf_counter() - t0,
    )
