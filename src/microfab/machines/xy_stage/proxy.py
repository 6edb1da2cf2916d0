"""A cheap proxy for the networks' σ: what part of the output the seed's inputs cannot predict.

Seed 002's networks (eq. 7, §III-B) predict each axis's position at 400 Hz from the last
500 ms of that axis's command (200 inputs); their validation σ (Table II: 3.2 / 6.0 µm)
bounds the part of the real stage's output that is not predictable from that window.
Training the networks takes far too long inside a calibration loop (issue 46), so the
calibration fits this proxy instead:

* the **same windows** as the networks (`microfab.identify.ann_data.windows` with the
  `microfab.identify.stage_ann.ann_config` spec: 400 Hz, h = 200, own axis, the
  extrapolated encoding, padded at the start of each run), on the same train / validation
  split of the same data (`microfab.machines.xy_stage.ann.ann_records`);
* a **fixed random-feature regression** (an "extreme learning machine": one hidden layer
  whose weights are drawn once from a fixed seed and never trained, LeakyReLU as the
  seed's networks, and a ridge-regression read-out), together with the encoded window
  itself (so the proxy is never worse than a linear regression on the window);
* its σ is the standard deviation of the measured minus the predicted position on the
  validation windows, per axis.

It is a regression of the same inputs onto the same target with a fixed nonlinear basis:
deterministic (a fixed seed), a linear solve per axis, about a second on a minute of data.
**Measured against the full training once** (`ProxySettings.recent`: the data file's twin,
60 s of the networks' data, seed 0): proxy σ x / y 28.5 / 49.6 µm, the networks trained
with the ``stage-identify`` job's schedule 23.1 / 36.4 µm: 23 % and 36 % above. The issue
asks for 25 %: on y this proxy does not yet meet it (it over-states the unpredictable
part), so it is to be improved or replaced before its σ is trusted as the networks'.
A second twin (the answer of `calibration_core`'s real run: friction 35 / 14 N): proxy
8.0 / 8.7 µm, the networks (same schedule, 328 s) 7.0 / 5.6 µm: 14 % and 55 % above.
On x the proxy is within 25 % on both twins; on y it is not on either.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from microfab.core.threads import single_threaded
from microfab.core.validate import check_int, check_positive
from microfab.identify.ann_data import HISTORY, MODEL_RATE_HZ, WindowSpec, windows
from microfab.identify.stage_data import StageRecord

__all__ = ["ProxySettings", "proxy_sigma"]


@dataclass(frozen=True, kw_only=True)
class ProxySettings:
    """The random-feature regression of `proxy_sigma`.

    Parameters
    ----------
    hidden : int
        Random hidden units (assumed 400: twice the 200 inputs, a few times fewer than
        the training windows of a minute of data, so the read-out is well determined).
    recent : int or None
        The hidden units read only the window's last ``recent`` encoded inputs (the most
        recent lags and the absolute position; the read-out still sees the whole window
        linearly). Assumed 50 (125 ms). Measured on 60 s of the networks' data (the data
        file's twin, seed 0; 400 units), validation σ x / y µm: all 200 33.0 / 59.6, 100
        31.0 / 54.3, 50 28.5 / 49.6, 20 30.9 / 53.4, 8 35.3 / 61.4; 1500 units at 50:
        27.6 / 49.1. The networks trained on the same data with the ``stage-identify``
        job's schedule (60 epochs, 282 s on 2 cores): 23.1 / 36.4 µm. The proxy lies 23 %
        (x) and 36 % (y) above them: y is outside the issue's 25 %.
    offsets : int
        Subsampling offsets of the training windows, spread over the 25 of 10 kHz -> 400 Hz
        (assumed 2: twice the windows at the cost of one more pass; the validation uses
        offset 0).
    ridge : float
        Ridge weight relative to the mean diagonal of the feature Gram matrix. Assumed
        1e-2; measured on the twin of the data file (60 s of the networks' data, seed 0),
        validation σ x / y µm: 36.7 / 73.2 at 1e-4, 33.0 / 59.6 at 1e-2, 35.8 / 62.4 at
        1e-1; the window alone (a linear regression) 39.8 / 69.2.
    slope : float
        Negative slope of the LeakyReLU (assumed 0.01, PyTorch's default, as the seed's
        networks, §III-B).
    seed : int
        Seed of the random hidden weights.
    """

    hidden: int = 400
    recent: int | None = 50
    offsets: int = 2
    ridge: float = 1e-2
    slope: float = 0.01
    seed: int = 0

    def __post_init__(self) -> None:
        check_int("hidden", self.hidden, 1, "units")
        check_int("offsets", self.offsets, 1)
        check_positive("ridge", self.ridge)
        check_int("seed", self.seed, 0)


def _spec(dt: float) -> WindowSpec:
    # the networks' windows: seed 002 §III-B, 400 Hz, h = 200 (ann_config's spec)
    return WindowSpec(run_rate_hz=1.0 / dt, rate_hz=MODEL_RATE_HZ, h=HISTORY)


def _design(
    records: Sequence[StageRecord], spec: WindowSpec, axis: int, offsets: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    xs, ts = [], []
    for r in records:
        for off in offsets:
            x, t, _ = windows(r.u, r.y, spec, axis=axis, offset=off)
            assert t is not None
            xs.append(x)
            ts.append(t)
    return np.concatenate(xs), np.concatenate(ts)


def _features(x: np.ndarray, w: np.ndarray, b: np.ndarray, slope: float) -> np.ndarray:
    z = x[:, -w.shape[0] :] @ w + b
    return np.concatenate([x, np.where(z > 0.0, z, slope * z), np.ones((x.shape[0], 1))], axis=1)


@single_threaded
def proxy_sigma(
    train: Sequence[StageRecord],
    val: Sequence[StageRecord],
    dt: float,
    settings: ProxySettings | None = None,
) -> tuple[float, float]:
    """σ of the validation error of the random-feature regression, per axis (x, y), m.

    Parameters
    ----------
    train, val : sequence of StageRecord
        Runs played on the twin at ``1 / dt`` (10 kHz), command ``u`` and measured ``y``
        (n, 2), m; each at least 500 ms long.
    dt : float
        Sample time of the runs, s.
    settings : ProxySettings, optional
        Hidden units, offsets, ridge, seed.

    Returns
    -------
    tuple of float
        ``(σ_x, σ_y)``, m; NaN for an axis whose regression is not finite.
    """
    s = ProxySettings() if settings is None else settings
    spec = _spec(dt)
    offs = sorted({round(k * spec.factor / s.offsets) for k in range(s.offsets)})
    rng = np.random.default_rng(s.seed)
    out = []
    for axis in (0, 1):
        x, t = _design(train, spec, axis, offs)
        xv, tv = _design(val, spec, axis, (0,))
        mu, sd = x.mean(axis=0), x.std(axis=0)
        sd = np.where(sd > 0.0, sd, 1.0)
        x, xv = (x - mu) / sd, (xv - mu) / sd
        t_mu, t_sd = float(t.mean()), float(t.std()) or 1.0
        k = x.shape[1] if s.recent is None else min(s.recent, x.shape[1])
        w = rng.standard_normal((k, s.hidden)) / np.sqrt(k)
        b = rng.standard_normal(s.hidden)
        gram = np.zeros((x.shape[1] + s.hidden + 1,) * 2)
        rhs = np.zeros(gram.shape[0])
        for k in range(0, x.shape[0], 8192):
            f = _features(x[k : k + 8192], w, b, s.slope)
            gram += f.T @ f
            rhs += f.T @ ((t[k : k + 8192] - t_mu) / t_sd)
        gram[np.diag_indices_from(gram)] += s.ridge * float(np.mean(np.diag(gram)))
        try:
            beta = np.linalg.solve(gram, rhs)
        except np.linalg.LinAlgError:
            out.append(float("nan"))
            continue
        pred = _features(xv, w, b, s.slope) @ beta * t_sd + t_mu
        err = tv - pred
        out.append(float(np.std(err)) if np.all(np.isfinite(err)) else float("nan"))
    return out[0], out[1]
