"""A real Ctrl-C (SIGINT to the whole process group, as a terminal sends it).

The command prints one ``interrupted`` line and exits 130; the sweep's worker processes,
which hear the same Ctrl-C, print nothing — before the cluster is up, while it starts and
while it runs.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX process groups")

MICROFAB = [sys.executable, "-m", "microfab"]


def _interrupt(args: list[str], cwd: Path, when: float | Path) -> tuple[int, str]:
    """Run ``microfab args``, send SIGINT to its group at ``when`` (seconds, or once the
    path exists), and return the exit code and standard error."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [*MICROFAB, *args],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        env=env,
    )
    try:
        if isinstance(when, Path):
            deadline = time.monotonic() + 120
            while not when.exists() and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
        else:
            time.sleep(when)
        assert proc.poll() is None, "the command ended before it could be interrupted"
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    return proc.returncode, err.decode()


@pytest.mark.parametrize(
    "when",
    [1.5, 3.0, "running"],
    ids=["while-starting", "while-the-cluster-starts", "while-points-run"],
)
def test_ctrl_c_during_a_sweep_on_workers_is_one_line(tmp_path: Path, when: object) -> None:
    out = tmp_path / "sweep"
    at = out / "sweep" / "points" if when == "running" else when
    code, err = _interrupt(
        ["droplet", "sweep", "--workers", "2", "--duration", "400", "--out", str(out)],
        tmp_path,
        at,  # type: ignore[arg-type]
    )
    assert code == 130, err
    assert err.splitlines() == [
        "interrupted; what was saved is kept: rerun the same command to resume"
    ], err
