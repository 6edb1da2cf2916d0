"""State files of the run store: what a run saves to resume, stamped with what it belongs to.

Every mechanism that resumes (a learner's state, a job's chunks, a stage-2 iterate, a
network's training, the plug-in RC memory) saves its state as one ``.npz`` file through
`save_state` and reads it back through `read_state`. The file holds the caller's arrays and
one JSON member ``meta`` with

- ``kind``: what the file is (``"ILC state"``, ``"stage-2 iterate"``, ...), so that a file
  of one kind is never taken for another;
- ``version``: the caller's format version;
- ``settings``: what the state depends on (a fingerprint: settings after defaults, input
  digests), so that a state of other settings is refused with the first setting that
  differs (``old -> new``), the same words `microfab.io.runstore` uses for a run folder;
- the caller's own metadata.

The file is written atomically (`microfab.io.atomic.atomic_save_npz`): complete or absent,
and recorded by an open run store like every other write. Reading refuses, on one line
that names the file and says what to do, a file that is empty, cut short, damaged, of
another kind, another format or other settings; it never returns a partial state.

Example::

    save_state(path, kind="stage-2 iterate", version=2, settings={"inputs": key},
               arrays={"r": r}, meta={"iteration": 7})
    saved = read_state(path, kind="stage-2 iterate", versions=(2,),
                       settings={"inputs": key})
    if saved is not None:
        r, it = saved.arrays["r"], saved.meta["iteration"]
"""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microfab.io.atomic import atomic_save_npz
from microfab.io.runstore import RunRefusedError, canonical_settings, settings_difference
from microfab.io.schema import check_npz, describe_file

__all__ = ["StateFile", "StateFileError", "read_state", "save_state"]

#: The archive member holding the JSON metadata.
META = "meta"
_RESERVED = ("kind", "version", "settings", "members")
#: How many differing settings a refusal names (the first one first).
_SHOWN = 3
#: What a state file that cannot be read may raise while it is read (a truncated archive
#: raises `zipfile.BadZipFile` or `EOFError`, a damaged member `zlib.error`; a damaged
#: member header names a compression method zipfile lacks, `NotImplementedError`, or sets
#: the encryption flag, `RuntimeError` "password required").
_UNREADABLE = (
    OSError,
    ValueError,
    KeyError,
    EOFError,
    zipfile.BadZipFile,
    zlib.error,
    NotImplementedError,
    RuntimeError,
)


class StateFileError(ValueError):
    """A state file that cannot be read (empty, cut short, damaged, not a state file)."""


@dataclass(frozen=True, eq=False)
class StateFile:
    """A state file read back by `read_state`.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    kind : str
        What it is.
    version : int
        Its format version.
    meta : dict
        The caller's metadata (without ``kind``, ``version`` and ``settings``).
    arrays : dict of str to numpy.ndarray
        The caller's arrays, loaded into memory.
    """

    path: Path
    kind: str
    version: int
    meta: dict[str, Any]
    arrays: dict[str, np.ndarray]


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def save_state(
    path: str | os.PathLike[str],
    *,
    kind: str,
    version: int,
    arrays: Mapping[str, Any],
    meta: Mapping[str, Any] | None = None,
    settings: Mapping[str, Any] | None = None,
) -> Path:
    """Write a state file atomically: the arrays and the stamped JSON metadata.

    Parameters
    ----------
    path : str or os.PathLike
        The file (``.npz``); its folder is created if missing.
    kind : str
        What the file is, e.g. ``"ILC state"``.
    version : int
        The caller's format version (bump it when what is saved changes meaning).
    arrays : mapping of str to array_like
        Archive members (not ``meta``).
    meta : mapping, optional
        JSON-ready metadata (not ``kind``, ``version`` or ``settings``).
    settings : mapping, optional
        What the state depends on; `read_state` refuses the file for other settings.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    if META in arrays:
        raise ValueError(f"a state file's arrays may not be named {META!r}")
    user = dict(meta or {})
    clash = [k for k in _RESERVED if k in user]
    if clash:
        raise ValueError(f"a state file's metadata may not use the names {clash}")
    # the member names: a zip archive's checksums cover each member's bytes, not its name
    doc: dict[str, Any] = {"kind": kind, "version": int(version), "members": sorted(arrays)}
    doc.update(user)
    if settings is not None:
        doc["settings"] = canonical_settings(settings)
    text = json.dumps(doc, default=_json_default, allow_nan=True)
    target = Path(path)
    atomic_save_npz(target, **{META: np.array(text)}, **arrays)
    return target


def _read(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    check_npz(path)  # the members' declared sizes, from their headers, before any is read
    with np.load(path, allow_pickle=False) as z:
        if META not in z.files:
            raise KeyError(f"no {META!r} member")
        raw = z[META]
        arrays = {k: z[k] for k in z.files if k != META}
    if raw.dtype == np.uint8:  # metadata saved as UTF-8 bytes
        text = raw.tobytes().decode()
    else:
        text = str(raw)
    doc = json.loads(text)
    if not isinstance(doc, dict):
        raise ValueError("its metadata is not a JSON object")
    return doc, arrays


def read_state(
    path: str | os.PathLike[str],
    *,
    kind: str,
    versions: Collection[int],
    settings: Mapping[str, Any] | None = None,
    fix: str = "remove it to start again",
) -> StateFile | None:
    """Read a state file written by `save_state`, or ``None`` when there is none.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    kind : str
        What the file must be. A file saved without a kind (by an earlier microfab) is
        taken to be of this kind when its version is one of ``versions``.
    versions : collection of int
        The format versions the caller reads.
    settings : mapping, optional
        What the state must belong to; compared with what was saved, setting by setting.
    fix : str
        What the user should do when the file is refused (ends each message).

    Returns
    -------
    StateFile or None
        The state, or ``None`` when ``path`` does not exist.

    Raises
    ------
    StateFileError
        The file is a folder, empty, cut short, damaged or not a state file.
    microfab.io.runstore.RunRefusedError
        It is another kind of file, another format version, or belongs to other settings:
        the message names the first difference (``old -> new``).
    """
    p = Path(path)
    if not p.exists():
        return None
    if not p.is_file():
        raise StateFileError(f"{p}: expected a {kind} file, found a folder; {fix}")
    if p.stat().st_size == 0:
        raise StateFileError(f"{p}: the {kind} file is empty (an interrupted copy?); {fix}")
    try:
        doc, arrays = _read(p)
    except _UNREADABLE as exc:
        other = describe_file(p)
        if other is not None and other not in ("a zip archive", f"a {kind} file"):
            raise StateFileError(f"{p}: this is {other}, not a {kind} file; {fix}") from None
        reason = str(exc) or type(exc).__name__
        raise StateFileError(
            f"{p}: not a readable {kind} file ({reason}; cut short or damaged?); {fix}"
        ) from None
    members = doc.pop("members", None)
    for key, ok in (
        ("members", members is None or (isinstance(members, list)
                                        and all(isinstance(m, str) for m in members))),
        ("kind", isinstance(doc.get("kind", kind), str)),
        ("settings", isinstance(doc.get("settings") or {}, dict)),
    ):  # fmt: skip
        if not ok:
            raise StateFileError(f"{p}: not a readable {kind} file (its {key!r} is damaged); {fix}")
    if members is not None and sorted(arrays) != members:
        lost = sorted(set(members) - set(arrays))
        odd = sorted(set(arrays) - set(members))
        what = "; ".join(
            w
            for w in (f"without {lost}" if lost else "", f"with unknown {odd}" if odd else "")
            if w
        )
        raise StateFileError(
            f"{p}: not a readable {kind} file ({what} of the members it was saved with: "
            f"cut short or damaged?); {fix}"
        )
    saved_kind = doc.pop("kind", kind)
    if saved_kind != kind:
        raise RunRefusedError(f"{p}: a {saved_kind} file where a {kind} was expected; {fix}")
    version = doc.pop("version", None)
    if version not in versions:
        readable = ", ".join(str(v) for v in sorted(versions))
        raise RunRefusedError(
            f"{p}: a {kind} in format {version}; this microfab reads format {readable}; {fix}"
        )
    saved_settings = doc.pop("settings", None)
    if settings is not None:
        diff = settings_difference(saved_settings or {}, canonical_settings(settings))
        if diff:
            shown = ", ".join(diff[:_SHOWN]) + (
                f" (and {len(diff) - _SHOWN} more)" if len(diff) > _SHOWN else ""
            )
            raise RunRefusedError(f"{p}: a {kind} of other settings: {shown}; {fix}")
    return StateFile(path=p, kind=kind, version=int(version), meta=doc, arrays=arrays)
