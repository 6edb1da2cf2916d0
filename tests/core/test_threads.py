from __future__ import annotations

import numpy as np
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
