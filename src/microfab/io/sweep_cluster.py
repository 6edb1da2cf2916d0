"""The Dask side of `microfab.io.sweep.run_sweep`: scheduler address, cluster, workers.

What a sweep needs only off the in-process path: checking and connecting to a running
scheduler's address (`check_scheduler_address`, `CONNECT_TIMEOUT_S`), starting a
``LocalCluster`` of quiet, single-threaded worker processes or using the given one,
sending the task and its points to it as cloudpickle bytes and handing each outcome back
as it completes (`_run_on_cluster`; on the worker, `_run_pickled` sets the thread pools
first, as the module docstring of `microfab.io.sweep` says), and the Ctrl-C handling
around it (a cluster's start holds the signal, a cluster cut by it closes without Dask's
teardown logs). Kept apart from the sweep's points, keys and results folder
(`microfab.io.sweep`, which re-exports these names); ``dask.distributed`` is imported
only when a cluster is used.
"""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import re
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TypeVar

from microfab.core.memory import apply_allocator_policy
from microfab.core.threads import apply_thread_policy, policy_threads

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["CONNECT_TIMEOUT_S", "check_scheduler_address"]

P = TypeVar("P")  # a sweep point (as in `microfab.io.sweep`)

#: Seconds to wait for a Dask scheduler to answer before the sweep is refused.
CONNECT_TIMEOUT_S = 10.0

_ADDRESS = re.compile(
    r"(?:(?P<scheme>tcp|tls|ws|wss|ucx)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)"
    r":(?P<port>[0-9]{1,5})/?"
)


def check_scheduler_address(address: str) -> str:
    """``address`` if it names a Dask scheduler as ``[tcp://]host:port``, else ValueError.

    Parameters
    ----------
    address : str
        E.g. ``"tcp://10.0.0.5:8786"`` or ``"10.0.0.5:8786"``; a scheme of ``tcp``,
        ``tls``, ``ws``, ``wss`` or ``ucx``; an IPv6 host in brackets; a port 1-65535.

    Raises
    ------
    ValueError
        Naming the address and the form expected (checked before any connection).
    """
    m = _ADDRESS.fullmatch(address.strip()) if isinstance(address, str) else None
    if m is None or not 1 <= int(m["port"]) <= 65535:
        raise ValueError(
            f"scheduler {address!r} is not a Dask scheduler address; give "
            "[tcp://]HOST:PORT with a port 1-65535, e.g. tcp://10.0.0.5:8786"
        )
    return address.strip()


@contextlib.contextmanager
def _connect(address: str) -> Iterator[Client]:
    """A client of the scheduler at ``address``, or ValueError if it does not answer."""
    try:
        from distributed import Client
    except ImportError as exc:
        raise ImportError(
            "running a sweep on a Dask scheduler needs dask.distributed; install it with "
            "`pip install microfab[sweep]`"
        ) from exc
    try:
        client = Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s")
    except Exception as exc:  # whatever answers there (or nothing) is input
        # (a port of another service sends bytes Dask reads as a frame length of EiB)
        raise ValueError(
            f"no Dask scheduler answered at {address} (waited up to {CONNECT_TIMEOUT_S:g} s; "
            f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
        ) from exc
    with client:
        yield client


def _run_on_cluster(
    task: Callable[[P], Any],
    todo: list[P],
    finish: Callable[[P, Any], None],
    workers: int,
    scheduler: str | None,
    client: Client | None,
) -> None:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError as exc:
        raise ImportError(
            "running a sweep on worker processes needs dask.distributed; install it with "
            "`pip install microfab[sweep]`, or run with workers=1"
        ) from exc
    import cloudpickle  # a dependency of distributed

    try:
        blob = cloudpickle.dumps(task)  # once: a big closure is not pickled per point
        payloads = {p: cloudpickle.dumps(p) for p in todo}
    except Exception as exc:
        raise TypeError(
            f"cannot send the task {task!r} or its points to worker processes ({exc}); "
            "make the task a module-level function"
        ) from exc
    own = client is None and scheduler is None  # a local cluster of our own
    with contextlib.ExitStack() as stack:
        if client is None and scheduler is not None:
            client = stack.enter_context(Client(scheduler))
        elif client is None:
            # No dashboard, the scheduler's HTTP server on a free port (not a warning that
            # 8787 is taken), no worker logs: SweepError reports the failures.
            from distributed.deploy.spec import SpecCluster

            # Dask's registry of live clusters (closed at exit); private, so looked up
            instances = getattr(SpecCluster, "_instances", None)
            earlier = set(instances or ())
            with _quiet_workers() as held:
                try:
                    cluster = LocalCluster(
                        n_workers=workers,
                        threads_per_worker=1,
                        processes=True,
                        dashboard_address=None,
                        scheduler_kwargs={"dashboard_address": ":0"},
                        silence_logs=logging.CRITICAL,
                    )
                except Exception:
                    if held:  # the workers' start was cut by the Ctrl-C they heard too:
                        # close the half-started cluster now, quietly (left to Python's
                        # exit, Dask asserts on a worker still starting and prints it)
                        _silence_distributed_logs()
                        for half in set(instances or ()) - earlier:
                            with contextlib.suppress(Exception):
                                half.close(timeout=5)
                            instances.discard(half)  # type: ignore[union-attr]
                        raise KeyboardInterrupt from None
                    raise
            stack.enter_context(_closed_quietly_on_error(cluster))
            client = stack.enter_context(_closed_quietly_on_error(Client(cluster)))
            if held:  # Ctrl-C while the cluster started: taken now that it closes cleanly
                raise KeyboardInterrupt
        # pure=False: never reuse a result cached by the scheduler (a failed point retried
        # on the same client must run again).
        n = policy_threads(workers) if own else 1
        running = {client.submit(_run_pickled, blob, payloads[p], n, pure=False): p for p in todo}
        try:
            for fut in as_completed(list(running)):
                p = running.pop(fut)
                try:
                    outcome = fut.result()
                except Exception as exc:  # the task's error, cancelled, a lost worker...
                    outcome = exc
                fut.release()
                finish(p, outcome)
        finally:
            if running:  # interrupted (e.g. Ctrl-C or a progress callback raised)
                client.cancel(list(running))


@contextlib.contextmanager
def _quiet_workers() -> Iterator[list[int]]:
    """Start worker processes whose standard error goes nowhere; hold Ctrl-C meanwhile.

    A terminal's Ctrl-C goes to every process of its group, and each worker would print
    its own ``KeyboardInterrupt`` traceback under this process's one-line message. A
    spawned process inherits its standard error from this one, so file descriptor 2
    points at the null device while the cluster starts its workers and is restored after.
    Nothing of a worker's is lost that the sweep reports: a task's error, a lost worker or
    a cancelled point comes back to this process as a `SweepFailure`.

    A cluster interrupted half-way through its start cannot be closed cleanly (Dask
    asserts on a worker still starting), so a Ctrl-C in those seconds is held: the list
    yielded gets the signal's number, and the caller raises `KeyboardInterrupt` once the
    cluster is up and in its ``with`` block. This process's own lines in those seconds (a
    progress bar's redraw) are dropped.
    """
    held: list[int] = []
    handler = None
    if threading.current_thread() is threading.main_thread():
        handler = signal.signal(signal.SIGINT, lambda signum, _frame: held.append(signum))
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no file descriptor 2 to redirect: leave it
        saved = -1
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        if saved >= 0:
            os.dup2(null, 2)
        yield held
    finally:
        if saved >= 0:
            os.dup2(saved, 2)
            os.close(saved)
        os.close(null)
        if handler is not None:
            signal.signal(signal.SIGINT, handler)


@contextlib.contextmanager
def _closed_quietly_on_error(resource: Any) -> Iterator[Any]:
    """``resource`` closed on leaving; on an error, its close's own errors dropped.

    The error that stopped the sweep (a Ctrl-C) is the one reported: Dask may assert on
    closing a cluster whose workers that Ctrl-C killed.
    """
    try:
        yield resource
    except BaseException:
        _silence_distributed_logs()
        with contextlib.suppress(Exception):
            resource.close()
        raise
    resource.close()


def _silence_distributed_logs() -> None:
    """Drop Dask's log records from now on in this process: a sweep was cut by an error.

    A cluster torn down by a Ctrl-C (whose workers heard it too and are gone) logs its
    broken connections, with tracebacks, from its event-loop thread, and may do so while
    or after it closes (``distributed.batched``'s "Batched Comm Closed" at INFO). Those
    lines say nothing the error being reported does not, so the ``distributed`` logger is
    set above CRITICAL and left there, and so are its handlers (a child logger with a
    level of its own, ``distributed.client``, still reaches them): the caller is reporting
    that error (the command line exits on it). A program that goes on using Dask after an
    interrupted sweep can set those levels back.
    """
    logger = logging.getLogger("distributed")
    logger.setLevel(logging.CRITICAL + 1)
    for handler in logger.handlers:
        handler.setLevel(logging.CRITICAL + 1)


def _run_pickled(task: bytes, point: bytes, threads: int = 1) -> Any:
    # On a worker. Task and point travel as cloudpickle bytes and are unpickled here, so a
    # worker that cannot import the task's module fails that point (reported) instead of
    # its connection to the scheduler (a hang), and modules registered with
    # cloudpickle.register_pickle_by_value (e.g. test modules) travel by value. The thread
    # pools are set first (module docstring), as the task's libraries may load with it.
    apply_allocator_policy()
    apply_thread_policy(threads=threads)
    return pickle.loads(task)(pickle.loads(point))
