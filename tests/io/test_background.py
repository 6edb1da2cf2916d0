"""`BackgroundWriter`: order, close waits, errors reach the caller, none saved after a failure."""

from __future__ import annotations

import threading
import time

import pytest

from microfab.io.atomic import atomic_write_text
from microfab.io.background import BackgroundWriter


def test_saves_run_in_order_and_close_waits(tmp_path):
    done: list[int] = []

    def slow(i: int) -> None:
        time.sleep(0.01 * (5 - i))  # the first is the slowest: order must still hold
        done.append(i)
        atomic_write_text(tmp_path / f"{i}.txt", str(i))

    with BackgroundWriter(max_pending=2) as w:
        for i in range(5):
            w.submit(slow, i)
    assert done == [0, 1, 2, 3, 4]
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{i}.txt" for i in range(5)]


def test_saves_run_off_the_calling_thread():
    names: list[str] = []
    with BackgroundWriter() as w:
        w.submit(lambda: names.append(threading.current_thread().name))
    assert names and names[0] != threading.current_thread().name


def test_a_failed_save_is_raised_and_later_saves_are_skipped(tmp_path):
    ran: list[int] = []
    gate = threading.Event()

    def save(i: int) -> None:
        gate.wait(5)
        if i == 1:
            raise OSError("disk full")
        ran.append(i)

    w = BackgroundWriter(max_pending=8)
    for i in range(4):
        w.submit(save, i)
    gate.set()
    with pytest.raises(OSError, match="disk full"):
        w.close()
    assert ran == [0]  # 2 and 3 come after the failed 1: not written
    w.close()  # closing twice is harmless
    with pytest.raises(RuntimeError, match="closed"):
        w.submit(save, 5)


def test_the_error_reaches_the_next_submit():
    w = BackgroundWriter(max_pending=1)
    w.submit(lambda: (_ for _ in ()).throw(ValueError("bad save")))
    with pytest.raises(ValueError, match="bad save"):
        w.submit(lambda: None)  # waits for the one pending: its error is raised here
    with pytest.raises(ValueError, match="bad save"):
        w.close()


def test_an_interrupted_body_still_lands_its_saves(tmp_path):
    with pytest.raises(KeyboardInterrupt), BackgroundWriter() as w:
        for i in range(3):
            w.submit(atomic_write_text, tmp_path / f"{i}.txt", str(i))
        raise KeyboardInterrupt
    assert len(list(tmp_path.iterdir())) == 3


def test_the_body_error_wins_and_notes_the_save_error():
    def fail() -> None:
        raise OSError("disk full")

    with pytest.raises(KeyError) as info, BackgroundWriter() as w:
        w.submit(fail)
        time.sleep(0.05)
        raise KeyError("body")
    assert any("disk full" in n for n in getattr(info.value, "__notes__", []))


def test_max_pending_is_checked():
    with pytest.raises(ValueError, match="max_pending"):
        BackgroundWriter(max_pending=0)
