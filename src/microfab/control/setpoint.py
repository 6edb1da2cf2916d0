"""`SetPoint`: the command is the reference, for plants whose input is a set position.

Some plants close their own position loop inside: the SLM galvo scanner of seed 003 part 2
(`microfab.plants.galvo_slm`) takes a set position every tick and reports the measured one.
Driven through the simulators of `microfab.sim.loop`, such a plant needs a controller that
hands the reference on unchanged, ``u_k = r_k`` (the measurement is not used): that is
`SetPoint`, a `microfab.control.base.CompiledController` whose numba kernel
(`setpoint_step`) and Python ``step`` do the same copy. A command filter (an input shaper)
goes in the `microfab.control.base.Loop`'s feedforward, in front of it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.core.validate import check_int

__all__ = ["SetPoint", "setpoint_step"]


@njit(cache=True)
def setpoint_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """Kernel of `SetPoint`: ``u[i] = ref[k, 0, i]`` for the ``p[0]`` axes; no state."""
    for i in range(int(p[0])):
        u[i] = ref[k, 0, i]


class SetPoint(CompiledController):
    """Open loop on a set-position plant: the command of sample ``k`` is the reference ``r_k``.

    Parameters
    ----------
    n_axes : int
        Number of axes (commands = reference axes), >= 1.

    Notes
    -----
    Preview 1, no state (an empty array). The measurement is ignored.
    """

    kernel_step: Any = setpoint_step

    def __init__(self, n_axes: int = 2) -> None:
        self.n_axes = check_int("n_axes", n_axes, 1, "axes")
        self.preview = 1
        self.params = np.array([float(self.n_axes)], dtype=np.float64)
        self.params.setflags(write=False)

    def init(self) -> np.ndarray:
        """No state: an empty array."""
        return np.zeros(0)

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(r_k, state)``: the current reference sample as the command."""
        return np.array(window.position[0, : self.n_axes], dtype=float), state
