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

`one_blas_thread` is the same guard as a cheap context manager for code entered many
times a second with small matrix products (the lifted LTI simulator): a thread team gains
nothing on them, and on a busy machine its threads wait for cores (a 10 000-sample period
took 24 ms instead of 0.2 ms).
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator
from typing import Any, ParamSpec, TypeVar

__all__ = ["blas_kernels", "one_blas_thread", "single_threaded"]

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


_depth = 0  # nesting depth of `one_blas_thread` (the BLAS thread count is process-wide)


@functools.cache
def _blas_libraries() -> tuple[Any, ...]:
    """The BLAS libraries' `threadpoolctl` controllers (inspecting them once is slow)."""
    from threadpoolctl import ThreadpoolController

    return tuple(ThreadpoolController().select(user_api="blas").lib_controllers)


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Limit BLAS to one thread inside the block; restored on exit. Nesting is free.

    Talks to the libraries found by `threadpoolctl` on first use directly (a few µs per
    block, where ``threadpool_limits`` takes some 300 µs).

    Examples
    --------
    >>> import numpy as np
    >>> with one_blas_thread():
    ...     (np.eye(2) @ np.eye(2)).tolist()
    [[1.0, 0.0], [0.0, 1.0]]
    """
    global _depth
    if _depth:
        yield
        return
    libs = _blas_libraries()
    before = [lib.get_num_threads() for lib in libs]
    for lib, n in zip(libs, before, strict=True):
        if n != 1:
            lib.set_num_threads(1)
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        for lib, n in zip(libs, before, strict=True):
            if n != 1:
                lib.set_num_threads(n)


def blas_kernels() -> tuple[str, ...]:
    """The BLAS kernel families loaded in this process (e.g. ``("Haswell",)`` for OpenBLAS).

    A single-threaded computation is repeatable on one machine, but two OpenBLAS kernel
    families (chosen by the processor, or forced with ``OPENBLAS_CORETYPE``) round some
    products differently in the last bit; a chaotic computation such as a jet that is
    close to pinching can then end another way. Benchmarks and tests name the kernel with
    such a result.

    Returns
    -------
    tuple of str
        Sorted, distinct ``architecture`` names as threadpoolctl reports them (empty when
        none is reported).
    """
    import numpy  # noqa: F401  (loads NumPy's BLAS)
    import scipy.linalg  # noqa: F401  (and SciPy's)
    from threadpoolctl import threadpool_info

    return tuple(
        sorted({str(i["architecture"]) for i in threadpool_info() if i.get("architecture")})
    )
