"""`microfab.io.lock`: one writer per folder (issue 44, cause E).

The lock is taken by another process, by another thread, again by the same thread, after
a holder killed with SIGKILL, and waited for; a refusal leaves the folder's parent as it
was (no lock file, no folder made); the run store refuses a second writer.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from microfab.io.lock import (
    FolderLockedError,
    _held_path_is_ours,
    folder_lock,
    lock_path,
)
from microfab.io.runstore import open_run

#: A child that holds a folder's lock until it is killed or its stdin closes; it prints
#: "held" once it holds it.
HOLDER = """
import sys
from microfab.io.lock import folder_lock
with folder_lock(sys.argv[1], what="state"):
    print("held", flush=True)
    sys.stdin.read()
"""


def _holder(folder: Path) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(folder)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "held"
    return proc


def _listing(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def test_lock_file_is_beside_the_folder_and_gone_afterwards(tmp_path: Path) -> None:
    folder = tmp_path / "a" / "b" / "state"
    with folder_lock(folder) as held:
        assert held == lock_path(folder) == tmp_path.resolve() / "a" / "b" / ".state.lock"
        assert held.read_text().strip() == str(os.getpid())
        with folder_lock(folder):  # the same thread again: re-entry, no deadlock
            pass
        assert held.exists()  # the inner exit does not release the outer hold
    # the lock file and the folders made for it are gone: nothing is left behind
    assert _listing(tmp_path) == []


def test_two_spellings_of_one_folder_share_one_lock(tmp_path: Path) -> None:
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    assert lock_path(tmp_path / "link") == lock_path(tmp_path / "real")
    assert lock_path(tmp_path / "x" / ".." / "real") == lock_path(tmp_path / "real")


def test_another_process_is_refused_naming_the_holder(tmp_path: Path) -> None:
    folder = tmp_path / "state"
    proc = _holder(folder)
    try:
        before = _listing(tmp_path)
        with pytest.raises(FolderLockedError) as err, folder_lock(folder, what="--state"):
            pytest.fail("entered a folder another process holds")
        msg = str(err.value)
        assert msg.startswith(f"--state {folder} is being written by another microfab ")
        assert f"(pid {proc.pid})" in msg and "\n" not in msg
        assert isinstance(err.value, OSError) and isinstance(err.value, ValueError)
        assert _listing(tmp_path) == before  # the refusal touched nothing
    finally:
        proc.communicate("")
    assert proc.returncode == 0
    assert _listing(tmp_path) == []  # the holder removed its lock file


def test_another_thread_is_refused_and_a_waiter_gets_it_after(tmp_path: Path) -> None:
    folder = tmp_path / "out"
    errors: list[str] = []
    waited: list[float] = []
    told: list[str] = []

    def refused() -> None:
        try:
            with folder_lock(folder):
                errors.append("entered")
        except FolderLockedError as exc:
            errors.append(str(exc))

    def waiter() -> None:
        t0 = time.monotonic()
        with folder_lock(folder, wait=True, on_wait=told.append, poll_s=0.02):
            waited.append(time.monotonic() - t0)

    with folder_lock(folder):
        t = threading.Thread(target=refused)
        t.start()
        t.join()
        w = threading.Thread(target=waiter)
        w.start()
        time.sleep(0.3)
        assert not waited  # still waiting while the folder is held
    w.join(timeout=10)
    assert len(errors) == 1 and "this process, another thread" in errors[0]
    assert len(waited) == 1 and waited[0] >= 0.25
    assert len(told) == 1 and told[0].startswith(f"waiting for folder {folder}")
    assert _listing(tmp_path) == []


def test_a_holder_killed_with_sigkill_leaves_a_stale_file_taken_over_at_once(
    tmp_path: Path,
) -> None:
    folder = tmp_path / "state"
    proc = _holder(folder)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    stale = lock_path(folder)
    # the dead holder's file (and its pid) are left; the OS dropped its lock with it
    assert stale.read_text().strip() == str(proc.pid)
    t0 = time.monotonic()
    with folder_lock(folder) as held:
        assert time.monotonic() - t0 < 5.0  # taken over, not waited for
        assert held.read_text().strip() == str(os.getpid())
    assert not stale.exists()


def test_a_lock_on_a_file_its_holder_removed_is_not_ours(tmp_path: Path) -> None:
    from filelock import FileLock

    path = tmp_path / ".x.lock"
    lock = FileLock(str(path), thread_local=False)
    lock.acquire(timeout=0)
    try:
        assert _held_path_is_ours(lock, path)
        path.unlink()  # what a finishing holder does while a waiter has the file open
        assert not _held_path_is_ours(lock, path)
        path.touch()  # another writer's new file of the same name
        assert not _held_path_is_ours(lock, path)
    finally:
        lock.release()


def test_the_run_store_refuses_a_second_writer(tmp_path: Path) -> None:
    root = tmp_path / "run"
    proc = _holder(root)
    try:
        with (
            pytest.raises(FolderLockedError, match="being written by another microfab"),
            open_run(root, {"a": 1}, other_hint="give another --out"),
        ):
            pytest.fail("opened a run folder another process holds")
        assert not root.exists()
    finally:
        proc.communicate("")
    with open_run(root, {"a": 1}) as store:  # free again: the run starts
        assert not store.resumed
    assert _listing(tmp_path) == []  # nothing written, no lock file left
