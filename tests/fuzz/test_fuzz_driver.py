"""The fuzz driver's hang: CPU time used, or none used, never wall time (issue 43)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fuzz_driver
from fuzz_driver import CaseTimeoutError, _alarm, cpu_seconds

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="SIGALRM, pthread_kill")


def _spin(seconds: float) -> None:
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_a_case_that_computes_past_its_cpu_time_is_a_hang() -> None:
    t0 = time.monotonic()
    with pytest.raises(CaseTimeoutError, match=r"over 0.5 s of CPU"), _alarm(0.5):
        _spin(30.0)
    assert time.monotonic() - t0 < 20.0  # caught long before the loop's own end


def test_a_case_that_waits_without_progress_is_a_hang() -> None:
    with pytest.raises(CaseTimeoutError, match="no progress"), _alarm(1.0):
        time.sleep(30.0)


def test_a_slow_case_that_makes_progress_is_not_a_hang(monkeypatch) -> None:
    """Wall time beyond the limit is no hang while the case keeps using CPU (load)."""
    monkeypatch.setattr(fuzz_driver, "WATCH_EVERY_S", 0.1)
    start = cpu_seconds()
    t0 = time.monotonic()
    with _alarm(1.0):  # 1 s of CPU allowed; the loop uses ~0.15 s of it in >1 s of wall
        while time.monotonic() - t0 < 1.5:
            _spin(0.01)
            time.sleep(0.09)  # 10 % of a core: a process sharing 2 cores with 20
    assert cpu_seconds() - start < 1.0


def test_cpu_seconds_counts_the_processes_a_case_started() -> None:
    before = cpu_seconds()
    code = "import time\nend = time.process_time() + 0.3\nwhile time.process_time() < end: pass"
    child = subprocess.Popen([sys.executable, "-c", code])
    seen = before
    while child.poll() is None:
        seen = max(seen, cpu_seconds())
        time.sleep(0.02)
    # while it ran, or once waited for (children's times): 0.3 s of it, minus the last look
    assert cpu_seconds() - before >= 0.25, (before, seen, cpu_seconds(), os.getpid())
