"""Ctrl-C inside a compiled solver: a `KeyboardInterrupt`, never a solver status.

A solver that runs in C and checks for signals itself (CasADi: IPOPT's iteration callback
and CasADi's ``InterruptHandler``) runs Python's SIGINT handler from inside the solve; the
`KeyboardInterrupt` that handler raises is caught there and comes back as a status
(IPOPT's ``NonIpopt_Exception_Thrown`` or ``User_Requested_Stop``, CasADi's
``KeyboardInterruptException`` warning), or as another exception (``RuntimeError`` from a
CasADi function with ``error_on_fail``). The caller then reads "did not converge" (a
traceback or an ``error:`` line) or, worse, goes on with a failed step as if nothing had
been asked. `interruptible` runs a solve so that a Ctrl-C during it is re-raised as a
`KeyboardInterrupt` once the solver returns, whatever it returned or raised: the command
prints its one ``interrupted`` line and what was saved before stays as it was.

How a SIGINT is told from a failure: while the solve runs, the SIGINT handler in place
(Python's default, or the ``microfab`` command's, `microfab.cli._sigint`) is wrapped by
one that records that it raised `KeyboardInterrupt`; the handler is put back after the
solve. Not the status string: a status says the solve stopped, not that a person asked
it to (``NonIpopt_Exception_Thrown`` is any exception in a callback).

CasADi also writes a warning line (``CasADi - <time> WARNING("KeyboardInterruptException")
[...ipopt_nlp.cpp:95]``) on Python's standard error when it catches the interrupt: that
line is dropped, so that the command's one ``interrupted`` line stands alone; every other
line written there during the solve goes through as it comes.

Only the main thread handles signals: elsewhere (a worker thread) the solve runs as it
is. A handler that is not a Python callable (SIG_IGN in a worker process, SIG_DFL) is left
alone: no `KeyboardInterrupt` can come from it.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["interruptible"]

_T = TypeVar("_T")


class _Watch:
    """SIGINT handler: the one it wraps, noting whether that one raised KeyboardInterrupt."""

    def __init__(self, inner: Callable[[int, Any], Any]) -> None:
        self.inner = inner
        self.raised = False

    def __call__(self, signum: int, frame: Any) -> Any:
        try:
            return self.inner(signum, frame)
        except KeyboardInterrupt:
            self.raised = True
            raise


#: What CasADi's warning of a caught interrupt holds (``casadi_warning`` in its IPOPT
#: interface and ``InterruptHandler``).
_CASADI_INTERRUPT = "KeyboardInterruptException"


class _DropInterruptWarning:
    """Standard error during a solve: every line but CasADi's interrupt warning, as it comes.

    Text is passed on line by line (a line's pieces are held until its newline, `flush` or
    the end of the solve); anything else (``fileno``, ``encoding``...) is the stream's own.
    """

    def __init__(self, stream: Any) -> None:
        self.stream = stream
        self.partial = ""

    def write(self, text: str) -> int:
        self.partial += text
        *lines, self.partial = self.partial.split("\n")
        for line in lines:
            if _CASADI_INTERRUPT not in line:
                self.stream.write(line + "\n")
        return len(text)

    def flush(self) -> None:
        self.end()
        self.stream.flush()

    def end(self) -> None:
        """Pass on a last unfinished line (unless it is the interrupt warning)."""
        if self.partial and _CASADI_INTERRUPT not in self.partial:
            self.stream.write(self.partial)
        self.partial = ""

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


def _put_back(handler: Any, watch: _Watch) -> None:
    """Install ``handler`` again, whatever signal is pending.

    ``signal.signal`` runs a pending handler (ours) before it replaces it; when that one
    raises, the replacement has not happened: try again (the signal is consumed by then).
    """
    while True:
        try:
            signal.signal(signal.SIGINT, handler)
        except KeyboardInterrupt:
            watch.raised = True
            continue
        return


def _restore(
    stderr: Any, filtered: _DropInterruptWarning | None, handler: Any, watch: _Watch
) -> None:
    """Put back the handler and standard error (its last unfinished line passed on).

    The handler first: a signal handled while the line is written raises through it.
    """
    _put_back(handler, watch)
    if sys.stderr is filtered:  # unless the solve replaced it in turn
        sys.stderr = stderr
    if filtered is not None:
        filtered.end()


def interruptible(solve: Callable[..., _T], /, *args: Any, **kwargs: Any) -> _T:
    """``solve(*args, **kwargs)``, with a Ctrl-C during it raised as KeyboardInterrupt.

    Parameters
    ----------
    solve : callable
        The solver call (a CasADi ``nlpsol``/``conic`` function, SciPy's ``linprog``...).
    *args, **kwargs
        Its arguments.

    Returns
    -------
    object
        What ``solve`` returned, when no SIGINT raised KeyboardInterrupt during it.

    Raises
    ------
    KeyboardInterrupt
        The SIGINT handler raised it while ``solve`` ran, whether the solver let it through,
        turned it into a status or into another exception (that one is dropped).
    """
    if threading.current_thread() is not threading.main_thread():
        return solve(*args, **kwargs)
    handler = signal.getsignal(signal.SIGINT)
    if not callable(handler) or handler in (signal.SIG_IGN, signal.SIG_DFL):
        return solve(*args, **kwargs)
    watch = _Watch(handler)
    signal.signal(signal.SIGINT, watch)
    stderr = sys.stderr
    filtered = None if stderr is None else _DropInterruptWarning(stderr)
    sys.stderr = filtered
    try:
        result = solve(*args, **kwargs)
    except BaseException:
        _restore(stderr, filtered, handler, watch)
        if watch.raised:
            raise KeyboardInterrupt from None
        raise
    _restore(stderr, filtered, handler, watch)
    if watch.raised:
        raise KeyboardInterrupt
    return result
