"""One writer per folder: the lock a command takes on the state or results folder it writes.

Two ``microfab`` processes writing one folder at once lose work without a word (two ``ilc
step`` on one state: one learning update is gone; two ``slm build`` into one folder: their
layer files mixed). `folder_lock` makes the second writer either refuse on one line,
naming the process that holds the folder, or wait for it (``wait=True``).

The lock is an operating-system lock (``flock``, through the `filelock` package) on a
small file **beside** the folder, in its parent::

    parent/.name.lock      the lock of parent/name/

Beside, not inside, because the folder often does not exist yet when the lock must be
taken (a first ``ilc step``, a new ``--out``), and because a file inside would be taken
for the command's output (the run store refuses a non-empty folder without ``run.json``).
The path is the folder's real path (symbolic links resolved), so two spellings of one
folder share one lock. The parent is created when missing (the writer would create it
anyway); the folders this call created are removed again when they are still empty.

The lock file holds the holder's process id, only for the refusal's message. It is
removed by its holder before the lock is released, so that a refused or finished command
leaves no file behind; a process that died (``kill -9``) leaves its lock file, but the
operating system dropped its lock with the process, so the next writer takes the file over
at once: a stale file, or a stale process id in it, never blocks. A waiter that wins the
lock on a file its holder has just removed tries again on the path's new file (the check
``_held_path_is_ours``), so two writers never hold two different files of one name.

In one thread, a folder already locked by this process is locked again for free (the
command takes the lock, the library function it calls takes it again); another thread of
the same process is refused or waits like another process.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "FolderLockError",
    "FolderLockedError",
    "folder_lock",
    "hold_for_command",
    "lock_path",
]

#: How often a waiting writer tries the lock again, s (assumed: a writer holds a folder
#: for seconds to hours, so a fifth of a second is prompt and costs nothing).
POLL_S = 0.2
#: Attempts to take the lock when its file vanishes under us (a holder that released and
#: removed it just then); each attempt is a few system calls (assumed: ample, since only a
#: holder finishing in that very moment makes one fail).
_RETRIES = 20

# (lock file, thread) -> how many times this thread holds it (re-entry is free)
_HELD: dict[tuple[str, int], int] = {}
_HELD_GUARD = threading.Lock()


class FolderLockError(OSError, ValueError):
    """A folder's lock cannot be taken (its file cannot be made, for instance).

    Both an `OSError` and a `ValueError`, like `io.UnsupportedOperation`, so that every
    handler of a command's refusals catches it; ``str()`` is the whole one-line message.
    """

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class FolderLockedError(FolderLockError, BlockingIOError):
    """The folder is being written by another process (or thread); nothing was done."""


def lock_path(folder: str | os.PathLike[str]) -> Path:
    """The lock file of a folder: ``.<name>.lock`` beside it, from its real path.

    Parameters
    ----------
    folder : str or os.PathLike
        The folder (it need not exist).

    Returns
    -------
    pathlib.Path
        ``<real parent>/.<name>.lock``; for the file system's root, ``/.microfab-root.lock``.
    """
    real = Path(os.path.realpath(folder))
    name = real.name or "microfab-root"
    return real.parent / f".{name}.lock"


def _read_pid(path: Path) -> int | None:
    """The process id a lock file names, or ``None`` (no file, empty, not a number)."""
    try:
        text = path.read_text(encoding="ascii", errors="replace").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _descriptor(lock: Any) -> int | None:
    """The file descriptor `filelock` holds the lock through (``None``: not known)."""
    fd = getattr(getattr(lock, "_context", None), "lock_file_fd", None)
    return fd if isinstance(fd, int) else None


def _held_path_is_ours(lock: Any, path: Path) -> bool:
    """Whether the locked file is still the file at ``path`` (not one removed meanwhile)."""
    fd = _descriptor(lock)
    if fd is None:
        return True  # filelock does not say: it checks this itself (filelock >= 3.13)
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except OSError:
        return False  # removed: the lock is on a file nobody else will open


def _write_pid(lock: Any) -> None:
    fd = _descriptor(lock)
    if fd is None:
        return
    with contextlib.suppress(OSError):  # the pid is for messages only
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)


def _remove_if_ours(lock: Any, path: Path) -> None:
    """Remove the lock file while still holding it (so a refusal leaves no file)."""
    if getattr(getattr(lock, "_context", None), "soft_fallback", False):
        return  # a file system without flock: filelock's marker removes itself
    if _held_path_is_ours(lock, path) and _descriptor(lock) is not None:
        with contextlib.suppress(OSError):
            path.unlink()


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; return those created, deepest first."""
    missing = []
    p = folder
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    made = []
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            continue
        made.append(d)
    return made[::-1]


def _holder(pid: int | None) -> str:
    """``pid N`` of a lock's holder as its file names it (or ``pid unknown``)."""
    if pid is None:
        return "pid unknown"
    return "this process, another thread" if pid == os.getpid() else f"pid {pid}"


@contextlib.contextmanager
def folder_lock(
    folder: str | os.PathLike[str],
    *,
    what: str = "folder",
    wait: bool = False,
    hint: str = "wait for it to finish, or give another folder",
    on_refused: Callable[[str], Any] | None = None,
    on_wait: Callable[[str], Any] | None = None,
    poll_s: float = POLL_S,
) -> Iterator[Path]:
    """Hold a folder's lock while the block runs: one writer per folder.

    Take it before the folder is read (a state is read, changed and written inside it).

    Parameters
    ----------
    folder : str or os.PathLike
        The state or results folder to be written (it need not exist yet).
    what : str
        What the folder is, for the message (``"learning state"``, ``"--out"``...).
    wait : bool
        Wait until the holder is done instead of refusing.
    hint : str
        What the refused user can do, ending the refusal's message.
    on_refused : callable, optional
        Called with the one-line message instead of raising at once (a command's ``fail``,
        which exits); if it returns, the error is raised.
    on_wait : callable, optional
        Called once with a one-line message when ``wait`` is set and the folder is busy.
    poll_s : float
        Seconds between two tries while waiting.

    Yields
    ------
    pathlib.Path
        The lock file (``.<name>.lock`` beside the folder; see `lock_path`).

    Raises
    ------
    FolderLockedError
        Another process (or another thread of this one) holds the folder and ``wait`` is
        not set.
    FolderLockError
        The lock file cannot be made (the parent is not writable, for instance).
    """
    from filelock import FileLock, Timeout

    path = lock_path(folder)
    key = (str(path), threading.get_ident())
    with _HELD_GUARD:
        again = key in _HELD
        if again:
            _HELD[key] += 1
    if again:  # this thread holds it already (a command, then its library function)
        try:
            yield path
        finally:
            with _HELD_GUARD:
                _HELD[key] -= 1
        return

    def refuse(exc: FolderLockError) -> FolderLockError:
        if on_refused is not None:
            on_refused(str(exc))
        return exc

    made: list[Path] = []
    lock: Any = None
    told = False
    try:
        for attempt in itertools.count():
            if attempt > _RETRIES and not wait:
                why = f"its lock file {path} keeps vanishing under it; try again"
                raise refuse(FolderLockError(f"cannot lock {what} {folder}: {why}"))
            try:
                made += _make_parents(path.parent)
            except OSError as exc:
                raise refuse(FolderLockError(f"cannot lock {what} {folder}: {exc}")) from None
            pid = _read_pid(path)
            candidate = FileLock(str(path), thread_local=False)
            try:
                candidate.acquire(timeout=0)
            except Timeout:
                if not wait:
                    pid = _read_pid(path) or pid
                    msg = (
                        f"{what} {folder} is being written by another microfab "
                        f"({_holder(pid)}); {hint}"
                    )
                    raise refuse(FolderLockedError(msg)) from None
                if on_wait is not None and not told:
                    told = True
                    on_wait(
                        f"waiting for {what} {folder}: it is being written by another "
                        f"microfab ({_holder(_read_pid(path) or pid)})"
                    )
                while True:
                    try:
                        candidate.acquire(timeout=poll_s)
                        break
                    except Timeout:
                        continue
            except FileNotFoundError:
                continue  # its folder vanished with a finishing holder: again
            except OSError as exc:
                raise refuse(FolderLockError(f"cannot lock {what} {folder}: {exc}")) from None
            if _held_path_is_ours(candidate, path):
                lock = candidate
                break
            candidate.release()  # a file its holder removed: take the path's new one
        _write_pid(lock)
        with _HELD_GUARD:
            _HELD[key] = 1
        try:
            yield path
        finally:
            with _HELD_GUARD:
                del _HELD[key]
            _remove_if_ours(lock, path)
            lock.release()
    finally:
        for d in made:  # deepest first; only when still empty
            with contextlib.suppress(OSError):
                d.rmdir()


def _command_context() -> Any:
    """The click context of the running command (typer's own click, or click's)."""
    import importlib

    # typer >= 0.2x carries its own copy of click (typer.main imports its
    # get_current_context); older typer uses click itself
    for name in ("typer.main", "click"):
        get = getattr(importlib.import_module(name), "get_current_context", None)
        ctx = get(silent=True) if get is not None else None
        if ctx is not None:
            return ctx
    raise RuntimeError("hold_for_command runs inside a microfab command only")


def hold_for_command(
    folder: str | os.PathLike[str] | None,
    option: str,
    *,
    on_refused: Callable[[str], Any],
    wait: bool = False,
    hint: str | None = None,
    on_wait: Callable[[str], Any] | None = None,
) -> None:
    """Lock ``folder`` until the running ``microfab`` command ends (its click context closes).

    One line in a command, after its output checks and before it reads the folder; the
    lock is released when the command returns, fails or is interrupted.

    Parameters
    ----------
    folder : str, os.PathLike or None
        The folder the command writes (``None``: not asked for; nothing is locked).
    option : str
        The option that names it, e.g. ``"--out"``, for the message.
    on_refused : callable
        The command's ``fail`` (prints the one ``error:`` line and exits 2).
    wait, on_wait
        As `folder_lock`.
    hint : str, optional
        What the refused user can do (default: wait, or give another folder).

    Raises
    ------
    RuntimeError
        Called outside a click command.
    """
    if folder is None:
        return
    _command_context().with_resource(
        folder_lock(
            folder,
            what=option,
            wait=wait,
            hint=hint or f"wait for it to finish, or give another {option}",
            on_refused=on_refused,
            on_wait=on_wait,
        )
    )
