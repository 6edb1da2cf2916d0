"""Run a task over a grid of points on Dask ``distributed``, saving each result as it comes.

A *point* is a frozen dataclass instance whose fields hold JSON values; a *task* is a
picklable module-level callable ``task(point) -> dict`` of JSON values. :func:`run_sweep`
knows nothing about what the task computes. ``results_dir`` holds, each file written by
:func:`microfab.io.atomic.atomic_write_json` (so absent or complete)::

    settings.json       {"format": 1, "settings": {...}, "points": [{fields}, ...]}
    points/<key>.json   {"key": ..., "point": {fields}, "row": {...}}  (one per finished point)

``settings`` is what the results depend on besides the point: a rerun with other settings
is refused, one with the same skips the points whose file exists (the grid may grow).
``points`` lists every point asked for, in the order first asked (that of
:func:`load_results`). A file per point, written as it finishes, makes each save O(1) and
loses at most the points in progress. One runner per directory at a time.

The key (:func:`point_key`) is ``name=value`` per field (strings bare, other values as
JSON) joined by ``,``, characters outside ``[A-Za-z0-9._=,+-]`` replaced by ``_``, cut to
80 characters, then ``-`` and 12 hex digits of the SHA-256 of the fields as compact sorted
JSON: stable, file-name safe, distinct per point. JSON tells ``50`` from ``50.0``.

``workers=1`` with neither ``scheduler`` nor ``client`` runs the points one after another
in this process, without Dask (the cheap path for callers' tests). Otherwise a
``LocalCluster`` of ``workers`` single-threaded processes is started and closed around the
sweep, or the given cluster is used. Workers are *spawned*: a script running a sweep on
them needs an ``if __name__ == "__main__":`` guard. A worker sets its thread pools before
each task (`microfab.core.threads.apply_thread_policy`): ``policy_threads(workers)`` on a
local cluster, so workers × threads ≤ cores; one on a given cluster (a Dask worker may
run several tasks at once).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from microfab.io.atomic import atomic_write_json
from microfab.io.runstore import RunRefusedError, canonical_settings, settings_difference
from microfab.io.sweep_cluster import _ADDRESS as _ADDRESS
from microfab.io.sweep_cluster import (
    CONNECT_TIMEOUT_S,
    _connect,
    _run_on_cluster,
    check_scheduler_address,
)
from microfab.io.sweep_cluster import _closed_quietly_on_error as _closed_quietly_on_error
from microfab.io.sweep_cluster import _quiet_workers as _quiet_workers
from microfab.io.sweep_cluster import _run_pickled as _run_pickled
from microfab.io.sweep_cluster import _silence_distributed_logs as _silence_distributed_logs

if TYPE_CHECKING:
    from distributed import Client

__all__ = [
    "CONNECT_TIMEOUT_S",
    "SweepError",
    "SweepFailure",
    "SweepResult",
    "check_scheduler_address",
    "grid",
    "load_results",
    "point_key",
    "run_sweep",
]

P = TypeVar("P")
_FORMAT = 1
_UNSAFE = re.compile(r"[^A-Za-z0-9._=,+-]")


@dataclass(frozen=True, kw_only=True)
class SweepFailure(Generic[P]):
    """A point whose task raised, or whose result was not a dict of JSON values.

    Attributes
    ----------
    point, key : object, str
        The point and its :func:`point_key`.
    error : str
        ``"ExceptionType: first line of the message"``.
    """

    point: P
    key: str
    error: str


@dataclass(frozen=True, kw_only=True)
class SweepResult(Generic[P]):
    """What a sweep produced.

    Attributes
    ----------
    rows : tuple of dict
        One per finished point (run now or loaded), in point order: the point's fields,
        then the task's entries (a point field wins over a task entry of the same name).
    failed : tuple of SweepFailure
        Points whose task failed, in point order; nothing of theirs is saved.
    skipped : tuple
        Points found finished in ``results_dir`` and not run again.
    """

    rows: tuple[dict[str, Any], ...]
    failed: tuple[SweepFailure[P], ...]
    skipped: tuple[P, ...]


class SweepError(RuntimeError):
    """Some points of a sweep failed; the others finished and are saved.

    Attributes
    ----------
    result : SweepResult
        Everything the sweep produced, failures included.
    """

    def __init__(self, result: SweepResult[Any], results_dir: Path | None) -> None:
        self.result = result
        saved = (
            ""
            if results_dir is None
            else f" and are saved in {results_dir}; running the sweep again retries the failed"
        )
        lines = "".join(f"\n  {f.point!r}: {f.error}" for f in result.failed)
        super().__init__(
            f"{len(result.failed)} sweep point(s) failed, the other {len(result.rows)} "
            f"finished{saved}:{lines}"
        )


def grid(point_type: type[P], /, **values: Iterable[Any]) -> list[P]:
    """Cartesian product of named value lists, as points of ``point_type``.

    Parameters
    ----------
    point_type : type
        A dataclass; fields not named keep their defaults, unknown names raise TypeError.
    **values : iterable
        Values of each named field. The last name varies fastest.

    Returns
    -------
    list
        Without duplicates; empty if a list is empty. E.g. ``grid(Pt, c=[1, 2], v=[40])``
        gives ``[Pt(c=1, v=40), Pt(c=2, v=40)]``.
    """
    combos = itertools.product(*(list(v) for v in values.values()))
    return list(dict.fromkeys(point_type(**dict(zip(values, c, strict=True))) for c in combos))


def _fields(point: Any) -> dict[str, Any]:
    try:
        return _jsonable({f.name: getattr(point, f.name) for f in dataclasses.fields(point)})
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"sweep point {point!r} has a field that is not a JSON value ({exc}); "
            "use numbers, strings, booleans, None or lists of them"
        ) from exc


def _jsonable(obj: Any) -> Any:
    # JSON round trip: the returned rows are what load_results reads back. NumPy values
    # (anything with .tolist()) and paths are converted as atomic_write_json does.
    def default(o: Any) -> Any:
        if hasattr(o, "tolist"):
            return o.tolist()
        if isinstance(o, Path):
            return str(o)
        raise TypeError(f"object of type {type(o).__name__} is not JSON serializable")

    return json.loads(json.dumps(obj, allow_nan=False, default=default))


def _key(fields: dict[str, Any]) -> str:
    text = {k: v if isinstance(v, str) else json.dumps(v) for k, v in fields.items()}
    readable = ",".join(f"{k}={v}" for k, v in text.items())
    digest = hashlib.sha256(json.dumps(fields, sort_keys=True, separators=(",", ":")).encode())
    return f"{_UNSAFE.sub('_', readable)[:80]}-{digest.hexdigest()[:12]}"


def point_key(point: Any) -> str:
    """Stable, file-name-safe key of a point (see the module docstring).

    E.g. ``"a=1,b=x-ecf9e98ec064"`` for ``Pt(a=1, b="x")``.
    """
    return _key(_fields(point))


def _unique_points(points: Iterable[P]) -> list[P]:
    points = list(points)
    kind: type | None = None
    for p in points:
        params = getattr(type(p), "__dataclass_params__", None)
        if isinstance(p, type) or params is None or not params.frozen:
            raise TypeError(
                f"sweep points must be frozen dataclass instances, got {p!r}; "
                "declare the point type with @dataclass(frozen=True)"
            )
        if kind is not None and type(p) is not kind:
            raise TypeError(
                f"all sweep points must have one type, got {kind.__name__} and "
                f"{type(p).__name__}; make one dataclass with a field telling them apart"
            )
        kind = type(p)
    return list(dict.fromkeys(points))


def _open_dir(path: Path, settings: dict[str, Any], fields: list[dict[str, Any]]) -> None:
    """Check ``path`` holds no sweep or one with these settings; record the points."""
    meta = path / "settings.json"
    known: list[dict[str, Any]] = []
    if meta.exists():
        try:
            saved = json.loads(meta.read_text(encoding="utf-8"))
            saved["points"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise RunRefusedError(
                f"{meta}: not a readable sweep settings file ({exc}); use another results "
                f"directory, or remove {path} to start over"
            ) from None
        old = {"(file format)": saved.get("format"), **saved.get("settings", {})}
        new = canonical_settings({"(file format)": _FORMAT, **settings})
        diff = settings_difference(old, new)
        if diff:
            raise RunRefusedError(
                f"{path} holds a sweep of other settings: {', '.join(diff[:3])}; "
                f"use another results directory, or remove {path} to start over"
            )
        known = saved["points"]
    seen = {_key(f) for f in known}
    merged = known + [f for f in fields if _key(f) not in seen]
    if not meta.exists() or merged != known:
        atomic_write_json(meta, {"format": _FORMAT, "settings": settings, "points": merged})


def _load_row(path: Path, fields: dict[str, Any]) -> dict[str, Any] | None:
    try:
        saved = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None  # missing, or not ours: the point is not done
    return saved.get("row") if saved.get("point") == fields else None


def load_results(
    results_dir: str | Path, points: Iterable[Any] | None = None
) -> list[dict[str, Any]]:
    """Rows saved by :func:`run_sweep` in ``results_dir``, in point order.

    Parameters
    ----------
    results_dir : str or Path
        The sweep's results directory.
    points : iterable of dataclass instances, optional
        Points to load, in this order; default: all, in the order first asked for.

    Returns
    -------
    list of dict
        Rows as in :attr:`SweepResult.rows`; points without one (not run, failed) are
        left out.

    Raises
    ------
    FileNotFoundError
        If ``results_dir`` holds no sweep (no ``settings.json``).
    """
    path = Path(results_dir)
    meta = path / "settings.json"
    if not meta.exists():
        raise FileNotFoundError(f"{path} holds no sweep results ({meta} is missing)")
    if points is None:
        wanted = json.loads(meta.read_text(encoding="utf-8"))["points"]
    else:
        wanted = [_fields(p) for p in _unique_points(points)]
    rows = (_load_row(path / "points" / f"{_key(f)}.json", f) for f in wanted)
    return [r for r in rows if r is not None]


def run_sweep(
    task: Callable[[P], Mapping[str, Any]],
    points: Iterable[P],
    *,
    results_dir: str | Path | None = None,
    settings: Mapping[str, Any] | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    client: Client | None = None,
    progress: Callable[[int, int, P, bool], None] | None = None,
    raise_on_failure: bool = True,
) -> SweepResult[P]:
    """Run ``task`` on every point, saving each result as it finishes.

    Parameters
    ----------
    task : callable
        ``task(point) -> dict`` of JSON values (NumPy values are converted). Off the
        in-process path it must be picklable (a module-level function; workers must be
        able to import its module, or ``cloudpickle`` must send it by value).
    points : iterable of frozen dataclass instances
        The grid (:func:`grid`), all of one type; duplicates run once.
    results_dir : str or Path, optional
        Where to save and resume (module docstring); default: nothing is saved.
    settings : mapping, optional
        JSON values the results depend on besides the points; checked on resume.
    workers : int, optional
        Processes of the ``LocalCluster`` started for the sweep; ``1`` runs in this
        process without Dask. Ignored with ``scheduler`` or ``client``.
    scheduler : str, optional
        Address of a running Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    client : distributed.Client, optional
        A client to run on; left open.
    progress : callable, optional
        ``progress(done, total, point, ok)``, called in this process as each point that
        runs completes; ``total`` counts all unique points, ``done`` the skipped ones too.
    raise_on_failure : bool, optional
        Raise :class:`SweepError` at the end if a point failed (default), or return the
        failures in :attr:`SweepResult.failed`.

    Returns
    -------
    SweepResult
        Rows of the finished points in point order, failures, skipped points.

    Raises
    ------
    SweepError
        If a point failed and ``raise_on_failure``; all other points ran and are saved,
        the failed ones are not marked done, so a rerun retries them.
    ValueError
        If ``workers < 1``, both ``scheduler`` and ``client`` are given, or
        ``results_dir`` holds a sweep with other settings.
    TypeError
        If the points are not frozen dataclass instances of one type with JSON fields.
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if scheduler is not None and client is not None:
        raise ValueError(f"pass scheduler or client, not both (got {scheduler!r} and a client)")
    if scheduler is not None:  # connected before the results folder is touched
        with _connect(check_scheduler_address(scheduler)) as connected:
            return run_sweep(
                task,
                points,
                results_dir=results_dir,
                settings=settings,
                client=connected,
                progress=progress,
                raise_on_failure=raise_on_failure,
            )
    unique = _unique_points(points)
    fields = {p: _fields(p) for p in unique}
    keys = {p: _key(f) for p, f in fields.items()}
    path = None if results_dir is None else Path(results_dir)
    rows: dict[P, dict[str, Any]] = {}
    if path is not None:
        _open_dir(path, _jsonable(dict(settings or {})), list(fields.values()))
        for p in unique:
            row = _load_row(path / "points" / f"{keys[p]}.json", fields[p])
            if row is not None:
                rows[p] = row
    skipped = tuple(rows)
    todo = [p for p in unique if p not in rows]
    errors: dict[P, str] = {}
    done = len(skipped)

    def finish(p: P, outcome: Any) -> None:
        nonlocal done
        if not isinstance(outcome, BaseException):
            try:
                if not isinstance(outcome, Mapping):
                    raise TypeError(f"task returned {type(outcome).__name__}, not a dict")
                row = dict(fields[p])
                row.update((k, v) for k, v in _jsonable(dict(outcome)).items() if k not in row)
                if path is not None:
                    record = {"key": keys[p], "point": fields[p], "row": row}
                    atomic_write_json(path / "points" / f"{keys[p]}.json", record)
                rows[p] = row
            except (TypeError, ValueError) as exc:  # not JSON: the point failed
                outcome = exc
        if isinstance(outcome, BaseException):
            name, lines = type(outcome).__name__, str(outcome).strip().splitlines()
            errors[p] = f"{name}: {lines[0]}" if lines else name
        done += 1
        if progress is not None:
            progress(done, len(unique), p, p in rows)

    if todo and workers == 1 and scheduler is None and client is None:
        for p in todo:
            try:
                outcome = task(p)
            except Exception as exc:  # isolate the point; the others go on
                outcome = exc
            finish(p, outcome)
    elif todo:
        _run_on_cluster(task, todo, finish, workers, scheduler, client)
    failed = tuple(
        SweepFailure(point=p, key=keys[p], error=errors[p]) for p in unique if p in errors
    )
    result = SweepResult(
        rows=tuple(rows[p] for p in unique if p in rows), failed=failed, skipped=skipped
    )
    if failed and raise_on_failure:
        raise SweepError(result, path)
    return result
