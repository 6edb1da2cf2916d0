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

`apply_thread_policy` is the process-wide rule on top of both: every thread pool of the
process (NumPy's and SciPy's OpenBLAS, the OpenBLAS bundled with CasADi's Ipopt, PyTorch's
OpenMP, numba's) gets `policy_threads` threads, one unless ``MICROFAB_THREADS`` says
otherwise, and the same environment variables go to every process this one starts. Work
runs side by side in worker processes instead (sweeps, the networks' axes, the reference
points), at most one per core, so that workers × threads ≤ cores. Measured on a 2-core
machine: the reference example (``examples/blackbox_stage_reference.toml``) took 3 min 34 s
with the default two threads per pool, 208 s user and 180 s system time, and 3 min 32 s
with one, 27 s system: an idle OpenBLAS thread waits for work by spinning on
``sched_yield``, system time that buys nothing on matrices as small as microfab's.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
from collections.abc import Callable, Iterator
from typing import Any, ParamSpec, TypeVar

__all__ = [
    "THREAD_ENV",
    "apply_thread_policy",
    "blas_kernels",
    "one_blas_thread",
    "policy_threads",
    "single_threaded",
    "thread_counts",
    "usable_cores",
]

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


#: The environment variables the thread pools read when their library loads.
#: `apply_thread_policy` sets them for the libraries not loaded yet and for every process
#: started from this one (a spawned worker reads them before it imports anything).
THREAD_ENV = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS",
)

#: Threads per pool when ``MICROFAB_THREADS`` is not set. Assumed from the measurement in
#: the module docstring: a second thread per pool gained no wall time and cost 6x the
#: system time; parallel work is spread over processes instead.
DEFAULT_THREADS = 1

#: Environment variable that overrides `DEFAULT_THREADS` (an integer ≥ 1).
THREADS_VAR = "MICROFAB_THREADS"


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity; the CPU count off Linux)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def policy_threads(workers: int = 1) -> int:
    """Threads per pool for one of ``workers`` processes running side by side.

    Parameters
    ----------
    workers : int
        Processes that compute at the same time (this one included), at least 1.

    Returns
    -------
    int
        ``MICROFAB_THREADS`` if set, else `DEFAULT_THREADS`, and at most
        ``usable_cores() // workers`` (but at least 1), so that workers × threads ≤ cores
        whenever workers ≤ cores.

    Raises
    ------
    ValueError
        ``MICROFAB_THREADS`` is not an integer ≥ 1, or ``workers`` < 1.
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    text = os.environ.get(THREADS_VAR, "").strip()
    if text:
        try:
            asked = int(text)
        except ValueError:
            asked = 0
        if asked < 1:
            raise ValueError(f"{THREADS_VAR} must be an integer of at least 1, got {text!r}")
    else:
        asked = DEFAULT_THREADS
    return max(1, min(asked, usable_cores() // workers))


@functools.cache
def _register_bundled_blas() -> None:
    """Make `threadpoolctl` see the OpenBLAS that CasADi bundles for Ipopt.

    ``libcasadi-tp-openblas`` is loaded with Ipopt's first solver; threadpoolctl knows
    OpenBLAS only by its usual file names, so without this its two threads (one spinning
    while Ipopt factorises) escape every limit.
    """
    import threadpoolctl

    class _CasadiOpenBLAS(threadpoolctl.OpenBLASController):  # type: ignore[misc]
        filename_prefixes = ("libcasadi-tp-openblas",)

    threadpoolctl.register(_CasadiOpenBLAS)


def apply_thread_policy(workers: int = 1, *, threads: int | None = None) -> int:
    """Set every thread pool of this process, and of those it starts, to `policy_threads`.

    Called once when the ``microfab`` command starts and in every sweep worker before its
    task; calling it again is cheap and sets the same. Covers the BLAS and OpenMP
    libraries loaded now (through `threadpoolctl`, CasADi's bundled OpenBLAS included),
    PyTorch's intra-op threads if it is imported, numba's pool if it was started, and
    `THREAD_ENV` for what loads later and for child processes.

    Parameters
    ----------
    workers : int
        Processes that compute side by side, this one included (see `policy_threads`).
    threads : int, optional
        This count instead of `policy_threads` (a sweep worker gets its parent's).

    Returns
    -------
    int
        The threads per pool now set.

    Raises
    ------
    ValueError
        As `policy_threads`, or ``threads`` < 1.
    """
    n = policy_threads(workers) if threads is None else threads
    if n < 1:
        raise ValueError(f"threads must be at least 1, got {n}")
    for name in THREAD_ENV:
        os.environ[name] = str(n)
    _register_bundled_blas()
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=n)  # called, not entered: the limits stay
    torch = sys.modules.get("torch")
    if torch is not None and torch.get_num_threads() != n:
        torch.set_num_threads(n)
    if _numba_pool_started():  # asking an idle numba would start its threads
        import numba

        numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    return n


def thread_counts() -> dict[str, int]:
    """Threads of each pool of this process (for checks and reports).

    Returns
    -------
    dict of str to int
        ``"<user_api>:<library file>"`` for every library `threadpoolctl` finds (CasADi's
        OpenBLAS once Ipopt is loaded), ``"torch"`` if PyTorch is imported, ``"numba"``
        if numba's pool was started.
    """
    _register_bundled_blas()
    from threadpoolctl import threadpool_info

    out = {
        f"{i['user_api']}:{os.path.basename(i['filepath'])}": int(i["num_threads"])
        for i in threadpool_info()
    }
    torch = sys.modules.get("torch")
    if torch is not None:
        out["torch"] = int(torch.get_num_threads())
    if _numba_pool_started():
        import numba

        out["numba"] = int(numba.get_num_threads())
    return out


def _numba_pool_started() -> bool:
    """Whether numba started its thread pool.

    Only ``parallel=True`` kernels start it; microfab has none, so its pool holds no
    threads unless another library's kernel ran.
    """
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    return parallel is not None and bool(getattr(parallel, "_is_initialized", False))
