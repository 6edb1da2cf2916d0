"""The identified models a reference optimisation runs on, read from an identification output.

`load_models` reads the folder a ``stage-identify`` job writes (the same files as
``microfab identify linear`` and ``microfab identify ann``): ``linear_model.json``, the
linear model of seed 002 eq. (6) (`microfab.identify.stage_data.StageLinearModel`),
converted to continuous time for stage 1 (eqs. 8-12), and ``ann/model``, the per-axis
networks of eq. (7) (`microfab.identify.stage_ann.read_ann_stage_model`) for stage 2
(eqs. 13-14). ``microfab optimize --model DIR`` and the seed 002 reference reproduction
read their models with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from microfab.identify.subspace_model import ContinuousModel

__all__ = ["Models", "check_models_dir", "load_models"]


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
    """

    linear: ContinuousModel
    networks: Any
    source: str = ""


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
    d = Path(directory)
    how = "run `microfab run examples/blackbox_stage_identify.toml` and give its output folder"
    if not d.is_dir():
        raise ValueError(f"models folder {d} does not exist; {how}")
    missing = [] if (d / "linear_model.json").is_file() else ["linear_model.json"]
    if networks and not (d / "ann" / "model" / "model.json").is_file():
        missing.append("ann/model/model.json")
    if missing:
        raise ValueError(f"models folder {d} holds no {' and no '.join(missing)}; {how}")


def load_models(directory: str | Path, *, networks: bool = True) -> Models:
    """The models of a ``stage-identify`` output: ``linear_model.json`` and ``ann/model``.

    ``networks=False`` reads only the linear model (stage 1 alone).

    Raises
    ------
    ValueError
        A missing or unreadable model, another format version, model rate or history
        (the message names the file).
    """
    from microfab.identify.stage_ann import read_ann_stage_model
    from microfab.identify.stage_data import StageLinearModel, read_stage_model

    d = Path(directory)
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
    if not networks:
        return Models(linear=cont, networks=None, source=str(d))
    ann = read_ann_stage_model(d / "ann" / "model")
    return Models(linear=cont, networks=ann.model, source=str(d))
