"""Tests of the generic sweep runner: in-process path and a real dask LocalCluster."""

from __future__ import annotations

import contextlib
import json
import logging
import multiprocessing
import os
import sys
import threading
import types
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
import pytest

from microfab.io.sweep import (
    SweepError,
    SweepResult,
    grid,
    load_results,
    point_key,
    run_sweep,
)

# Worker processes must unpickle this module's tasks and point class, but with
# --import-mode=importlib they cannot import it by name: send them by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@dataclass(frozen=True)
class Pt:
    a: int
    b: str = "x"


def square(p: Pt) -> dict[str, Any]:
    return {"sq": p.a * p.a, "pid": os.getpid()}


def fail_on_3(p: Pt) -> dict[str, Any]:
    if p.a == 3:
        raise ValueError("three is bad\nsecond line")
    return square(p)


class Recorder:
    """In-process task that records the points it ran."""

    def __init__(self, fail: int | None = None, interrupt: int | None = None) -> None:
        self.ran: list[Pt] = []
        self.fail = fail
        self.interrupt = interrupt

    def __call__(self, p: Pt) -> dict[str, Any]:
        if p.a == self.interrupt:
            raise KeyboardInterrupt
        self.ran.append(p)
        if p.a == self.fail:
            raise ValueError("three is bad\nsecond line")
        return {"sq": p.a * p.a, "pid": os.getpid()}


def pts(*a: int) -> list[Pt]:
    return [Pt(a=i) for i in a]


def saved_keys(d: Path) -> set[str]:
    return {f.stem for f in (d / "points").glob("*.json")}


# -- grid and keys ---------------------------------------------------------------------


def test_grid_is_cartesian_product_last_name_fastest() -> None:
    g = grid(Pt, a=[2, 1], b=["u", "v"])
    assert g == [Pt(2, "u"), Pt(2, "v"), Pt(1, "u"), Pt(1, "v")]
    assert grid(Pt, a=[1, 1, 2]) == [Pt(1), Pt(2)]
    assert grid(Pt, a=[], b=["u"]) == []
    with pytest.raises(TypeError, match="'c'"):
        grid(Pt, a=[1], c=[2])


def test_point_key_is_stable_readable_and_filename_safe() -> None:
    # a fixed value (SHA-256 of '{"a":1,"b":"x"}'): a change would orphan saved sweeps
    assert point_key(Pt(1)) == "a=1,b=x-ecf9e98ec064"
    assert point_key(Pt(1, "1")) != point_key(Pt(1)) != point_key(Pt(2))
    weird = point_key(Pt(1, "a/b c:*"))
    assert weird.startswith("a=1,b=a_b_c__-")
    # escaping gives both the same readable part; the hash keeps them apart
    assert point_key(Pt(1, "a/b")) != point_key(Pt(1, "a:b"))
    assert len(point_key(Pt(1, "z" * 500))) == 80 + 1 + 12


# -- in-process path -------------------------------------------------------------------


def test_in_process_rows_in_point_order_saved_after_each_point(tmp_path: Path) -> None:
    task = Recorder()
    calls: list[tuple[int, int, Pt, bool]] = []

    def progress(done: int, total: int, p: Pt, ok: bool) -> None:
        # the point is on disk when its progress is reported, and only the points so far
        assert point_key(p) in saved_keys(tmp_path)
        assert len(saved_keys(tmp_path)) == done
        calls.append((done, total, p, ok))

    res = run_sweep(task, pts(3, 1, 2), results_dir=tmp_path, progress=progress)
    assert [r["a"] for r in res.rows] == [3, 1, 2]
    assert [r["sq"] for r in res.rows] == [9, 1, 4]
    assert {r["pid"] for r in res.rows} == {os.getpid()}  # no worker processes
    assert res.rows[0] == {"a": 3, "b": "x", "sq": 9, "pid": os.getpid()}
    assert calls == [(1, 3, Pt(3), True), (2, 3, Pt(1), True), (3, 3, Pt(2), True)]
    assert res.failed == () and res.skipped == ()
    assert load_results(tmp_path) == list(res.rows)
    saved = json.loads((tmp_path / "points" / f"{point_key(Pt(1))}.json").read_text())
    assert saved["point"] == {"a": 1, "b": "x"} and saved["row"]["sq"] == 1


def test_interrupted_sweep_keeps_finished_points_and_resumes(tmp_path: Path) -> None:
    with pytest.raises(KeyboardInterrupt):
        run_sweep(Recorder(interrupt=3), pts(1, 2, 3, 4), results_dir=tmp_path)
    assert saved_keys(tmp_path) == {point_key(Pt(1)), point_key(Pt(2))}
    task = Recorder()
    seen: list[int] = []
    res = run_sweep(
        task, pts(1, 2, 3, 4), results_dir=tmp_path, progress=lambda d, t, p, ok: seen.append(d)
    )
    assert task.ran == pts(3, 4)
    assert res.skipped == tuple(pts(1, 2))
    assert seen == [3, 4]
    assert [r["a"] for r in res.rows] == [1, 2, 3, 4]


def test_rerun_skips_done_points_and_grid_can_grow(tmp_path: Path) -> None:
    first = Recorder()
    run_sweep(first, pts(1, 2), results_dir=tmp_path, settings={"duration_s": 1e-4})
    again = Recorder()
    res = run_sweep(again, pts(2, 3, 1), results_dir=tmp_path, settings={"duration_s": 1e-4})
    assert first.ran == pts(1, 2) and again.ran == pts(3)
    assert [r["a"] for r in res.rows] == [2, 3, 1]
    assert res.skipped == tuple(pts(2, 1))
    # load order: order first asked for; an explicit list picks and orders
    assert [r["a"] for r in load_results(tmp_path)] == [1, 2, 3]
    assert [r["a"] for r in load_results(tmp_path, pts(3, 9, 1))] == [3, 1]


def test_other_settings_refused_naming_the_difference(tmp_path: Path) -> None:
    run_sweep(Recorder(), pts(1), results_dir=tmp_path, settings={"duration_s": 1e-4, "n": 2})
    task = Recorder()
    with pytest.raises(ValueError) as err:
        run_sweep(task, pts(1), results_dir=tmp_path, settings={"duration_s": 2e-4, "n": 2})
    msg = str(err.value)
    assert "holds a sweep of other settings: duration_s 0.0001 -> 0.0002;" in msg
    assert " n " not in msg
    assert "another results directory" in msg and f"remove {tmp_path}" in msg
    assert task.ran == []
    with pytest.raises(ValueError, match=r"n 2 -> \(absent\)"):
        run_sweep(task, pts(1), results_dir=tmp_path, settings={"duration_s": 1e-4})
    (tmp_path / "settings.json").write_text('{"format": 1, "sett')  # cut short
    with pytest.raises(ValueError, match="not a readable sweep settings file"):
        run_sweep(task, pts(1), results_dir=tmp_path, settings={"duration_s": 1e-4})
    assert task.ran == []


def test_failing_point_isolated_others_saved_then_retried(tmp_path: Path) -> None:
    task = Recorder(fail=3)
    with pytest.raises(SweepError) as err:
        run_sweep(task, pts(1, 2, 3, 4, 5), results_dir=tmp_path)
    assert isinstance(err.value, RuntimeError)
    msg = str(err.value)
    assert "Pt(a=3, b='x'): ValueError: three is bad" in msg
    assert "second line" not in msg and "1 sweep point(s) failed" in msg
    assert task.ran == pts(1, 2, 3, 4, 5)
    res = err.value.result
    assert [r["a"] for r in res.rows] == [1, 2, 4, 5]
    assert [f.point for f in res.failed] == [Pt(3)]
    assert res.failed[0].error == "ValueError: three is bad"
    assert point_key(Pt(3)) not in saved_keys(tmp_path)
    assert len(saved_keys(tmp_path)) == 4
    retry = Recorder()
    res2 = run_sweep(retry, pts(1, 2, 3, 4, 5), results_dir=tmp_path)
    assert retry.ran == pts(3)
    assert [r["sq"] for r in res2.rows] == [1, 4, 9, 16, 25]


def test_failures_returned_when_not_raising() -> None:
    oks: list[bool] = []
    res = run_sweep(
        Recorder(fail=3),
        pts(3, 4),
        raise_on_failure=False,
        progress=lambda d, t, p, ok: oks.append(ok),
    )
    assert isinstance(res, SweepResult)
    assert [f.point for f in res.failed] == [Pt(3)]
    assert [r["a"] for r in res.rows] == [4]
    assert oks == [False, True]


def test_unsaveable_results_are_failures(tmp_path: Path) -> None:
    def bad(p: Pt) -> Any:
        return {"x": float("nan")} if p.a == 1 else [p.a] if p.a == 2 else {"x": np.float64(2)}

    res = run_sweep(bad, pts(1, 2, 3), results_dir=tmp_path, raise_on_failure=False)
    assert [f.point for f in res.failed] == pts(1, 2)
    assert res.failed[0].error.startswith("ValueError")
    assert res.failed[1].error == "TypeError: task returned list, not a dict"
    assert res.rows == ({"a": 3, "b": "x", "x": 2.0},)
    assert type(res.rows[0]["x"]) is float
    assert saved_keys(tmp_path) == {point_key(Pt(3))}


def test_validation(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="workers must be at least 1, got 0"):
        run_sweep(Recorder(), pts(1), workers=0)
    with pytest.raises(ValueError, match="scheduler or client, not both"):
        run_sweep(Recorder(), pts(1), scheduler="tcp://x:1", client=object())  # type: ignore[arg-type]

    @dataclass
    class Mutable:
        a: int

    with pytest.raises(TypeError, match="frozen"):
        run_sweep(Recorder(), [Mutable(1)])

    @dataclass(frozen=True)
    class Other:
        a: int

    with pytest.raises(TypeError, match="one type"):
        run_sweep(Recorder(), [Pt(1), Other(1)])
    task = Recorder()
    res = run_sweep(task, pts(2, 1, 2, 1))
    assert task.ran == pts(2, 1) and len(res.rows) == 2
    empty = run_sweep(Recorder(), [], results_dir=tmp_path / "e", workers=4)
    assert empty.rows == () and empty.failed == () and empty.skipped == ()
    assert load_results(tmp_path / "e") == []
    with pytest.raises(FileNotFoundError, match="holds no sweep"):
        load_results(tmp_path / "nothing")


# -- distributed path on a real LocalCluster -------------------------------------------


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": ":0"},
        silence_logs=logging.CRITICAL,
    ) as c:
        yield c


@pytest.fixture(scope="module")
def client(cluster):
    from distributed import Client

    with Client(cluster) as c:
        yield c


def test_cluster_runs_points_in_worker_processes(client, tmp_path: Path) -> None:
    seen: list[tuple[int, int]] = []
    res = run_sweep(
        square,
        pts(5, 4, 3, 2, 1, 0),
        results_dir=tmp_path,
        client=client,
        progress=lambda d, t, p, ok: seen.append((d, t)),
    )
    assert [r["a"] for r in res.rows] == [5, 4, 3, 2, 1, 0]
    assert [r["sq"] for r in res.rows] == [25, 16, 9, 4, 1, 0]
    pids = {r["pid"] for r in res.rows}
    assert os.getpid() not in pids
    assert seen == [(i, 6) for i in range(1, 7)]
    assert load_results(tmp_path) == list(res.rows)
    assert client.status == "running"  # a caller's client is left open


def test_cluster_failure_isolated_then_retried(client, tmp_path: Path) -> None:
    oks: dict[int, bool] = {}
    res = run_sweep(
        fail_on_3,
        pts(1, 2, 3, 4),
        results_dir=tmp_path,
        client=client,
        raise_on_failure=False,
        progress=lambda d, t, p, ok: oks.__setitem__(p.a, ok),
    )
    assert [f.point for f in res.failed] == [Pt(3)]
    assert res.failed[0].error == "ValueError: three is bad"
    assert oks == {1: True, 2: True, 3: False, 4: True}
    assert len(saved_keys(tmp_path)) == 3 and point_key(Pt(3)) not in saved_keys(tmp_path)
    with pytest.raises(SweepError, match=r"Pt\(a=3, b='x'\): ValueError: three is bad"):
        run_sweep(fail_on_3, pts(1, 2, 3, 4), results_dir=tmp_path, client=client)
    res2 = run_sweep(square, pts(1, 2, 3, 4), results_dir=tmp_path, client=client)
    assert res2.skipped == tuple(pts(1, 2, 4))
    assert [r["sq"] for r in res2.rows] == [1, 4, 9, 16]


def test_cluster_task_workers_cannot_import_fails_its_points_without_hanging(client) -> None:
    mod = types.ModuleType("microfab_sweep_test_not_importable")
    exec("import os\ndef task(p):\n    return {'pid': os.getpid()}\n", mod.__dict__)
    sys.modules[mod.__name__] = mod  # so cloudpickle sends the task by reference
    try:
        res = run_sweep(mod.task, pts(1, 2), client=client, raise_on_failure=False)
    finally:
        del sys.modules[mod.__name__]
    assert [f.point for f in res.failed] == pts(1, 2)
    assert all(f.error.startswith("ModuleNotFoundError") for f in res.failed)


def test_cluster_refuses_a_task_that_cannot_be_pickled(client) -> None:
    lock = threading.Lock()
    with pytest.raises(TypeError, match="cannot send the task"):
        run_sweep(lambda p: {"locked": lock.locked()}, pts(1), client=client)


def test_scheduler_address_connects_to_running_cluster(cluster) -> None:
    res = run_sweep(square, pts(1, 2), scheduler=cluster.scheduler_address)
    assert [r["sq"] for r in res.rows] == [1, 4]
    assert os.getpid() not in {r["pid"] for r in res.rows}


def square_and_pools(p: Pt) -> dict[str, Any]:
    """`square`, and the thread pools of the worker once the heavy libraries are loaded."""
    import contextlib

    import scipy.linalg  # noqa: F401  (SciPy's own OpenBLAS)

    from microfab.core.threads import THREAD_ENV, thread_counts, usable_cores

    with contextlib.suppress(ImportError):  # Ipopt loads CasADi's bundled OpenBLAS
        import casadi

        x = casadi.SX.sym("x")
        casadi.nlpsol("s", "ipopt", {"x": x, "f": x**2}, {"print_time": 0, "ipopt.print_level": 0})
    env = {name: os.environ.get(name) for name in THREAD_ENV}  # for what loads later
    return {**square(p), "pools": thread_counts(), "cores": usable_cores(), "env": env}


def test_runner_starts_and_closes_its_own_local_cluster(tmp_path: Path) -> None:
    """Its workers run their pools on policy_threads(workers): workers × threads ≤ cores."""
    pytest.importorskip("distributed")
    before = set(multiprocessing.active_children())
    res = run_sweep(square_and_pools, pts(1, 2, 3), results_dir=tmp_path, workers=2)
    assert [r["sq"] for r in res.rows] == [1, 4, 9]
    assert os.getpid() not in {r["pid"] for r in res.rows}
    assert set(multiprocessing.active_children()) <= before  # its workers are gone
    for row in res.rows:
        pools = row["pools"]
        assert any(k.startswith("blas:") for k in pools), pools
        assert set(pools.values()) == {1}, pools  # MICROFAB_THREADS unset: one each
        assert set(row["env"].values()) == {"1"}, row["env"]  # Dask sets only three
        assert 2 * max(pools.values()) <= max(2, row["cores"])


@pytest.mark.parametrize(
    "address",
    ["tcp://10.0.0.5:8786", "10.0.0.5:8786", "tls://host.example:1", "[::1]:8786",
     "tcp://[fe80::1]:65535", " localhost:8786 "],
)  # fmt: skip
def test_scheduler_addresses_of_dask_s_form_are_accepted(address: str) -> None:
    from microfab.io.sweep import check_scheduler_address

    assert check_scheduler_address(address) == address.strip()


@pytest.mark.parametrize(
    "address",
    ["", " ", "0", "-5:-1", "x=1e308", "host", "host:", ":8786", "host:0", "host:70000",
     "http://host:8786", "1:2:3", "a b:1", "tcp://host:8786/extra"],
)  # fmt: skip
def test_scheduler_addresses_that_are_no_address_are_refused_before_any_file(
    address: str, tmp_path: Path
) -> None:
    from microfab.io.sweep import run_sweep

    with pytest.raises(ValueError, match="not a Dask scheduler address"):
        run_sweep(square, [Pt(1)], results_dir=tmp_path / "r", scheduler=address)
    assert list(tmp_path.iterdir()) == []


class _Closable:
    def __init__(self) -> None:
        self.closed = 0

    def close(self) -> None:
        self.closed += 1


@pytest.fixture
def dask_logging() -> Any:
    """The ``distributed`` logger and its handlers' levels, put back after the test."""
    logger = logging.getLogger("distributed")
    saved = (logger.level, [(h, h.level) for h in logger.handlers])
    yield logger
    logger.setLevel(saved[0])
    for handler, level in saved[1]:
        handler.setLevel(level)


class _Keep(logging.Handler):
    """A handler on ``distributed`` like the one Dask's logging config adds (outside
    pytest, whose own capture replaces it), keeping the messages it would print."""

    def __init__(self) -> None:
        super().__init__(logging.NOTSET)
        self.seen: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.seen.append(record.getMessage())


def _dask_teardown_lines() -> None:
    # what a cluster cut by Ctrl-C logged from its loop thread as it closed (CI, stop 51),
    # and a child logger with a level of its own (Dask's config: distributed.client WARNING)
    logging.getLogger("distributed.batched").info("Batched Comm Closed <TCP (closed)>")
    logging.getLogger("distributed.client").warning("a client warning")


@pytest.mark.parametrize("cut", [True, False], ids=["cut-by-ctrl-c", "ends-well"])
def test_a_sweep_cut_by_an_error_drops_dask_s_teardown_logs(dask_logging: Any, cut: bool) -> None:
    """The Ctrl-C's one line is the whole report: Dask's broken-connection tracebacks,
    logged while or after the cut cluster closes, are dropped (not raced); a sweep that
    ends well leaves Dask's logging as it was."""
    from microfab.io.sweep import _closed_quietly_on_error

    dask_logging.setLevel(logging.INFO)
    logging.getLogger("distributed.client").setLevel(logging.WARNING)
    handler = _Keep()
    dask_logging.addHandler(handler)
    cluster = _Closable()
    try:
        with contextlib.suppress(KeyboardInterrupt), _closed_quietly_on_error(cluster):
            if cut:
                raise KeyboardInterrupt
        _dask_teardown_lines()
    finally:
        dask_logging.removeHandler(handler)
    assert cluster.closed == 1
    if cut:
        assert handler.seen == []
    else:
        assert dask_logging.level == logging.INFO
        assert handler.seen == ["Batched Comm Closed <TCP (closed)>", "a client warning"]
