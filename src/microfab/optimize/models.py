"""The identified models a reference optimisation runs on, read from an identification output.

`load_models` reads the folder a ``stage-identify`` job writes (the same files as
``microfab identify linear`` and ``microfab identify ann``): ``linear_model.json``, the
linear model of seed 002 eq. (6) (`microfab.identify.stage_data.StageLinearModel`),
converted to continuous time for stage 1 (eqs. 8-12), and ``ann/model``, the per-axis
networks of eq. (7) (`microfab.identify.stage_ann.read_ann_stage_model`) for stage 2
(eqs. 13-14). ``microfab optimize --model DIR`` and the seed 002 reference reproduction
read their models with it.

**Shipped models.** The package holds the models of the ``stage-identify`` job on the
built-in twin (``microfab/data/xy_stage_models``: the same files, plus ``trained.json``:
the settings, seed, data digest and validation σ that produced them, written by ``python
-m microfab.experiments.seed002_stage.shipped``). A models folder given as ``""`` or ``"builtin"``
means them (`resolve_models_dir`), so the reference optimisation runs straight after
install; a user's own folder is any other path. `models_digest` hashes the model files
themselves, so that a result computed on other models is never taken for this one.

**Recorded validation σ** (`recorded_validation_sigma`): the networks' σ per axis on their
validation runs, as the folder records it — ``trained.json`` (the shipped models:
``validation.<axis>.sigma_um``) or the ``summary.json`` of a ``stage-identify`` job
(``ann.validation.<axis>.std_m``); None when neither holds it (``identify ann`` writes
no such file). The reference optimisation warns when it exceeds μ
(`microfab.optimize.pipeline.PredictionCheck`).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from microfab.identify.subspace_model import ContinuousModel

__all__ = [
    "BUILTIN",
    "Models",
    "builtin_models_dir",
    "check_models_dir",
    "load_models",
    "models_digest",
    "recorded_validation_sigma",
    "resolve_models_dir",
]

#: The name that selects the shipped models (an empty string does too).
BUILTIN = "builtin"
_FILES = ("linear_model.json", "ann/model/model.json", "ann/model/weights.npz")


def builtin_models_dir() -> Path:
    """The folder of the shipped models (``microfab/data/xy_stage_models``)."""
    return Path(str(resources.files("microfab.data").joinpath("xy_stage_models")))


def resolve_models_dir(directory: str | Path | None) -> Path:
    """The models folder meant by ``directory``.

    ``None``, ``""`` or ``"builtin"`` are the shipped models (`builtin_models_dir`);
    anything else is that path, as given.
    """
    if directory is None or str(directory).strip() in ("", BUILTIN):
        return builtin_models_dir()
    return Path(directory)


def models_digest(directory: str | Path | None, *, networks: bool = True) -> str:
    """SHA-256 (hex) of the model files of a models folder, in a fixed order.

    What decides an optimisation's numbers: two folders with the same files digest alike,
    a retrained network in the same folder does not. Missing files are hashed as absent.
    """
    from microfab.io.runstore import content_digest

    d = resolve_models_dir(directory)
    h = hashlib.sha256()
    for name in _FILES if networks else _FILES[:1]:
        f = d / name
        h.update(name.encode())
        h.update(content_digest(f).encode() if f.is_file() else b"<absent>")
    return h.hexdigest()


@dataclass(frozen=True, eq=False)
class Models:
    """The identified models a point is optimised with.

    Attributes
    ----------
    linear : ContinuousModel
        Eq. (6), continuous, m.
    networks : microfab.identify.ann.AnnModel
        Eq. (7), one per axis.
    source : str
        Where they were read from.
    validation_sigma_m : dict of str to float or None
        The networks' recorded validation σ per axis, m (`recorded_validation_sigma`).
    """

    linear: ContinuousModel
    networks: Any
    source: str = ""
    validation_sigma_m: dict[str, float] | None = None


def recorded_validation_sigma(directory: str | Path | None) -> dict[str, float] | None:
    """The networks' validation σ per axis (m) recorded in a models folder, or None.

    ``trained.json`` (``validation.<axis>.sigma_um``, µm) first, then a stage-identify
    job's ``summary.json`` (``ann.validation.<axis>.std_m``, m); a file that is missing,
    unreadable or without the numbers is skipped (module docstring).
    """
    d = resolve_models_dir(directory)
    sources = (
        ("trained.json", ("validation",), 1e-6, "sigma_um"),
        ("summary.json", ("ann", "validation"), 1.0, "std_m"),
    )
    for name, path, scale, key in sources:
        try:
            node: Any = json.loads((d / name).read_text())
            for part in path:
                node = node[part]
            out = {str(a): float(v[key]) * scale for a, v in node.items()}
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue
        if out and all(math.isfinite(v) and v >= 0 for v in out.values()):
            return out
    return None


def check_models_dir(directory: str | Path, *, networks: bool = True) -> None:
    """Refuse, before any work, a folder that does not hold a stage-identify job's models.

    Only the presence of ``linear_model.json`` (and of ``ann/model/model.json`` with
    ``networks``) is checked, so that ``microfab run --check`` can tell; `load_models`
    reads and checks them.

    Raises
    ------
    ValueError
        Naming the folder, what is missing and the job that writes it.
    """
    d = resolve_models_dir(directory)
    how = "run `microfab run examples/blackbox_stage_identify.toml` and give its output folder"
    if d == builtin_models_dir():
        how = "the installed package lacks its shipped models: reinstall microfab"
    if not d.is_dir():
        raise ValueError(f"models folder {d} does not exist; {how}")
    missing = [] if (d / "linear_model.json").is_file() else ["linear_model.json"]
    if networks and not (d / "ann" / "model" / "model.json").is_file():
        missing.append("ann/model/model.json")
    if missing:
        raise ValueError(f"models folder {d} holds no {' and no '.join(missing)}; {how}")


def load_models(directory: str | Path, *, networks: bool = True) -> Models:
    """The models of a ``stage-identify`` output: ``linear_model.json`` and ``ann/model``.

    ``networks=False`` reads only the linear model (stage 1 alone). ``directory`` ``""``
    or ``"builtin"``: the shipped models (`resolve_models_dir`).

    Raises
    ------
    ValueError
        A missing or unreadable model, another format version, model rate or history
        (the message names the file).
    """
    from microfab.identify.stage_ann import read_ann_stage_model
    from microfab.identify.stage_data import StageLinearModel, read_stage_model

    d = resolve_models_dir(directory)
    lin_path = d / "linear_model.json"
    if not lin_path.is_file():
        raise ValueError(f"{lin_path}: no linear model (the output of a stage-identify job)")
    lin = read_stage_model(lin_path)
    if not isinstance(lin, StageLinearModel):
        raise ValueError(f"{lin_path}: not a linear stage model")
    try:
        cont = lin.continuous()  # held at the runs' rate, not the decimated one
    except ValueError as exc:
        raise ValueError(f"{lin_path}: {exc}") from None
    source = BUILTIN if d == builtin_models_dir() else str(d)
    if not networks:
        return Models(linear=cont, networks=None, source=source)
    ann = read_ann_stage_model(d / "ann" / "model")
    return Models(linear=cont, networks=ann.model, source=source,
                  validation_sigma_m=recorded_validation_sigma(d))  # fmt: skip
