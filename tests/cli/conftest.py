"""Shared data of the seed 003 part 2 command tests (identify, shaper, slm).

The seed's galvo model (Buls et al. §1) as a model JSON file, and the check that a
refusal is one ``error:`` line with exit code 2.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from microfab.identify.model import TFModel

SEED_NUM = (1.242e11,)  # seed 003 part 2 §1
SEED_DEN = (1.0, 9517.0, 5.773e7, 1.272e11)  # seed 003 part 2 §1


def _one_error_line(res: Any, says: str) -> None:
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert says in lines[0], res.output


@pytest.fixture(scope="session")
def one_error_line() -> Callable[[Any, str], None]:
    """Check that a CLI result is one ``error:`` line holding ``says``, exit code 2."""
    return _one_error_line


@pytest.fixture(scope="session")
def seed_model() -> TFModel:
    """The seed's model G(s), position command in bit to measured position in bit."""
    return TFModel(num=SEED_NUM, den=SEED_DEN, unit="bit/bit")


@pytest.fixture(scope="session")
def model_file(tmp_path_factory, seed_model: TFModel) -> Path:
    """``seed_model`` as a model JSON file (what ``identify chirp --json`` writes)."""
    p = tmp_path_factory.mktemp("model") / "model.json"
    p.write_text(json.dumps(seed_model.to_dict()))
    return p
