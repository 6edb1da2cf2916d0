"""Run numerical work on one BLAS/LAPACK thread, so its result does not depend on the core count.

A multithreaded BLAS splits a matrix product or factorisation among its threads, and the
order of the partial sums, hence the last bits of the result, changes with the number of
threads. For most of microfab that is harmless. For the drop-on-demand model it is not:
the breakup of a viscoelastic thread is sensitive to the last bits of its input (at 1 %
NaAlg, 50 V, the acoustic flow computed with two OpenBLAS threads gave a breakup at
258 µs, with one thread at 126 µs). A sweep point run in this process (BLAS threads =
cores) and on a Dask worker (one thread) then disagreed. Every such computation runs
under `single_threaded`, so a point gives one answer whichever command, process or
machine core count runs it. Different BLAS builds or CPU kernels may still round
differently; that is a limit of floating point, not of this guard.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

__all__ = ["single_threaded"]

P = ParamSpec("P")
R = TypeVar("R")


def single_threaded(fn: Callable[P, R]) -> Callable[P, R]:
    """Decorate ``fn`` to run with BLAS/LAPACK (and OpenMP) limited to one thread.

    The previous limits are restored on return. Uses ``threadpoolctl``.

    Examples
    --------
    >>> import numpy as np
    >>> @single_threaded
    ... def gram(a):
    ...     return a.T @ a
    >>> gram(np.eye(2)).tolist()
    [[1.0, 0.0], [0.0, 1.0]]
    """
    from threadpoolctl import threadpool_limits

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with threadpool_limits(limits=1):
            return fn(*args, **kwargs)

    return wrapper
