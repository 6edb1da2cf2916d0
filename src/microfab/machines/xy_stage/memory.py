"""How far back the XY stage twin remembers: what a window of its command cannot know.

Seed 002 eq. (7) predicts the position from the last 500 ms of the command alone (§III-B:
h = 200 samples at 400 Hz). That can work only if the machine forgets what came before.
`history_spread` measures it on the twin: one command segment played after several
different histories, each a run that ends at rest at the origin, as every excitation
run starts and ends (`microfab.identify.excitation`), so each joined command is as smooth
as its parts; the spread of the outputs across histories at a time ``t`` into the segment
is what no model of the last ``t`` seconds of command can predict.

On the calibrated twin, noise off, the spread is 18.6 / 18.8 µm (x / y) at the start of
the segment, 0.004 µm after 250 ms and 0 after 500 ms: the 500 ms window holds all the
twin's memory (issue 34, item 0).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from microfab.machines.xy_stage.machine import Command, CommandRun, TwinSettings, play_runs

__all__ = ["HistorySpread", "history_spread"]


@dataclass(frozen=True)
class HistorySpread:
    """Spread of the twin's output across histories, along the common segment.

    Attributes
    ----------
    time_s : numpy.ndarray
        Time into the segment, s, shape (n,).
    spread_m : numpy.ndarray
        Standard deviation across histories of the measured position, m, shape (n, 2).
    """

    time_s: np.ndarray
    spread_m: np.ndarray

    def at(self, t_s: float) -> np.ndarray:
        """The spread (x, y) at ``t_s`` into the segment, m."""
        k = int(np.searchsorted(self.time_s, t_s))
        if not 0 <= k < self.time_s.shape[0]:
            raise ValueError(f"t_s = {t_s!r} s lies outside the segment")
        return self.spread_m[k]

    def after(self, t_s: float) -> np.ndarray:
        """The largest spread (x, y) from ``t_s`` on, m."""
        k = int(np.searchsorted(self.time_s, t_s))
        if not 0 <= k < self.time_s.shape[0]:
            raise ValueError(f"t_s = {t_s!r} s lies outside the segment")
        return self.spread_m[k:].max(axis=0)


def history_spread(
    segment: CommandRun,
    histories: Sequence[CommandRun],
    settings: TwinSettings | None = None,
) -> HistorySpread:
    """Play ``segment`` after each history; the output's spread across them (module doc).

    Parameters
    ----------
    segment : CommandRun
        The common command, (n, 2) m; it must start where every history ends (an
        excitation run: at rest at the origin).
    histories : sequence of CommandRun
        At least two commands at the segment's ``dt``, each ending at the segment's first
        sample.
    settings : TwinSettings, optional
        The twin (default: calibrated, noise off, no hold: the spread of the model's
        own memory, not of its noise).

    Raises
    ------
    ValueError
        Fewer than two histories, another ``dt``, or a history that does not end at the
        segment's start (a jump in the joined command).
    """
    if len(histories) < 2:
        raise ValueError("history_spread needs at least two histories")
    s = TwinSettings(noise=False, hold_s=0.0) if settings is None else settings
    seg = np.asarray(segment.command, dtype=float)
    joined = []
    for k, h in enumerate(histories):
        if abs(h.dt - segment.dt) > 1e-12 * segment.dt:
            raise ValueError(f"history {k} is at dt {h.dt!r} s, the segment at {segment.dt!r} s")
        cmd = np.asarray(h.command, dtype=float)
        if np.abs(cmd[-1] - seg[0]).max() > 1e-9:
            raise ValueError(
                f"history {k} ends at {cmd[-1].tolist()} m, not at the segment's start "
                f"{seg[0].tolist()} m: the joined command would jump"
            )
        joined.append(Command(name=f"history_{k}", command=np.vstack([cmd, seg]), dt=segment.dt))
    played = play_runs(joined, s)
    outs = np.stack(
        [r.y[h.command.shape[0] : h.command.shape[0] + seg.shape[0]] for r, h in
         zip(played.records, histories, strict=True)]
    )  # fmt: skip
    return HistorySpread(time_s=np.arange(seg.shape[0]) * segment.dt, spread_m=outs.std(axis=0))
