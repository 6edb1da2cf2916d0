"""The run store: a run folder that knows the settings its results belong to.

Everything that resumes (learning state, sweep points, checkpoints, stage-2 iterates,
trained networks) lives in a run folder whose ``run.json`` records the *fingerprint* of the
fully resolved settings: every setting after defaults, the content digests of the input
files and of the packaged data files the run reads, the store's format and the caller's
state and model versions. Opening the folder again

- with the same fingerprint **resumes** (whatever was saved there is reused);
- with a different one is **refused** with one line naming the first setting that differs
  (old -> new) and how to start fresh, and nothing is touched;
- with ``fresh=True`` moves the files the earlier run wrote (and only those: the store
  records every file written under the folder through `microfab.io.atomic` while it is
  open) to ``_previous/<time>/`` and starts clean.

A folder that exists, is not empty and holds no ``run.json`` is refused: the store cannot
tell what wrote it, so it neither reuses nor moves anything there.

One writer per run folder: `open_run` holds the folder's lock (`microfab.io.lock`) from
before it reads ``run.json`` until the block ends, so a second run on the same folder is
refused on one line (or waits, ``wait=True``) instead of mixing its files with the first's.

Example::

    with open_run("report", {"scan.rate": 400, "model": "1"}, fresh=False) as run:
        ...  # every atomic write under report/ is recorded in report/run.json

The manifest is written just before the first file under the folder is, and rewritten just
before each file of a new name (per run or per checkpoint, never per sample): a run refused
before it writes anything leaves no trace, and no interruption leaves a file it has not
recorded (a name may be recorded whose file never came).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import math
import os
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from microfab.io.atomic import atomic_write_json, watch_writes
from microfab.io.lock import folder_lock

__all__ = [
    "MANIFEST",
    "PREVIOUS",
    "STORE_FORMAT",
    "RunRefusedError",
    "RunStore",
    "canonical_settings",
    "check_run",
    "content_digest",
    "open_run",
    "read_manifest",
    "settings_difference",
]

#: Version of the run folder's layout and of ``run.json``.
STORE_FORMAT = 1
#: The manifest's file name inside a run folder.
MANIFEST = "run.json"
#: Where ``fresh`` moves an earlier run's files, inside the run folder.
PREVIOUS = "_previous"
_MISSING = object()


class RunRefusedError(ValueError):
    """A run folder that cannot be used for these settings (the message says why and how)."""


def content_digest(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes, or of a folder's files (names and bytes, sorted).

    Parameters
    ----------
    path : str or os.PathLike
        An existing file or folder. In a folder, hidden entries (names starting with
        ``.``) are skipped: they are temporary files of atomic writes or a system's
        bookkeeping, not content.

    Returns
    -------
    str
        ``"sha256:<64 hex digits>"``.

    Raises
    ------
    FileNotFoundError
        No such file or folder.
    """
    p = Path(path)
    h = hashlib.sha256()
    if p.is_dir():
        for f in sorted(q for q in p.rglob("*") if q.is_file()):
            rel = f.relative_to(p)
            if any(part.startswith(".") for part in rel.parts):
                continue
            h.update(rel.as_posix().encode() + b"\0")
            _hash_file(f, h)
            h.update(b"\0")
    elif p.is_file():
        _hash_file(p, h)
    else:
        raise FileNotFoundError(f"{p}: no such file or folder")
    return "sha256:" + h.hexdigest()


def _hash_file(path: Path, h: Any) -> None:
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)


def _canonical(value: Any) -> Any:
    """A JSON value that compares equal after a write and read of ``run.json``."""
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_canonical(v) for v in value]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "item") and not isinstance(value, str | bytes):
        value = value.item()  # a NumPy scalar
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # JSON has no NaN or inf; a setting rarely is one, but may
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return repr(value)


def canonical_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """Settings as they compare after a JSON write and read (paths as text, NaN as text).

    Parameters
    ----------
    settings : mapping of str to value
        Setting name -> value (JSON values, paths, NumPy scalars; anything else is
        compared by its ``repr``).
    """
    return {str(k): _canonical(v) for k, v in settings.items()}


def _shown(value: Any) -> str:
    if value is _MISSING:
        return "(absent)"
    if isinstance(value, str) and value.startswith("sha256:"):
        return f"content {value[7:15]}"
    text = json.dumps(value, ensure_ascii=False)
    return text if len(text) <= 60 else text[:57] + "..."


def settings_difference(old: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    """Every setting that differs, as ``"name old -> new"``, in the new settings' order.

    Parameters
    ----------
    old, new : mapping of str to JSON value
        Fingerprints (as `open_run` records them).
    """
    names = list(new) + [k for k in old if k not in new]
    return [
        f"{k} {_pair(old.get(k, _MISSING), new.get(k, _MISSING))}"
        for k in names
        if old.get(k, _MISSING) != new.get(k, _MISSING)
    ]


def _pair(a: Any, b: Any) -> str:
    """``a -> b``, floats with 12 significant digits where those tell them apart.

    A value computed from a unit (100 µm as 9.999999999999999e-05 m) then reads 0.0001.
    """
    if isinstance(a, float) and isinstance(b, float):
        short_a, short_b = f"{a:.12g}", f"{b:.12g}"
        if short_a != short_b:
            return f"{short_a} -> {short_b}"
    return f"{_shown(a)} -> {_shown(b)}"


def read_manifest(root: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The ``run.json`` of a run folder, or ``None`` when there is none.

    Raises
    ------
    RunRefusedError
        The manifest exists but is not a run store's (unreadable, not JSON, another format).
    """
    path = Path(root) / MANIFEST
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RunRefusedError(
            f"{path} is not a readable run manifest ({type(exc).__name__}); move the folder "
            "aside or give another output folder"
        ) from None
    if not (
        isinstance(data, dict)
        and isinstance(data.get("settings"), dict)
        and isinstance(data.get("files", []), list)
    ):
        raise RunRefusedError(
            f"{path} is not a run manifest (no settings); move the folder aside or give "
            "another output folder"
        )
    return data


@dataclass(eq=False)
class RunStore:
    """An open run folder (made by `open_run`).

    Attributes
    ----------
    root : pathlib.Path
        The run folder.
    settings : dict
        The fingerprint, canonical JSON values by name.
    resumed : bool
        The folder held a run of these settings (its saved state is reused).
    moved_to : pathlib.Path or None
        Where ``fresh`` moved the earlier run's files, if it moved any.
    files : list of str
        Files written under the folder by runs of these settings, relative POSIX paths.
    """

    root: Path
    settings: dict[str, Any]
    resumed: bool = False
    moved_to: Path | None = None
    files: list[str] = field(default_factory=list)
    _real_root: str = ""
    _created: str = ""
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def record(self, path: str | os.PathLike[str]) -> None:
        """Record a file about to be written under the folder (others are ignored).

        The manifest is written the first time, and again whenever the name is new. Safe
        to call from several threads (checkpoints are written on a worker thread).
        """
        real = os.path.realpath(path)
        if os.path.commonpath([real, self._real_root]) != self._real_root:
            return
        rel = Path(os.path.relpath(real, self._real_root)).as_posix()
        if rel == MANIFEST or rel.split("/", 1)[0] == PREVIOUS:
            return
        with self._lock:
            if rel in self.files:
                return
            self.files.append(rel)
            self._write_manifest()

    def _write_manifest(self) -> None:
        atomic_write_json(
            self.root / MANIFEST,
            {
                "format": STORE_FORMAT,
                "created": self._created,
                "settings": self.settings,
                "files": self.files,
            },
        )


def _is_empty(root: Path) -> bool:
    return not any(not p.name.startswith(".") for p in root.iterdir())


def _move_previous(root: Path, files: list[str]) -> Path | None:
    """Move the recorded files (and the manifest) to ``root/_previous/<time>/``."""
    present = [f for f in [*files, MANIFEST] if (root / f).is_file()]
    if not present:
        return None
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    dest = root / PREVIOUS / stamp
    n = 1
    while dest.exists():
        n += 1
        dest = root / PREVIOUS / f"{stamp}-{n}"
    for rel in present:
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(root / rel, target)
    for rel in present:  # folders the move emptied
        parent = (root / rel).parent
        while parent != root:
            with contextlib.suppress(OSError):
                parent.rmdir()  # only when empty
            parent = parent.parent
    return dest


def _plan(
    path: Path, settings: Mapping[str, Any], fresh: bool, fresh_hint: str, other_hint: str
) -> tuple[RunStore, list[str] | None]:
    """The store to open and the earlier files to move aside (``None``: none), or refuse."""
    canon = json.loads(json.dumps(_canonical(dict(settings)), allow_nan=False))
    canon["store.format"] = STORE_FORMAT
    if path.exists() and not path.is_dir():
        raise RunRefusedError(f"{path} is a file, not an output folder; {other_hint}")
    manifest = read_manifest(path) if path.is_dir() else None
    store = RunStore(root=path, settings=canon)
    move = None
    if manifest is not None:
        diff = settings_difference(manifest["settings"], canon)
        old_files = [f for f in manifest.get("files", []) if isinstance(f, str)]
        if fresh:
            move = old_files
        elif not diff:
            store.resumed = True
            store.files = old_files
            store._created = str(manifest.get("created", ""))
        else:
            more = f" (and {len(diff) - 1} more)" if len(diff) > 1 else ""
            raise RunRefusedError(
                f"{path} holds a run of other settings: {diff[0]}{more}; {fresh_hint} "
                f"(its files move to {path / PREVIOUS}/), or {other_hint}"
            )
    elif path.is_dir() and not _is_empty(path):
        raise RunRefusedError(
            f"{path} is not empty and holds no {MANIFEST}, so no run of microfab wrote it; "
            f"{other_hint} (or an empty folder)"
        )
    return store, move


_FRESH_HINT = "rerun with --fresh to start again there"
_OTHER_HINT = "give another --out"


def check_run(
    root: str | os.PathLike[str],
    settings: Mapping[str, Any],
    *,
    fresh: bool = False,
    fresh_hint: str = _FRESH_HINT,
    other_hint: str = _OTHER_HINT,
) -> str:
    """What `open_run` would do, without doing it: ``"resume"``, ``"start"`` or ``"start fresh"``.

    Raises
    ------
    RunRefusedError
        As `open_run` would.
    """
    store, move = _plan(Path(root), settings, fresh, fresh_hint, other_hint)
    return "resume" if store.resumed else "start fresh" if move else "start"


@contextlib.contextmanager
def open_run(
    root: str | os.PathLike[str],
    settings: Mapping[str, Any],
    *,
    fresh: bool = False,
    fresh_hint: str = _FRESH_HINT,
    other_hint: str = _OTHER_HINT,
    wait: bool = False,
    busy_hint: str = "wait for it to finish",
    on_wait: Callable[[str], Any] | None = None,
) -> Iterator[RunStore]:
    """Open a run folder for these settings; record every file written under it.

    Parameters
    ----------
    root : str or os.PathLike
        The run folder; created on the first write if missing.
    settings : mapping of str to JSON value
        The fully resolved settings (see the module docstring); tuples, paths and NumPy
        scalars are turned into JSON values.
    fresh : bool
        Move an earlier run's files aside and start clean instead of resuming or refusing.
    fresh_hint, other_hint : str
        How the caller's user starts fresh or elsewhere, for the refusal.
    wait : bool
        When another process writes the folder (holds its lock, `microfab.io.lock`):
        wait for it instead of refusing.
    busy_hint : str
        How the caller's user waits, for the refusal of a busy folder.
    on_wait : callable, optional
        Told once, with a one-line message, when ``wait`` is set and the folder is busy.

    Yields
    ------
    RunStore
        While the block runs, every file written under ``root`` through
        `microfab.io.atomic` is recorded in ``root/run.json``.

    Raises
    ------
    RunRefusedError
        ``root`` is not a folder, holds a run of other settings (naming the first
        difference, old -> new), or holds files of no recorded run. Nothing is changed.
    microfab.io.lock.FolderLockedError
        Another process writes the folder and ``wait`` is not set (also a `ValueError`).
        Nothing is changed.

    Notes
    -----
    The folder's lock (`microfab.io.lock.folder_lock`, a ``.<name>.lock`` file beside the
    folder, removed on exit) is taken before ``run.json`` is read and held until the block
    ends: one writer per run folder.
    """
    path = Path(root)
    with folder_lock(
        path,
        what="the run folder",
        wait=wait,
        hint=f"{busy_hint}, or {other_hint}",
        on_wait=on_wait,
    ):
        store, move = _plan(path, settings, fresh, fresh_hint, other_hint)
        if move is not None:
            store.moved_to = _move_previous(path, move)
        if not store._created:
            store._created = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        store._real_root = os.path.realpath(path)
        with watch_writes(store.record, when="before"):
            yield store
