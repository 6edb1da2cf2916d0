"""`microfab.core.interrupt.interruptible`: a Ctrl-C inside a solver is a KeyboardInterrupt.

The solvers here are stand-ins that do what CasADi does with a SIGINT (catch the
KeyboardInterrupt its handler raises and return a status, or raise another error); the
real IPOPT is in ``tests/optimize/test_interrupt.py``.
"""

from __future__ import annotations

import io
import os
import signal
import sys
import threading
import time

import pytest

from microfab.core.interrupt import interruptible

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

_WARNING = (
    'CasADi - 2026-11-29 07:39:09 WARNING("KeyboardInterruptException") '
    "[.../casadi/interfaces/ipopt/ipopt_nlp.cpp:132]\n"
)


def _ctrl_c_inside() -> None:
    """A SIGINT to this process, handled before returning (the handler raises here)."""
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(5.0)  # the handler runs at once: this sleep is cut short
    raise AssertionError("the SIGINT handler did not run")  # pragma: no cover


def _swallowing_solver(status: str = "NonIpopt_Exception_Thrown") -> str:
    """What CasADi's IPOPT does: the KeyboardInterrupt becomes a status, and a warning."""
    try:
        _ctrl_c_inside()
    except KeyboardInterrupt:
        sys.stderr.write(_WARNING)
        return status
    raise AssertionError("no interrupt")  # pragma: no cover


def _converting_solver() -> str:
    """A solver whose wrapper turns the interrupt into another error."""
    try:
        _ctrl_c_inside()
    except KeyboardInterrupt:
        raise RuntimeError("Error in Function::call for 'solver' [IpoptInterface]") from None
    raise AssertionError("no interrupt")  # pragma: no cover


def test_a_status_made_of_a_ctrl_c_is_raised_as_keyboardinterrupt(capsys) -> None:
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        interruptible(_swallowing_solver)
    assert signal.getsignal(signal.SIGINT) is before
    # CasADi's warning of the interrupt is dropped: the command's one line stands alone
    assert capsys.readouterr().err == ""


def test_another_error_made_of_a_ctrl_c_is_raised_as_keyboardinterrupt() -> None:
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        interruptible(_converting_solver)
    assert signal.getsignal(signal.SIGINT) is before


def test_without_a_ctrl_c_the_answer_and_errors_pass_through(capsys) -> None:
    before = signal.getsignal(signal.SIGINT)

    def solver(x: float, *, scale: float) -> float:
        sys.stderr.write("a solver's own warning\nand an unfinished line")
        return x * scale

    assert interruptible(solver, 2.0, scale=3.0) == 6.0
    assert capsys.readouterr().err == "a solver's own warning\nand an unfinished line"

    def failing() -> None:
        raise RuntimeError("infeasible")

    with pytest.raises(RuntimeError, match="infeasible"):
        interruptible(failing)
    assert signal.getsignal(signal.SIGINT) is before


def test_an_uncaught_ctrl_c_stays_a_keyboardinterrupt() -> None:
    with pytest.raises(KeyboardInterrupt):
        interruptible(_ctrl_c_inside)


def test_a_status_that_was_no_ctrl_c_is_returned() -> None:
    """IPOPT's ``NonIpopt_Exception_Thrown`` without a SIGINT is the solver's answer."""
    assert interruptible(lambda: "NonIpopt_Exception_Thrown") == "NonIpopt_Exception_Thrown"


def test_a_handler_that_does_not_raise_is_not_an_interrupt() -> None:
    """A handler that holds the signal (the sweep's, while its cluster starts) is obeyed."""
    held: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, _frame: held.append(signum))
    try:

        def solver() -> str:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
            return "done"

        assert interruptible(solver) == "done"
        assert held == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_off_the_main_thread_the_solve_runs_as_it_is() -> None:
    got: list[object] = []
    thread = threading.Thread(target=lambda: got.append(interruptible(lambda: "ok")))
    thread.start()
    thread.join(10)
    assert got == ["ok"]


def test_the_filter_passes_lines_as_they_come() -> None:
    from microfab.core.interrupt import _DropInterruptWarning

    out = io.StringIO()
    f = _DropInterruptWarning(out)
    f.write("first ")
    assert out.getvalue() == ""  # held until its newline
    f.write("line\n" + _WARNING + "last")
    assert out.getvalue() == "first line\n"
    f.flush()
    assert out.getvalue() == "first line\nlast"
    assert f.getvalue() == out.getvalue()  # the stream's own attributes
