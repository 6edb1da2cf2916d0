"""Timing and peak-memory helpers shared by the benchmark scripts.

* `timed`: the wall time of one call, with its result (optionally after a garbage
  collection outside the timing).
* `best`: the shortest wall time of a few calls (the machine may be shared: the minimum is
  the least disturbed figure), with the last call's result.
* `traced_peak`: the largest amount of memory Python and NumPy held at once during one
  call, above what they held before it (`tracemalloc`; NumPy reports its array buffers to
  it; memory that numba kernels or LAPACK allocate outside NumPy is not seen).
* `in_child`: one call in a fresh process (``spawn``), after a loading step, with its wall
  time and the process's peak resident memory over the call (Linux ``VmHWM``, reset after
  loading through ``/proc/self/clear_refs``; elsewhere ``ru_maxrss``, which then includes
  the loading). The fresh process sees no memory of earlier benchmarks, and a call that
  runs out of memory takes down only the child.

Import as ``from _timing import best`` from a script in this folder (run as
``python benchmarks/<script>.py``, the folder is on ``sys.path``).
"""

from __future__ import annotations

import gc
import multiprocessing as mp
import resource
import sys
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

MB = 1e6  # bytes; memory is printed in MB and GB of 1e6 and 1e9 bytes


def timed(fn: Callable[[], Any], *, collect: bool = False) -> tuple[float, Any]:
    """Wall time of one call of ``fn``, s, and its result.

    With ``collect``, garbage left by earlier calls (reference cycles that only the cyclic
    collector frees, such as an ezdxf document) is collected first, outside the timing, so
    that this call does not pay for another's.
    """
    if collect:
        gc.collect()
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def best(fn: Callable[[], Any], repeats: int = 3, *, collect: bool = False) -> tuple[float, Any]:
    """Shortest wall time of ``repeats`` calls of ``fn``, s, and the last call's result.

    An earlier call's result is let go before the next call starts, so no call runs with
    the memory of another's result held. ``collect`` as in `timed`, before each call.
    """
    t_best = float("inf")
    out = None
    for _ in range(max(1, repeats)):
        out = None
        t, out = timed(fn, collect=collect)
        t_best = min(t_best, t)
    return t_best, out


def traced_peak(fn: Callable[[], Any]) -> tuple[Any, int]:
    """Result of ``fn()`` and the peak of traced allocations during it, bytes.

    The peak counts what was allocated during the call above what was held at its start
    (arrays alive before the call, such as the input data, are not counted).
    """
    was_tracing = tracemalloc.is_tracing()
    if not was_tracing:
        tracemalloc.start()
    tracemalloc.reset_peak()
    start, _ = tracemalloc.get_traced_memory()
    try:
        out = fn()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        if not was_tracing:
            tracemalloc.stop()
    return out, max(0, peak - start)


def _status_kb(key: str) -> int | None:
    """A ``/proc/self/status`` field in kB (``VmRSS``, ``VmHWM``), or None off Linux."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def rss_bytes() -> int:
    """Resident memory of this process now, bytes (0 where unknown)."""
    kb = _status_kb("VmRSS")
    return 1024 * kb if kb is not None else 0


def reset_peak_rss() -> bool:
    """Reset this process's peak resident memory to its current value (Linux); success."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        return False
    return True


def peak_rss_bytes() -> int:
    """Peak resident memory of this process, bytes (``VmHWM``, else ``ru_maxrss``)."""
    kb = _status_kb("VmHWM")
    if kb is None:
        kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        if sys.platform == "darwin":  # bytes there
            return int(kb)
    return 1024 * kb


@dataclass(frozen=True)
class ChildRun:
    """What `in_child` measured.

    Attributes
    ----------
    result : Any
        What the work returned (pickled back).
    wall_s : float
        Wall time of the work alone, s.
    base_rss : int
        Resident memory after loading, before the work, bytes.
    peak_rss : int
        Peak resident memory of the process during the work, bytes (interpreter,
        libraries and loaded data included).
    peak_reset : bool
        Whether the peak could be reset after loading (else it may come from loading).
    traced : int
        Peak of `tracemalloc`-traced allocations during the work above its start, bytes
        (0 unless asked for).
    """

    result: Any
    wall_s: float
    base_rss: int
    peak_rss: int
    peak_reset: bool
    traced: int

    @property
    def added_rss(self) -> int:
        """Peak resident memory above the post-loading level, bytes."""
        return max(0, self.peak_rss - self.base_rss)


def _child(conn: Any, load: Callable[..., Any], load_args: tuple, work: Callable, trace: bool):
    try:
        data = load(*load_args)
        if trace:
            tracemalloc.start()
        base = rss_bytes()
        reset = reset_peak_rss()
        t0 = time.perf_counter()
        if trace:
            out, traced = traced_peak(lambda: work(data))
        else:
            out, traced = work(data), 0
        wall = time.perf_counter() - t0
        peak = peak_rss_bytes()
        conn.send(("ok", ChildRun(out, wall, base, peak, reset, traced)))
    except BaseException as exc:  # report any failure (MemoryError included) to the parent
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def in_child(
    load: Callable[..., Any],
    load_args: tuple,
    work: Callable[[Any], Any],
    *,
    trace: bool = False,
    timeout_s: float | None = None,
    repeats: int = 1,
) -> ChildRun:
    """Run ``work(load(*load_args))`` in a fresh process; time and memory of ``work`` alone.

    ``load`` and ``work`` must be importable module-level functions (``spawn`` pickles
    them by name). With ``repeats`` > 1, as many fresh processes run one after the other
    and the fastest run is returned (its memory; the others' differ only by noise).
    Raises `RuntimeError` with the child's message when it fails or dies.
    """
    runs = [_one_child(load, load_args, work, trace, timeout_s) for _ in range(max(1, repeats))]
    return min(runs, key=lambda r: r.wall_s)


def _one_child(
    load: Callable[..., Any],
    load_args: tuple,
    work: Callable[[Any], Any],
    trace: bool,
    timeout_s: float | None,
) -> ChildRun:
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, load, load_args, work, trace))
    proc.start()
    child.close()
    try:
        if not parent.poll(timeout_s):
            proc.kill()
            raise RuntimeError(f"child ran past {timeout_s} s and was stopped")
        status, payload = parent.recv()
    except EOFError:
        proc.join()
        raise RuntimeError(f"child died (exit code {proc.exitcode})") from None
    finally:
        proc.join()
    if status != "ok":
        raise RuntimeError(f"child failed: {payload}")
    return payload
