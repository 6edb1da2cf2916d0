"""Trained RBF networks and RC memory exported for a real-time target: round trip, the
exported network computes the controller's command, refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from microfab.control.base import ReferenceWindow
from microfab.control.export import (
    EXPORT_FORMAT,
    EXPORT_VERSION,
    RBFExport,
    export_controller,
    load_exported,
)
from microfab.control.rbf import RBFAdaptive, RBFConfig
from microfab.control.rc_memory import RCMemory
from microfab.control.repetitive import RCConfig

DT = 1e-4  # assumed 10 kHz (the seed 001 twin's)
N = 200


def _circle() -> tuple[np.ndarray, ...]:
    t = np.arange(N) * DT
    w = 2 * np.pi / (N * DT)
    pos = 0.1 + 0.075 * np.column_stack([np.cos(w * t), np.sin(w * t)])
    vel = 0.075 * w * np.column_stack([-np.sin(w * t), np.cos(w * t)])
    return pos, vel, -(w**2) * (pos - 0.1)


def _trained() -> tuple[RBFAdaptive, np.ndarray, RCMemory]:
    pos, vel, acc = _circle()
    rbf = RBFAdaptive.for_reference(pos, vel, acc, DT, RBFConfig(n_nodes=9))
    rng = np.random.default_rng(4)
    # a stand-in for a run on the stage: the network adapts along a noisy lagging output
    log = rbf.replay(pos, vel, acc, pos + rng.normal(0, 1e-3, pos.shape) - 2e-3)
    mem = RCMemory.initial(RCConfig(period_s=N * DT, dt=DT, lead_samples=3), 2)
    for _ in range(3):
        mem = mem.after_period(rng.normal(0, 1e-3, (N, 2)))
    return rbf, log.final_state, mem


@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_round_trip_keeps_every_array_and_setting(tmp_path: Path, suffix: str) -> None:
    rbf, state, mem = _trained()
    assert np.abs(rbf.weights(state)).max() > 0  # trained weights, not Ŵ(0) = 0
    path = export_controller(
        tmp_path / f"ctrl{suffix}",
        rbf=rbf,
        rbf_state=state,
        rc=mem,
        meta={"machine": "xy stage", "job": 7},
    )
    got = load_exported(path)
    assert got.version == EXPORT_VERSION and got.meta == {"machine": "xy stage", "job": 7}
    r = got.rbf
    assert r is not None and r.n_axes == 2 and r.n_nodes == 9
    np.testing.assert_array_equal(r.weights, rbf.weights(state))
    for a, net in enumerate(rbf.networks):
        for name in ("centres", "widths", "offset", "scale"):
            np.testing.assert_array_equal(getattr(r, name)[a], getattr(net, name))
    np.testing.assert_array_equal(r.gamma, rbf.config.gamma_diagonal())
    np.testing.assert_array_equal(r.estimator, rbf.config.estimator.discrete(DT))
    assert (r.lam, r.sigma, r.dt) == (rbf.config.lam, rbf.config.sigma, DT)
    rc = got.rc
    assert rc is not None and rc.config == mem.config and rc.samples == 3 * N
    for name in ("memory", "error", "error_current", "inner"):
        np.testing.assert_array_equal(getattr(rc, name), getattr(mem, name))
    np.testing.assert_array_equal(rc.next_correction(), mem.next_correction())
    assert not list(tmp_path.glob(".*"))  # atomic: no temporary file left


def test_the_exported_network_gives_the_controllers_command() -> None:
    rbf, state, _ = _trained()
    pos, vel, acc = _circle()
    exp = RBFExport.from_controller(rbf, state)
    k = 37
    win = ReferenceWindow(
        position=pos[k : k + 1], velocity=vel[k : k + 1], acceleration=acc[k : k + 1]
    )
    u, after = rbf.step(state, win, pos[k] + 3e-3)
    # the state logs h of both axes and the scaled z of the last axis (y); see RBFAdaptive
    nl = rbf.n_nodes
    ih = 2 * nl + 6
    iz = ih + 2 * nl
    z_y = after[iz : iz + 6] * exp.scale[1] + exp.offset[1]
    h_y = after[ih + nl : ih + 2 * nl]
    np.testing.assert_allclose(exp.hidden(1, z_y), h_y, rtol=1e-12, atol=0)
    assert exp.weights[1] @ h_y == pytest.approx(u[1], rel=1e-12)
    z = np.stack([np.zeros(6), z_y])
    assert exp.command(z)[1] == pytest.approx(u[1], rel=1e-12)
    assert abs(u[1]) > 1e-6  # the check is not between zeros


def test_plain_arrays_export_without_adaptation(tmp_path: Path) -> None:
    w = np.array([[0.5, -0.25]])
    c = np.zeros((1, 2, 6))
    c[0, 1, 4] = 1.0
    exp = RBFExport(weights=w, centres=c, widths=np.ones((1, 2)), lam=100.0, dt=DT)
    got = load_exported(export_controller(tmp_path / "a.npz", rbf=exp)).rbf
    assert got is not None and got.gamma is None and got.estimator is None
    np.testing.assert_array_equal(got.offset, 0.0)
    # z at the first centre: h = (1, exp(-1/2))
    assert got.command(np.zeros((1, 6)))[0] == pytest.approx(0.5 - 0.25 * np.exp(-0.5))
    assert load_exported(export_controller(tmp_path / "b.h5", rc=_trained()[2])).rbf is None


def test_bad_exports_and_files_are_refused(tmp_path: Path) -> None:
    rbf, state, mem = _trained()
    with pytest.raises(ValueError, match=r"must end in \.npz, \.h5, \.hdf5"):
        export_controller(tmp_path / "c.txt", rc=mem)
    with pytest.raises(ValueError, match="nothing to export"):
        export_controller(tmp_path / "c.npz")
    good = export_controller(tmp_path / "c.npz", rc=mem)
    before = good.read_bytes()
    with pytest.raises(ValueError, match="meta must be JSON-ready"):
        export_controller(good, rc=mem, meta={"t": object()})
    with pytest.raises(ValueError, match="meta must be JSON-ready"):
        export_controller(good, rc=mem, meta={"t": float("nan")})
    assert good.read_bytes() == before  # a refused export leaves the old file
    with pytest.raises(ValueError, match="rbf_state goes with an RBFAdaptive"):
        export_controller(good, rbf=RBFExport.from_controller(rbf), rbf_state=state)
    with pytest.raises(ValueError, match=r"centres must be shaped \(axes, nodes, 6\)"):
        RBFExport(
            weights=np.zeros((2, 3)),
            centres=np.zeros((2, 3, 4)),
            widths=np.ones((2, 3)),
            lam=1.0,
            dt=DT,
        )
    with pytest.raises(ValueError, match="widths must be positive"):
        RBFExport(
            weights=np.zeros((1, 1)),
            centres=np.zeros((1, 1, 6)),
            widths=np.zeros((1, 1)),
            lam=1.0,
            dt=DT,
        )
    with pytest.raises(ValueError, match=r"gamma .* and sigma .* together"):
        RBFExport(
            weights=np.zeros((1, 1)),
            centres=np.zeros((1, 1, 6)),
            widths=np.ones((1, 1)),
            lam=1.0,
            dt=DT,
            gamma=np.ones(1),
        )


def _patched_npz(src: Path, dst: Path, **changes: object) -> Path:
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    arrays |= {k: np.array(v) for k, v in changes.items()}
    np.savez(dst, **arrays)
    return dst


def test_other_formats_and_newer_versions_are_refused(tmp_path: Path) -> None:
    _, _, mem = _trained()
    good = export_controller(tmp_path / "c.npz", rc=mem)
    newer = _patched_npz(good, tmp_path / "n.npz", version=EXPORT_VERSION + 1)
    with pytest.raises(ValueError, match=r"export version 2, newer .* upgrade microfab"):
        load_exported(newer)
    with pytest.raises(ValueError, match="unknown export version 0"):
        load_exported(_patched_npz(good, tmp_path / "z.npz", version=0))
    with pytest.raises(ValueError, match="not a microfab controller export"):
        load_exported(_patched_npz(good, tmp_path / "o.npz", format="something-else"))
    mem.save(tmp_path / "rc_state.npz")  # an RC state is not an export
    with pytest.raises(ValueError, match="not a microfab controller export"):
        load_exported(tmp_path / "rc_state.npz")
    head = json.loads(str(np.load(good)["meta"]))
    head["rc"]["config"]["period_s"] = 0.5 * N * DT
    with pytest.raises(ValueError, match="inconsistent"):
        load_exported(_patched_npz(good, tmp_path / "i.npz", meta=json.dumps(head)))
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(ValueError, match="cannot read controller export"):
        load_exported(tmp_path / "junk.npz")
    with pytest.raises(FileNotFoundError, match="no controller export"):
        load_exported(tmp_path / "missing.h5")
    import h5py

    h5 = export_controller(tmp_path / "c.h5", rc=mem)
    with h5py.File(h5, "r+") as f:
        f.attrs["version"] = EXPORT_VERSION + 1
    with pytest.raises(ValueError, match=r"newer .* upgrade microfab"):
        load_exported(h5)
    with h5py.File(h5, "r+") as f:
        f.attrs["format"] = "x"
    with pytest.raises(ValueError, match="not a microfab controller export"):
        load_exported(h5)
    assert EXPORT_FORMAT == "microfab-controller-export"
