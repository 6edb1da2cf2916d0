"""Ctrl-C in the ``microfab`` command: one line and exit 130, whenever it comes.

Standard library only, so that it guards the command's imports too. Two ways of taking
SIGINT, one handler (`_Guard`):

``hold``
    While the command loads (``microfab.cli`` imports NumPy, typer, rich, ...; typer then
    builds the command, resolving every signature: seconds on a loaded machine), the
    signal is only recorded. A KeyboardInterrupt raised there leaves a module half
    imported, prints a traceback instead of the one line, and inside a C extension's
    initialisation (pybind11: SciPy's HiGHS) turns into ``ImportError: initialization
    failed``. The command raises the held interrupt once it runs (`arm`).
``defer``
    While the command runs, KeyboardInterrupt is raised at once, except while Python
    runs source text (``exec``/``eval`` of a string) or imports a module. CPython (3.11;
    ``run_eval_code_obj``) marks a KeyboardInterrupt that leaves ``exec`` of a string
    as unhandled, whoever catches it later, and ``python -m microfab`` then kills itself
    with SIGINT after its one ``interrupted`` line: exit -2 instead of 130. That was the
    flaky ``tests/cli/test_interrupt.py`` case: a Ctrl-C 1.1-1.6 s after the start, under
    load, landed while the sweep's lazy import of SciPy ran
    ``exec("from numpy import *")`` (``array_api_compat.clone_module``); 6 of 16 such
    runs exited -2. There the signal is sent again `RETRY_S` later, until the program is
    out of it (at most `DEFER_MAX_S`, then raised wherever it lands).

Only the main thread handles signals; elsewhere (a command run from a worker thread)
these are no-ops and Python's handler stays.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from typing import Any

__all__ = ["DEFER_MAX_S", "RETRY_S", "arm", "hold", "pending", "restore"]

#: Seconds between a deferred signal and its next delivery (assumed: short against a
#: person's patience, long against the ~µs of a bytecode step).
RETRY_S = 0.05
#: Seconds a signal is deferred at most (assumed: an import that takes longer is stuck;
#: the interrupt is then raised inside it, as Python would).
DEFER_MAX_S = 10.0

_SOURCE_TEXT = "<string>"  # co_filename of code compiled from a string by exec/eval


def _unsafe(frame: Any) -> bool:
    """Whether ``frame`` or a caller runs source text or an import (module docstring)."""
    while frame is not None:
        name = frame.f_code.co_filename
        if name == _SOURCE_TEXT or name.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


class _Guard:
    """The SIGINT handler in either way of taking it (module docstring)."""

    def __init__(self, previous: Any) -> None:
        self.previous = previous
        self.held = 0  # signals recorded while holding, not yet raised
        self.armed = False
        self.active = True  # until `restore`: a deferred signal is still owed
        self.first_deferred: float | None = None
        self.timer: threading.Timer | None = None

    def __call__(self, signum: int, frame: Any) -> None:
        if not self.armed:
            self.held += 1
            return
        now = time.monotonic()
        if _unsafe(frame):
            if self.first_deferred is None:
                self.first_deferred = now
            if now - self.first_deferred < DEFER_MAX_S:
                self._again()
                return
        self.first_deferred = None
        raise KeyboardInterrupt

    def _again(self) -> None:
        if self.timer is not None and self.timer.is_alive():
            return
        self.timer = threading.Timer(RETRY_S, self._resend)
        self.timer.daemon = True
        self.timer.start()

    def _resend(self) -> None:
        # to whichever handler is in place now (a sweep's, holding it while its cluster
        # starts, takes it as its own); none once the command has ended
        if self.active:
            os.kill(os.getpid(), signal.SIGINT)


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _guard() -> _Guard | None:
    handler = signal.getsignal(signal.SIGINT)
    return handler if isinstance(handler, _Guard) else None


def _installed() -> _Guard:
    """The guard on SIGINT, installed over the current handler if it is not there yet."""
    guard = _guard()
    if guard is None:
        guard = _Guard(signal.getsignal(signal.SIGINT))
        signal.signal(signal.SIGINT, guard)
    return guard


def hold() -> None:
    """Start recording SIGINT instead of raising (the command is loading)."""
    if not _main_thread():
        return
    _installed().armed = False


def pending() -> bool:
    """Whether a SIGINT was held and not yet raised."""
    guard = _guard()
    return guard is not None and guard.held > 0


def arm() -> None:
    """Raise KeyboardInterrupt on SIGINT from now on (deferred where unsafe); a held one now.

    Installs the guard if `hold` did not.

    Raises
    ------
    KeyboardInterrupt
        A SIGINT was held.
    """
    if not _main_thread():
        return
    guard = _installed()
    guard.armed = True
    if guard.held:
        guard.held = 0
        raise KeyboardInterrupt


def restore() -> None:
    """Put back the handler found by the first `hold` or `arm`.

    A signal still held is dropped: ask `pending` first.
    """
    if not _main_thread():
        return
    guard = _guard()
    if guard is not None:
        guard.armed = guard.active = False
        signal.signal(signal.SIGINT, guard.previous)
