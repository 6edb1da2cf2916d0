"""One guard for all the paths a command writes, checked together before any work.

Each command names every output (file or folder) and every input it reads; `check_paths`
refuses, with one sentence, a set that would go wrong after the work had begun:

- a path that is a symbolic-link loop, or a special file (FIFO, socket, device): it is
  looked at with ``os.stat`` only, never opened (opening a FIFO blocks until a writer
  comes);
- an output of the wrong kind (a folder where a file goes, or the reverse), or under a
  file, or in a folder that cannot be written;
- an output that is an input (the same path, a link or a hard link to it) or is already
  in an input folder (a file or folder of what that input holds: a frame of the frames
  folder); a new name in an input folder is let through;
- two outputs on one path, or one output inside another output folder (the command owns
  that folder: it writes, resumes or clears its own files there).

`microfab.cli._kit.check_outputs` turns a refusal into the one ``error:`` line, exit 2.
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["PathRefusedError", "check_paths"]


class PathRefusedError(ValueError):
    """A path set refused; the message is the sentence for the user."""


@dataclass(frozen=True)
class _Seen:
    """One path as found on disk: where it leads, and what is there (``None``: nothing)."""

    name: str  # the option or argument as typed, e.g. "--json" or "TRACE"
    path: Path
    real: Path
    st: os.stat_result | None


_SPECIAL = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def _look(name: str, path: Path, *, output: bool) -> _Seen | None:
    """Where ``path`` leads and what is there, refusing a loop or a special file.

    An input that names no file (a drawing given as ``circle:radius=...``, a missing file
    the command refuses itself) is ``None``.
    """
    if "\x00" in str(path):
        if not output:
            return None
        raise PathRefusedError(f"{name} {str(path)!r}: a path cannot hold a NUL byte")
    loop = f"{name} {path} is a symbolic link that loops (it leads back to itself)"
    try:
        real = Path(os.path.abspath(path)).resolve(strict=False)
    except RuntimeError:  # Python 3.11's resolve: "Symlink loop from ..."
        raise PathRefusedError(loop) from None
    except (OSError, ValueError):
        real = Path(os.path.abspath(path))
    try:
        st: os.stat_result | None = os.stat(path)  # follows links; never opens the file
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise PathRefusedError(loop) from None
        st = None
    if st is None:
        return _Seen(name, path, real, None) if output else None
    for test, what in _SPECIAL:
        if test(st.st_mode):
            raise PathRefusedError(
                f"{name} {path} is {what}, not a regular file or folder; give a file"
            )
    return _Seen(name, path, real, st)


def _label(seen: _Seen) -> str:
    """``NAME path``, or the path alone when it is its own name."""
    return str(seen.path) if seen.name == str(seen.path) else f"{seen.name} {seen.path}"


def _same(a: _Seen, b: _Seen) -> bool:
    """One file or folder: the same real path, or (both there) the same inode."""
    if a.real == b.real:
        return True
    return a.st is not None and b.st is not None and os.path.samestat(a.st, b.st)


def _inside(a: _Seen, folder: _Seen) -> bool:
    """``a`` lies below ``folder`` (by real path)."""
    return a.real != folder.real and folder.real in a.real.parents


def _writable_parent(out: _Seen) -> None:
    """The nearest existing folder above ``out`` must be a writable folder."""
    parent = out.real.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise PathRefusedError(f"{out.name} {out.path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise PathRefusedError(f"{out.name} {out.path}: the folder {parent} is not writable")
    # os.access answers yes to root everywhere, also in /proc, /sys or on a read-only
    # mount: a folder made and removed at once is the answer of the file system itself
    where = out.real if out.real.is_dir() else parent
    try:
        probe = tempfile.mkdtemp(prefix=".microfab-probe-", dir=where)
    except OSError as exc:
        raise PathRefusedError(
            f"{out.name} {out.path}: nothing can be written in {where} ({exc.strerror})"
        ) from None
    os.rmdir(probe)


def _flat(
    inputs: Mapping[str, Path | Iterable[Path | None] | None],
) -> list[tuple[str, Path]]:
    """``(name, path)`` for each input; a sequence under one name gives one entry each."""
    flat: list[tuple[str, Path]] = []
    for name, value in inputs.items():
        if value is None:
            continue
        if isinstance(value, (str, os.PathLike)):
            flat.append((name, Path(value)))
        else:
            flat.extend((name, Path(v)) for v in value if v is not None)
    return flat


def check_paths(
    files: Mapping[str, Path | None],
    folders: Mapping[str, Path | None],
    inputs: Mapping[str, Path | Iterable[Path | None] | None],
) -> None:
    """Refuse a set of outputs and inputs that cannot all be written and read as asked.

    Parameters
    ----------
    files : mapping of str to pathlib.Path or None
        Each output file, keyed by its option as typed (``"--json"``); ``None``: not
        asked for. A file may replace a file, never a folder.
    folders : mapping of str to pathlib.Path or None
        Each output folder (the command owns it: it may resume, refuse or clear its own
        files there); a folder may be reused, never a file.
    inputs : mapping of str to pathlib.Path, sequence of pathlib.Path, or None
        What the command reads, keyed by its option or argument (``"TRACE"``); a missing
        path is passed over (the command says so itself).

    Raises
    ------
    PathRefusedError
        With the sentence for the user, at the first problem found.
    """
    outs: list[_Seen] = []
    for kind, given in (("file", files), ("folder", folders)):
        for name, path in given.items():
            if path is None:
                continue
            seen = _look(name, Path(path), output=True)
            assert seen is not None
            if seen.st is not None and kind == "file" and stat.S_ISDIR(seen.st.st_mode):
                raise PathRefusedError(f"{name} {path} is a folder; give a file name")
            if seen.st is not None and kind == "folder" and not stat.S_ISDIR(seen.st.st_mode):
                raise PathRefusedError(f"{name} {path} is a file; give a folder")
            outs.append(seen)
    ins = [s for n, p in _flat(inputs) if (s := _look(n, p, output=False)) is not None]
    for out in outs:
        for inp in ins:
            if _same(out, inp):
                raise PathRefusedError(
                    f"{out.name} {out.path} is also an input ({_label(inp)}); "
                    "writing it would destroy that input"
                )
            if (
                out.st is not None
                and inp.st is not None
                and stat.S_ISDIR(inp.st.st_mode)
                and _inside(out, inp)
            ):
                raise PathRefusedError(
                    f"{out.name} {out.path} is inside the input folder {_label(inp)} "
                    "and already there; writing it would change that input, give a path "
                    "outside it"
                )
    for i, a in enumerate(outs):
        for b in outs[i + 1 :]:
            if _same(a, b):
                raise PathRefusedError(
                    f"{a.name} and {b.name} are the same path ({b.path}); give each output its own"
                )
            for inner, outer in ((a, b), (b, a)):
                if outer.name in folders and _inside(inner, outer):
                    raise PathRefusedError(
                        f"{inner.name} {inner.path} is inside the {outer.name} folder "
                        f"{outer.path}, which the command writes; give a path outside it"
                    )
    for out in outs:
        _writable_parent(out)
