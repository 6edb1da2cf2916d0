"""Ctrl-C inside IPOPT (issue 44, cause F): a KeyboardInterrupt, never "did not converge".

CasADi catches the KeyboardInterrupt that the SIGINT handler raises inside IPOPT and
returns a status (``NonIpopt_Exception_Thrown`` when CasADi's own signal check took it,
``User_Requested_Stop`` when it came in an iteration callback). Before issue 44 stage 1
then raised ``Stage1Error`` (a traceback, or an ``error:`` line) and stage 2 took the QP
for failed and ended as if it had stopped by itself. Deterministic: the SIGINT is sent
from IPOPT's iteration callback at a given iteration (``iteration_callback``), or, for the
command, by the test once IPOPT has reached its third iteration, as a terminal sends it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ca = pytest.importorskip("casadi")
pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def _callback(nx: int, ng: int, act: Any) -> Any:
    """An IPOPT iteration callback of an NLP with ``nx`` variables and ``ng`` rows that
    calls ``act()`` at every iteration."""

    class Hook(ca.Callback):
        def __init__(self) -> None:
            ca.Callback.__init__(self)
            self.construct("hook", {})

        def get_n_in(self) -> int:
            return ca.nlpsol_n_out()

        def get_n_out(self) -> int:
            return 1

        def get_sparsity_in(self, i: int) -> Any:
            name = ca.nlpsol_out(i)
            if name == "f":
                return ca.Sparsity.scalar()
            if name in ("x", "lam_x"):
                return ca.Sparsity.dense(nx)
            if name in ("g", "lam_g"):
                return ca.Sparsity.dense(ng)
            return ca.Sparsity(0, 0)

        def eval(self, arg: Any) -> list[int]:
            act()
            return [0]

    return Hook()


def _hooked_nlpsol(act: Any) -> Any:
    """``casadi.nlpsol`` whose IPOPT solvers call ``act()`` at every iteration."""
    real, hooks = ca.nlpsol, []  # CasADi keeps a reference only: keep the hooks alive

    def nlpsol(name: str, plugin: str, nlp: dict[str, Any], opts: Any = None) -> Any:
        ng = int(nlp["g"].numel()) if "g" in nlp else 0
        hooks.append(_callback(int(nlp["x"].numel()), ng, act))
        return real(name, plugin, nlp, {**(opts or {}), "iteration_callback": hooks[-1]})

    return nlpsol


@pytest.fixture
def ctrl_c_in_ipopt(monkeypatch):
    """``arm(at)``: Ctrl-C at the ``at``-th IPOPT iteration (counted over every solve
    built after it; once)."""

    def arm(at: int) -> None:
        calls = [0]

        def act() -> None:
            calls[0] += 1
            if calls[0] == at:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(5.0)  # cut short by the handler's KeyboardInterrupt

        monkeypatch.setattr(ca, "nlpsol", _hooked_nlpsol(act))

    return arm


def test_ctrl_c_taken_by_casadis_own_signal_check_is_an_interrupt(capsys):
    """The path of a real Ctrl-C: no Python callback, CasADi's check of signals in IPOPT.

    A Rosenbrock chain of 4000 variables from -1.2 runs IPOPT to its 3000 iterations in
    8 s (measured here, on a loaded 2-core machine); the SIGINT comes 0.3 s into the solve.
    """
    from microfab.core.interrupt import interruptible

    n = 4000
    x = ca.SX.sym("x", n)
    f = ca.sum1(100 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2)
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
            "ipopt.max_wall_time": 60.0}  # fmt: skip
    solver = ca.nlpsol("chain", "ipopt", {"x": x, "f": f}, opts)
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            interruptible(solver, x0=np.full(n, -1.2))
    finally:
        timer.cancel()
    assert solver.stats()["return_status"] == "NonIpopt_Exception_Thrown"
    assert "KeyboardInterruptException" not in capsys.readouterr().err  # CasADi's warning


def test_ctrl_c_in_stage_one_is_an_interrupt_not_a_stage1error(tiny_models, ctrl_c_in_ipopt):
    from microfab.geometry.shapes import circle
    from microfab.optimize.models import load_models
    from microfab.optimize.problem import ContourProblem
    from microfab.optimize.stage1 import Stage1Settings, solve_stage1

    models = load_models(tiny_models[0])
    problem = ContourProblem(circle(2e-3), a_max=2.0, tolerance_m=20e-6)
    before = signal.getsignal(signal.SIGINT)
    ctrl_c_in_ipopt(3)
    with pytest.raises(KeyboardInterrupt):
        solve_stage1(problem, models.linear, Stage1Settings(n=60))
    assert signal.getsignal(signal.SIGINT) is before


def test_ctrl_c_in_stage_one_of_a_job_point_saves_no_error(tiny_models, ctrl_c_in_ipopt, tmp_path):
    """The reference job saves a point whose stage 1 failed (`Stage1Error`) and reads it
    back on a rerun: a Ctrl-C taken for a failure was a permanent error there."""
    from microfab.geometry.shapes import circle
    from microfab.machines.xy_stage.machine import TwinSettings
    from microfab.machines.xy_stage.reference import saved_point
    from microfab.optimize.models import load_models
    from microfab.optimize.problem import ContourProblem

    problem = ContourProblem(circle(2e-3), a_max=2.0, tolerance_m=20e-6)
    ctrl_c_in_ipopt(3)
    with pytest.raises(KeyboardInterrupt):
        saved_point("c", problem, load_models(tiny_models[0]), twin=TwinSettings(),
                    stage2_max_iter=1, folder=tmp_path, fingerprint="f")  # fmt: skip
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_in_stage_two_keeps_the_checkpoint_and_a_rerun_resumes(
    case, ctrl_c_in_ipopt, tmp_path
):
    """Stage 2 on IPOPT's QP, Ctrl-C in its 5th QP: interrupted, not ended as converged."""
    from microfab.optimize.stage2 import Stage2Settings, solve_stage2

    models, problem, target, r_init = case
    st = Stage2Settings(max_iter=6, qp="ipopt", checkpoint_every=1)
    ckpt = str(tmp_path / "stage2.npz")
    kw = dict(rest=np.asarray(problem.path.start), tolerance_m=problem.tolerance_m,
              v_max=problem.v_max, a_max=problem.a_max, limits=problem.limits, settings=st,
              checkpoint=ckpt)  # fmt: skip
    ctrl_c_in_ipopt(40)  # IPOPT callbacks over all QPs (8-12 per QP here)
    with pytest.raises(KeyboardInterrupt):
        solve_stage2(target, r_init, models.networks, **kw)
    with np.load(ckpt, allow_pickle=False) as saved:  # whole: written atomically before
        assert "r" in saved.files
    # the rerun (the Ctrl-C was once) resumes from the checkpoint and ends by itself
    res = solve_stage2(target, r_init, models.networks, **kw)
    assert res.resumed_from >= 1
    assert res.iterations > res.resumed_from


def test_microfab_optimize_interrupted_in_ipopt_is_one_line_and_reruns(tmp_path):
    """A real Ctrl-C (SIGINT to the process group) while IPOPT runs stage 1."""
    marker = tmp_path / "ipopt-running"
    out = tmp_path / "opt"
    args = ["optimize", "circle:radius=0.002", "--out", str(out), "--stage", "1", "--n", "60",
            "--amax", "2"]  # fmt: skip
    # IPOPT's third iteration writes the marker and waits (up to 60 s) for the Ctrl-C
    driver = textwrap.dedent(
        f"""
        import sys, time
        from pathlib import Path
        import casadi as ca
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_interrupt import _hooked_nlpsol
        calls = [0]
        def act():
            calls[0] += 1
            if calls[0] == 3:
                Path({str(marker)!r}).write_text("3")
                time.sleep(60)
        ca.nlpsol = _hooked_nlpsol(act)
        from microfab.cli import app
        app(prog_name="microfab")
        """
    )
    # a file, not ``-c``: code run from a string defers Ctrl-C (`microfab.cli._sigint`)
    (tmp_path / "driver.py").write_text(driver)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "driver.py", *args], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, env=env)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert marker.exists() and proc.poll() is None, "IPOPT never reached iteration 3"
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    text = err.decode()
    assert proc.returncode == 130, text
    assert text.splitlines() == [
        "interrupted; what was saved is kept: rerun the same command to resume"
    ], text
    assert not out.exists()  # stage 1 writes nothing before it has converged
    # the same command again (no Ctrl-C) completes
    from typer.testing import CliRunner

    from microfab.cli import app

    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert (out / "command.csv").is_file()
