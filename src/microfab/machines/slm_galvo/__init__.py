"""The SLM galvo scanner of seed 003 part 2: one module per role.

- `machine`: the twin, its limits and loop;
- `shapers`: shapers side by side on both twins;
- `shaping`: identification, input shaping and scan time (`run_shaping`).

The machine module's public names are re-exported here, so that
``from microfab.machines import slm_galvo``
then ``slm_galvo.twin(...)`` works; code inside the project imports
``microfab.machines.slm_galvo.machine`` itself.
"""

from microfab.machines.slm_galvo.machine import (
    DATA_FILES,
    SEED_MODEL_DEN,
    SEED_MODEL_NUM,
    chirp_frf,
    limits,
    play,
    twin,
)

__all__ = [
    "DATA_FILES",
    "SEED_MODEL_DEN",
    "SEED_MODEL_NUM",
    "chirp_frf",
    "limits",
    "play",
    "twin",
]
