"""Checkpoint files of the seed 001 job: batches of chunks round-trip; foreign runs refused."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.machines.nanomanipulator.chunks import (
    Chunk,
    chunk_path,
    load_chunks,
    save_chunks,
)
from microfab.sim.loop import LoopState


def _chunk(rng, n, final_circle=None, with_loop=True):
    loop = LoopState(
        plant=rng.standard_normal(5),
        controller=rng.standard_normal(40),
        observer=np.zeros(0),
        command=rng.standard_normal(2),
    )
    return Chunk(
        output=rng.standard_normal((n, 2)),
        measured=rng.standard_normal((n, 2)),
        command=rng.standard_normal((n, 2)),
        laser=rng.random(n) > 0.5,
        log_index=np.arange(0, n, 3),
        log_w=rng.standard_normal((len(range(0, n, 3)), 2)),
        log_s=rng.standard_normal((len(range(0, n, 3)), 2)),
        loop=loop if with_loop else None,
        gate=rng.standard_normal(4) if with_loop else None,
        final_circle=final_circle,
        final_controller=None if final_circle is None else rng.standard_normal(40),
    )


def test_batches_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    first = [_chunk(rng, 7), _chunk(rng, 5, final_circle=0), _chunk(rng, 9)]
    second = [_chunk(rng, 4, final_circle=1), _chunk(rng, 6, final_circle=2)]
    save_chunks(tmp_path, 0, first, "fp")
    save_chunks(tmp_path, 3, second, "fp")
    got = load_chunks(tmp_path, "fp", total=8)
    assert len(got) == 5
    for want, have in zip(first + second, got, strict=True):
        for name in ("output", "measured", "command", "laser", "log_index", "log_w", "log_s"):
            np.testing.assert_array_equal(getattr(have, name), getattr(want, name), name)
        assert have.final_circle == want.final_circle
        if want.final_controller is not None:
            np.testing.assert_array_equal(have.final_controller, want.final_controller)
    # only the last chunk of a file carries the loop state
    assert [c.loop is not None for c in got] == [False, False, True, False, True]
    np.testing.assert_array_equal(got[2].loop.controller, first[2].loop.controller)
    np.testing.assert_array_equal(got[4].gate, second[1].gate)


def test_reading_stops_at_the_first_missing_file(tmp_path):
    rng = np.random.default_rng(1)
    save_chunks(tmp_path, 0, [_chunk(rng, 3)], "fp")
    save_chunks(tmp_path, 2, [_chunk(rng, 3)], "fp")  # chunk 1 missing
    assert len(load_chunks(tmp_path, "fp", total=5)) == 1
    assert load_chunks(tmp_path / "nothing", "fp", total=5) == []


def test_foreign_or_old_runs_are_refused(tmp_path):
    rng = np.random.default_rng(2)
    save_chunks(tmp_path, 0, [_chunk(rng, 3), _chunk(rng, 3)], "fp")
    with pytest.raises(ValueError, match="job checkpoint of other settings: job"):
        load_chunks(tmp_path, "other", total=5)
    with pytest.raises(ValueError, match="more chunks than this job"):
        load_chunks(tmp_path, "fp", total=1)
    data = chunk_path(tmp_path, 0).read_bytes()
    chunk_path(tmp_path, 0).write_bytes(data[: len(data) // 3])  # cut short
    with pytest.raises(ValueError, match="not a readable nanomanipulator job checkpoint"):
        load_chunks(tmp_path, "fp", total=5)
    (tmp_path / "state.npz").write_bytes(b"")
    with pytest.raises(ValueError, match="format 1"):
        load_chunks(tmp_path, "fp", total=5)


def test_a_checkpoint_needs_the_state_after_it(tmp_path):
    rng = np.random.default_rng(3)
    with pytest.raises(ValueError, match="loop state"):
        save_chunks(tmp_path, 0, [_chunk(rng, 3, with_loop=False)], "fp")
    with pytest.raises(ValueError, match="at least one"):
        save_chunks(tmp_path, 0, [], "fp")
    assert not chunk_path(tmp_path, 0).exists()
