"""Codes and indices shared by the Eulerian jet's numba kernels and their driver.

The boundary codes (``BC_*``) and meniscus codes (``MENISCUS_*``), the positions in the
parameter vectors ``par`` (``P_*``) and ``ipar`` (``I_*``), the layout of the history and
event arrays (``HIST_ROWS``, ``EV_COLS``) and the shortest run of cells followed as a body
(``MIN_CELLS``). What they mean is described in :mod:`.jet_euler_kernels`, which
re-exports them; they sit apart so that the time step there and the breakup bookkeeping
of :mod:`.jet_euler_breakup` share them without importing each other. Numba reads them as
compile-time constants.
"""

from __future__ import annotations

__all__ = [
    "BC_NOZZLE",
    "BC_OUTFLOW",
    "BC_WALL",
    "EV_COLS",
    "HIST_ROWS",
    "I_BL",
    "I_BR",
    "I_COUPLED",
    "I_LIMITER",
    "I_MENISCUS",
    "MENISCUS_PINNED",
    "MENISCUS_RETRACTING",
    "MIN_CELLS",
    "N_IPAR",
    "N_PAR",
    "P_A_FILM",
    "P_A_NOZ",
    "P_BACK",
    "P_BORE",
    "P_CAP",
    "P_CFL",
    "P_DEPIN",
    "P_DT_MAX",
    "P_DZ",
    "P_GP",
    "P_H_BREAK",
    "P_INV_DE",
    "P_INV_L2",
    "P_OH",
    "P_REWET",
]

#: Left end at the nozzle exit: prescribed velocity, full nozzle behind it.
BC_NOZZLE = 0
#: Symmetry plane: zero velocity, mirrored profile.
BC_WALL = 1
#: Open far end: zero gradient, liquid leaves the domain.
BC_OUTFLOW = 2

(
    P_DZ, P_OH, P_GP, P_INV_DE, P_INV_L2, P_A_FILM, P_A_NOZ, P_CFL, P_H_BREAK, P_REWET,
    P_DT_MAX, P_BORE, P_CAP, P_DEPIN, P_BACK,
) = range(15)  # fmt: skip
N_PAR = 15
I_BL, I_BR, I_LIMITER, I_MENISCUS, I_COUPLED = range(5)
N_IPAR = 5

#: Meniscus codes (``ipar[I_MENISCUS]``): held at the rim (suction empties the root), or
#: free to retract into the bore (:mod:`.jet_euler_meniscus`).
MENISCUS_PINNED = 0
MENISCUS_RETRACTING = 1

#: Rows of the history array: t, neck radius, neck z, tip z, tip v, volume, injected,
#: bodies, meniscus position.
HIST_ROWS = 9
#: Columns of the event array: t, neck z, tip z, tail z, attached (0/1), neck cell.
EV_COLS = 6
#: Bodies shorter than this many cells are not followed as bodies (their volume stays).
MIN_CELLS = 2
