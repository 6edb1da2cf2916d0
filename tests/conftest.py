"""Shared fixtures: a tiny stage model for the optimisation tests (optimize, cli, experiments).

The "stage" is a per-axis second-order lag (70 and 60 rad/s) with a feedthrough, simulated
at 10 kHz; the networks (Fig. 5, h = 200) train for a few epochs on
its response to smooth random commands. They are poor models; the tests check the
optimisation's mechanics, not the seed's numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

FS = 10_000.0


def axis_model(wn: float, zeta: float, wz: float, d: float):
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[wn**2 - d * wn**2, wz - d * 2 * zeta * wn]])
    return a, b, c, np.array([[d]])


def stage_matrices(d: float = 0.9):
    mx, my = axis_model(70.0, 0.5, 40.0, d), axis_model(60.0, 0.6, 30.0, d)
    z2, z1 = np.zeros((2, 2)), np.zeros((2, 1))
    a = np.block([[mx[0], z2], [z2, my[0]]])
    b = np.block([[mx[1], z1], [z1, my[1]]])
    c = np.block([[mx[2], np.zeros((1, 2))], [np.zeros((1, 2)), my[2]]])
    return a, b, c, np.diag([d, d])


def smooth_run(n: int, seed: int, amplitude_m: float = 3e-3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    bb, aa = scipy.signal.butter(2, 4.0 / (FS / 2))
    u = np.cumsum(scipy.signal.lfilter(bb, aa, rng.standard_normal((n, 2)), axis=0), axis=0)
    u -= u[0]
    u *= amplitude_m / np.abs(u).max()
    ramp = np.clip(np.arange(n) / 2000.0, 0.0, 1.0)
    u *= (ramp**2 * (3 - 2 * ramp))[:, None]
    a, b, c, d = stage_matrices()
    sys = scipy.signal.StateSpace(a, b, c, d).to_discrete(1 / FS)
    _, y, _ = scipy.signal.dlsim(sys, u)
    return u, np.asarray(y)


@pytest.fixture(scope="session")
def tiny_models(tmp_path_factory):
    """A folder like a stage-identify output: linear_model.json and ann/model."""
    pytest.importorskip("torch")
    from microfab.identify.ann import AnnConfig
    from microfab.identify.ann_data import WindowSpec
    from microfab.identify.ann_train import train_ann
    from microfab.identify.stage_ann import save_ann_model
    from microfab.identify.stage_data import StageLinearModel, write_stage_model
    from microfab.identify.subspace_model import SubspaceModel

    d = tmp_path_factory.mktemp("models")
    train = [smooth_run(12_000, s) for s in range(3)]
    val = [smooth_run(8_000, 10)]
    cfg = AnnConfig(window=WindowSpec(), batch_size=512, offsets=(0, 7, 13),
                    learning_rate=2e-3, max_epochs=4, device="cpu", threads=1)  # fmt: skip
    model = train_ann(train, val, cfg)
    save_ann_model(model, d / "ann" / "model")
    a, b, c, dd = stage_matrices()
    dsys = scipy.signal.StateSpace(a, b, c, dd).to_discrete(1e-3)
    sub = SubspaceModel(a=dsys.A, b=dsys.B, c=dsys.C, d=dsys.D, dt=1e-3, x0=np.zeros((1, 4)),
                        singular_values=np.ones(4), block_rows=10, weighting="n4sid",
                        fit_mean=np.zeros(4), fit_std=np.ones(4))  # fmt: skip
    write_stage_model(d / "linear_model.json",
                      StageLinearModel(model=sub, input_dt=1e-4, decimate=10))  # fmt: skip
    return d, model
