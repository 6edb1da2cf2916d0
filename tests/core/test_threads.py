from __future__ import annotations

import os

import numpy as np
import pytest
from threadpoolctl import threadpool_info

from microfab.core.threads import single_threaded


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_single_threaded_limits_blas_inside_and_restores_after() -> None:
    before = _blas_threads()

    @single_threaded
    def work(a: np.ndarray) -> tuple[np.ndarray, list[int]]:
        """Docstring kept."""
        return a @ a, _blas_threads()

    out, inside = work(np.eye(3))
    assert np.array_equal(out, np.eye(3))
    assert all(n == 1 for n in inside)
    assert _blas_threads() == before
    assert work.__doc__ == "Docstring kept."


def test_one_blas_thread_limits_inside_nests_and_restores_after() -> None:
    from microfab.core.threads import one_blas_thread

    before = _blas_threads()
    with one_blas_thread():
        assert all(n == 1 for n in _blas_threads())
        with one_blas_thread():
            assert all(n == 1 for n in _blas_threads())
        assert all(n == 1 for n in _blas_threads())
    assert _blas_threads() == before


# -- the process-wide policy (issue 43: workers × threads ≤ cores) ---------------------


def test_policy_threads_default_override_and_cap(monkeypatch) -> None:
    from microfab.core import threads

    monkeypatch.setattr(threads, "usable_cores", lambda: 4)
    monkeypatch.delenv(threads.THREADS_VAR, raising=False)
    assert threads.policy_threads() == threads.DEFAULT_THREADS == 1
    monkeypatch.setenv(threads.THREADS_VAR, "8")
    assert [threads.policy_threads(w) for w in (1, 2, 3, 4, 8)] == [4, 2, 1, 1, 1]
    for bad in ("0", "-1", "two", "1.5"):
        monkeypatch.setenv(threads.THREADS_VAR, bad)
        with pytest.raises(ValueError, match=threads.THREADS_VAR):
            threads.policy_threads()


def test_apply_thread_policy_sets_loaded_pools_and_the_environment(monkeypatch) -> None:
    from threadpoolctl import threadpool_limits

    from microfab.core import threads

    for name in threads.THREAD_ENV:  # restored after the test
        monkeypatch.setenv(name, "7")
    with threadpool_limits(limits=2):  # the pools' counts come back on leaving
        assert threads.apply_thread_policy(threads=1) == 1
        counts = threads.thread_counts()
        assert counts and set(counts.values()) == {1}, counts
        assert all(os.environ[name] == "1" for name in threads.THREAD_ENV)


def test_the_command_applies_the_policy_and_refuses_a_bad_setting(monkeypatch) -> None:
    from threadpoolctl import threadpool_limits
    from typer.testing import CliRunner

    from microfab.cli import app
    from microfab.core import threads

    for name in threads.THREAD_ENV:
        monkeypatch.setenv(name, "7")
    monkeypatch.delenv(threads.THREADS_VAR, raising=False)
    with threadpool_limits(limits=2):
        assert CliRunner().invoke(app, ["--version"]).exit_code == 0
        assert set(threads.thread_counts().values()) == {1}
        assert os.environ["OMP_NUM_THREADS"] == "1"
    res = CliRunner().invoke(app, ["--version"], env={threads.THREADS_VAR: "none"})
    assert res.exit_code == 2
    assert res.output.splitlines() == [
        "error: MICROFAB_THREADS must be an integer of at least 1, got 'none'"
    ]
