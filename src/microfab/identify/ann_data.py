"""Training windows and scaling for the per-axis neural networks of seed 002 (eq. 7).

Seed 002 §III-B models each axis of the black-box stage by a causal feed-forward network
at 400 Hz,

``φ_i = f_nlm(r_{i-h}, ..., r_{i-1})``  (eq. 7),

``r`` the 400 Hz input trajectory (the command, one axis) and ``φ_i`` the measured
position at 400 Hz sample ``i`` ("the predicted position at the subsequent time step":
the output at the instant *after* the last input of the window; ``r_i`` itself is not an
input). ``h = 200``: the last 500 ms at 400 Hz (§III-B).

What is built here, and the choices made (the seed leaves them open):

* **Subsampling.** A run is recorded at ``run_rate_hz`` (10 kHz, seed 002 Table I); the
  400 Hz series are every ``factor``-th sample (25) from a start ``offset`` in
  ``[0, factor)``, taken as they are, with no anti-alias filter: ``r`` is a set-point
  (smooth commands, a ≤ 5 m/s² in the seed's data, nothing near 200 Hz) and ``φ_i`` is the
  encoder's reading at that instant, noise included, as the seed's encoders record it.
  Every offset is an equally valid 400 Hz view of a run; training uses all of them by
  default (25 windows per 400 Hz sample), and `microfab.identify.ann.AnnModel.predict`
  can predict every 10 kHz sample by interleaving the offsets.
* **Start of a run.** The runs start at rest (issue 17: "each from rest"), so the input
  before a run's first sample is its first command sample (the rest position): with
  ``pad=True`` (default) the history is padded with it and every 400 Hz sample of the
  run is a target, the first ones seeing mostly rest. With ``pad=False`` a run's windows
  start only once ``h`` samples of history exist.
* **Encoding** (a fixed, invertible linear map of the window; eq. 7 holds unchanged).
  ``"extrapolated"`` (default): inputs ``[r_{i-h} - r_{i-1}, ..., r_{i-2} - r_{i-1},
  r_{i-1}]`` and target ``φ_i - (2 r_{i-1} - r_{i-2})``, the error of the straight line
  through the last two commands. The network then learns a correction of ~a dt² plus the
  tracking error (tens of µm) rather than the absolute position (up to 0.19 m), so the
  seed's few-µm accuracy is ~10 % of the target's spread instead of ~1e-5, which a
  float32 network can reach; the absolute ``r_{i-1}`` stays an input for the
  position-dependent forces (cogging, cable carrier). ``"relative"``: the same inputs,
  target ``φ_i - r_{i-1}`` (~v dt, up to mm). ``"absolute"``: the window and ``φ_i`` as
  they are. On the twin (8 runs of 6 s, x, 20 epochs) the extrapolated target gave a
  validation σ of 4.3 µm where the relative one gave 9.5 µm.
* **Inputs.** ``"own"`` (default, seed 002 §III-B: "the most recent 500 ms of the input
  trajectory for the corresponding axis"): ``h`` inputs; ``"both"``: both axes' windows
  (x first), ``2 h`` inputs, for the coupling study the seed promises in §III-B.
* **Position features** (``features="position"``; default ``"none"``, the seed's 200
  inputs). A force that is a periodic function of the absolute position (a linear motor's
  cogging, a cable carrier's links) makes an error the seed's network must build from the
  one absolute input ``r_{i-1}``: many periods across the travel, which a LeakyReLU
  network learns poorly. With this option the inputs also hold ``sin`` and ``cos`` of
  ``2π r_{i-k} / λ_j`` for the lags ``k`` of `FEATURE_LAGS` and the wavelengths ``λ_j``
  of `FEATURE_WAVELENGTHS_M` (own axis; both axes with ``inputs="both"``): still a
  function of the window, so eq. 7 holds; 208 more inputs per axis. Measured on the
  calibrated twin (x, noise off, 300 s of random runs, 150 s of training): with the
  friction off, so that the cogging is the nonlinearity, validation σ 21.5 µm of a
  23.3 µm target without the features, 3.3 µm with them; the full twin 22.9 -> 14.6 µm.
  With the ``stage-identify`` job's data and schedule: validation σ x / y 13.9 / 24.8 µm
  against about 19 / 38 without, but the letters at 1 m/s² (shapes the training never
  saw) 27.3 / 61.3 against 21.6 / 41.4: the features also let the network tie the
  friction's effects to places, which does not carry over. Hence an option, off by
  default (issue 34's note).
* **Scaling.** After encoding, every input column and the target get an offset (mean) and
  a scale (standard deviation) fitted on the training windows (`Scaling`), stored with
  the model; a column that does not vary keeps scale 1.

Windows are never built by a Python loop per window: `windows` returns a strided view
(`numpy.lib.stride_tricks.sliding_window_view`) and `WindowSet.batch` gathers a batch by
one fancy index from the concatenated 400 Hz series (memory stays that of the series,
not ``h`` times it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from microfab.core.validate import check_int, check_positive
from microfab.identify.ann_digest import SUMMARY_POINTS as SUMMARY_POINTS
from microfab.identify.ann_digest import (
    Run,
    data_digest,
    data_summary,
    summary_deviation,
)
from microfab.identify.ann_scaling import Scaling

__all__ = [
    "AXES",
    "ENCODINGS",
    "FEATURES",
    "FEATURE_LAGS",
    "FEATURE_WAVELENGTHS_M",
    "HISTORY",
    "INPUTS",
    "MODEL_RATE_HZ",
    "RUN_RATE_HZ",
    "Scaling",
    "WindowSet",
    "WindowSpec",
    "check_run",
    "data_digest",
    "data_summary",
    "summary_deviation",
    "windows",
]

AXES = ("x", "y")  # column order of every command and measured array
MODEL_RATE_HZ = 400.0  # seed 002 §III-B: "subsampled at 400Hz"
RUN_RATE_HZ = 10_000.0  # seed 002 Table I: low-level control loop frequency 10 kHz
HISTORY = 200  # seed 002 §III-B: 500 ms at 400 Hz, "leading to 200 inputs"
ENCODINGS = ("extrapolated", "relative", "absolute")
INPUTS = ("own", "both")
FEATURES = ("none", "position")
#: Wavelengths of the position features, m: 5 per decade from 251 mm to 1 mm (13), so
#: that a position-periodic force of any pitch in that span lies within a factor 10^0.1
#: (26 %) of one of them. Assumed: the span covers Table I's 0.38 m travel down to the
#: pitch of fine mechanics; no pitch of the twin is among them (its cogging is 24 mm).
FEATURE_WAVELENGTHS_M: tuple[float, ...] = tuple(10.0 ** (-k / 5.0) for k in range(3, 16))
#: Lags of the position features, model samples back (r_{i-1} ... r_{i-16}: the last
#: 40 ms at 400 Hz). Assumed: a position-dependent force acts on the output through the
#: built-in loop over about its response time (a 25 Hz loop: some 40 ms); denser near now.
FEATURE_LAGS: tuple[int, ...] = (1, 2, 3, 4, 6, 8, 12, 16)


@dataclass(frozen=True, kw_only=True)
class WindowSpec:
    """How a run becomes windows (see the module docstring).

    Parameters
    ----------
    run_rate_hz : float
        Sample rate of the recorded runs, Hz (10 kHz, seed 002 Table I); a whole
        multiple of ``rate_hz``.
    rate_hz : float
        Model rate, Hz (400 Hz, seed 002 §III-B).
    h : int
        History length in model samples (200 = 500 ms at 400 Hz, seed 002 §III-B).
    inputs : {"own", "both"}
        The axis's own command window (seed), or both axes' windows (coupling study).
    encoding : {"relative", "extrapolated", "absolute"}
        Window relative to its last sample; target relative to the straight line
        through its last two samples (default) or to the last sample; or both raw.
    pad : bool
        Pad the history before a run's first sample with that sample (the rest position).
    features : {"none", "position"}
        The seed's inputs only, or also the position features (module docstring).
    """

    run_rate_hz: float = RUN_RATE_HZ
    rate_hz: float = MODEL_RATE_HZ
    h: int = HISTORY
    inputs: str = "own"
    encoding: str = "extrapolated"
    pad: bool = True
    features: str = "none"

    def __post_init__(self) -> None:
        check_positive("run_rate_hz", self.run_rate_hz, "Hz")
        check_positive("rate_hz", self.rate_hz, "Hz")
        ratio = self.run_rate_hz / self.rate_hz
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise ValueError(
                f"run_rate_hz must be a whole multiple of rate_hz ({self.rate_hz:g} Hz), got "
                f"{self.run_rate_hz:g} Hz; resample the run to e.g. "
                f"{round(max(ratio, 1.0)) * self.rate_hz:g} Hz"
            )
        h = check_int("h (history length)", self.h, 2, "samples")
        if self.inputs not in INPUTS:
            raise ValueError(f"inputs must be one of {INPUTS}, got {self.inputs!r}")
        if self.encoding not in ENCODINGS:
            raise ValueError(f"encoding must be one of {ENCODINGS}, got {self.encoding!r}")
        if not isinstance(self.pad, bool):
            raise ValueError(f"pad must be True or False, got {self.pad!r}")
        if self.features not in FEATURES:
            raise ValueError(f"features must be one of {FEATURES}, got {self.features!r}")
        if self.features == "position" and h < max(FEATURE_LAGS):
            raise ValueError(f"position features need a history h >= {max(FEATURE_LAGS)}, got {h}")
        object.__setattr__(self, "h", h)
        object.__setattr__(self, "run_rate_hz", float(self.run_rate_hz))
        object.__setattr__(self, "rate_hz", float(self.rate_hz))

    @property
    def factor(self) -> int:
        """Run samples per model sample (25 for 10 kHz -> 400 Hz)."""
        return round(self.run_rate_hz / self.rate_hz)

    @property
    def n_features(self) -> int:
        """Position features per axis (0 without them)."""
        if self.features == "none":
            return 0
        return 2 * len(FEATURE_LAGS) * len(FEATURE_WAVELENGTHS_M)

    @property
    def n_inputs(self) -> int:
        """Network inputs: ``h`` plus the features, per axis read (own: 1, both: 2)."""
        return (self.h + self.n_features) * (2 if self.inputs == "both" else 1)

    @property
    def min_run_samples(self) -> int:
        """Shortest run accepted, run samples (``h`` model samples: 500 ms)."""
        return self.h * self.factor

    def as_dict(self) -> dict[str, Any]:
        """JSON form (all fields)."""
        return {
            "run_rate_hz": self.run_rate_hz,
            "rate_hz": self.rate_hz,
            "h": self.h,
            "inputs": self.inputs,
            "encoding": self.encoding,
            "pad": self.pad,
            "features": self.features,
        }


def check_run(
    command: np.ndarray, measured: np.ndarray | None, spec: WindowSpec, name: str = "run"
) -> tuple[np.ndarray, np.ndarray | None]:
    """Check one run and return it as float64 arrays.

    Parameters
    ----------
    command : numpy.ndarray
        Commanded position ``ρ`` per axis, shape (n, 2) (x, y), m, at ``spec.run_rate_hz``.
    measured : numpy.ndarray or None
        Measured position ``γ``, shape (n, 2), m; None when only predicting.
    spec : WindowSpec
        The window specification (rate, history).
    name : str
        The run's name for messages.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray or None)
        ``command`` and ``measured`` as C-contiguous float64.

    Raises
    ------
    ValueError
        Wrong shape, lengths that differ, a non-finite sample (named), or a run shorter
        than ``h`` model samples (500 ms).
    """
    out: list[np.ndarray | None] = []
    for what, a in (("command", command), ("measured output", measured)):
        if a is None:
            out.append(None)
            continue
        arr = np.ascontiguousarray(a, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != len(AXES):
            raise ValueError(
                f"{name}: the {what} must have shape (n_samples, 2) (columns x, y), got {arr.shape}"
            )
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            k, a_i = bad[0]
            raise ValueError(
                f"{name}: the {what} has a non-finite value {arr[k, a_i]} at sample {k} "
                f"of axis {AXES[a_i]}"
            )
        out.append(arr)
    cmd, meas = out
    assert cmd is not None
    if meas is not None and meas.shape != cmd.shape:
        raise ValueError(
            f"{name}: command and measured output differ in length: "
            f"{cmd.shape[0]} and {meas.shape[0]} samples"
        )
    if cmd.shape[0] < spec.min_run_samples:
        raise ValueError(
            f"{name}: a run must last at least the history h = {spec.h} samples at "
            f"{spec.rate_hz:g} Hz ({spec.h / spec.rate_hz * 1e3:g} ms, {spec.min_run_samples} "
            f"samples at {spec.run_rate_hz:g} Hz), got {cmd.shape[0]} samples"
        )
    return cmd, meas


def _encode(win: np.ndarray, spec: WindowSpec) -> tuple[np.ndarray, np.ndarray]:
    """Encode raw windows (b, h) of one axis; returns (encoded (b, h), base (b,))."""
    last = win[:, -1].copy()
    if spec.encoding == "absolute":
        return np.array(win, dtype=np.float64), np.zeros_like(last)
    enc = win - last[:, None]
    enc[:, -1] = last
    if spec.encoding == "extrapolated":
        return enc, 2.0 * last - win[:, -2]
    return enc, last


def _encode_axes(
    raw: list[np.ndarray], axis: int, spec: WindowSpec
) -> tuple[np.ndarray, np.ndarray]:
    """Encoded network inputs for ``axis`` from raw windows of both axes; base of ``axis``."""
    enc = [_encode(w, spec) for w in raw]
    base = enc[axis][1]
    read = (axis,) if spec.inputs == "own" else tuple(range(len(raw)))
    parts = [enc[a][0] for a in read]
    if spec.features == "position":
        parts += [position_features(raw[a]) for a in read]
    return (parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)), base


def position_features(win: np.ndarray) -> np.ndarray:
    """The position features of raw windows (b, h), m: shape (b, 208) (module docstring).

    Columns: for each lag ``k`` of `FEATURE_LAGS`, ``sin`` of every wavelength of
    `FEATURE_WAVELENGTHS_M`, then ``cos``.
    """
    pos = win[:, [-k for k in FEATURE_LAGS]]  # (b, lags)
    phase = (2.0 * np.pi) * pos[:, :, None] / np.asarray(FEATURE_WAVELENGTHS_M)
    return np.concatenate([np.sin(phase), np.cos(phase)], axis=2).reshape(win.shape[0], -1)


def windows(
    command: np.ndarray,
    measured: np.ndarray | None,
    spec: WindowSpec,
    *,
    axis: int,
    offset: int = 0,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Encoded windows of one run at one start offset (vectorised, strided view).

    Parameters
    ----------
    command, measured : numpy.ndarray
        One run, shape (n, 2), m, at ``spec.run_rate_hz`` (``measured`` may be None).
    spec : WindowSpec
        The window specification.
    axis : int
        Output axis, 0 (x) or 1 (y).
    offset : int
        Start offset of the subsampling, in run samples, ``0 <= offset < spec.factor``.

    Returns
    -------
    inputs : numpy.ndarray
        Shape (n_windows, spec.n_inputs), encoded, unscaled. Row ``j`` holds the
        commands at model samples ``i-h .. i-1`` of target sample ``i`` (``i = j`` with
        ``pad``, ``i = j + h`` without).
    target : numpy.ndarray or None
        Shape (n_windows,), the encoded measured position at sample ``i``.
    base : numpy.ndarray
        Shape (n_windows,): add to a decoded target to get the position (``r_{i-1}`` for
        the relative encoding, ``2 r_{i-1} - r_{i-2}`` for the extrapolated one, 0 for the
        absolute one).
    """
    cmd, meas = check_run(command, measured, spec)
    factor = spec.factor
    offset = check_int("offset", offset, 0, "samples")
    if not 0 <= offset < factor:
        raise ValueError(f"offset must lie in [0, {factor}) run samples, got {offset}")
    if axis not in (0, 1):
        raise ValueError(f"axis must be 0 (x) or 1 (y), got {axis!r}")
    r = cmd[offset::factor]
    m = r.shape[0]
    h = spec.h
    if spec.pad:
        r = np.concatenate([np.repeat(cmd[:1], h, axis=0), r])
        first = 0
    else:
        first = h
    n_win = m - first
    raw = [sliding_window_view(r[:, a], h)[:n_win] for a in range(len(AXES))]
    inputs, base = _encode_axes(raw, axis, spec)
    target = None
    if meas is not None:
        y = meas[offset::factor, axis][first:]
        target = y - base
    return inputs, target, base


class WindowSet:
    """All windows of many runs and offsets, gathered by index, never materialised.

    The 400 Hz command series of every (run, offset) are stored one after the other
    (each preceded by ``h`` rest samples when ``spec.pad``); a window is its start index
    in that array, so a batch is one fancy index ``series[start[:, None] + arange(h)]``.

    Parameters
    ----------
    runs : sequence of (command, measured)
        Each (n, 2), m, at ``spec.run_rate_hz`` (see `check_run`).
    spec : WindowSpec
        The window specification.
    offsets : sequence of int, optional
        Subsampling offsets to use (default all, ``0 .. factor-1``).
    """

    def __init__(
        self, runs: Sequence[Run], spec: WindowSpec, offsets: Sequence[int] | None = None
    ) -> None:
        if len(runs) == 0:
            raise ValueError("at least one run is needed")
        factor, h = spec.factor, spec.h
        offs = tuple(range(factor)) if offsets is None else tuple(offsets)
        for o in offs:
            if not 0 <= check_int("offset", o, 0, "samples") < factor:
                raise ValueError(f"offsets must lie in [0, {factor}) run samples, got {o}")
        series: list[np.ndarray] = []
        targets: list[np.ndarray] = []
        starts: list[np.ndarray] = []
        pos = 0
        accel_max = np.zeros(len(AXES))
        for k, (command, measured) in enumerate(runs):
            cmd, meas = check_run(command, measured, spec, name=f"run {k}")
            assert meas is not None
            for o in offs:
                r = cmd[o::factor]
                y = meas[o::factor]
                if r.shape[0] > 2:
                    acc = np.abs(np.diff(r, n=2, axis=0)).max(axis=0) * spec.rate_hz**2
                    accel_max = np.maximum(accel_max, acc)
                if spec.pad:
                    r = np.concatenate([np.repeat(cmd[:1], h, axis=0), r])
                    first = 0
                else:
                    first = h
                n_win = y.shape[0] - first
                series.append(r)
                targets.append(y[first:])
                starts.append(pos + np.arange(n_win, dtype=np.int64))
                pos += r.shape[0]
        self.spec = spec
        self.offsets = offs
        self.series = np.concatenate(series)
        self.targets = np.concatenate(targets)
        self.starts = np.concatenate(starts)
        self._ar = np.arange(h, dtype=np.int64)
        self._accel_max = accel_max
        self._columns = [np.ascontiguousarray(self.series[:, a]) for a in range(len(AXES))]

    def __len__(self) -> int:
        return int(self.starts.shape[0])

    def batch(self, index: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Encoded, unscaled inputs (b, n_inputs) and targets (b,) of windows ``index``."""
        rows = self.starts[index][:, None] + self._ar
        raw = [col[rows] for col in self._columns]
        inputs, base = _encode_axes(raw, axis, self.spec)
        return inputs, self.targets[index, axis] - base

    def fit_scaling(self, axis: int, chunk: int = 65_536) -> Scaling:
        """`Scaling` of all windows for ``axis``, in one pass in chunks of ``chunk``.

        The moments are summed about a shift (the first chunk's mean), so one pass is as
        accurate as two: the variance is ``E[(x - c)^2] - (E[x] - c)^2`` with ``c`` close to
        the mean. Each chunk's windows are encoded once (the encoding is most of the cost).
        """
        n = len(self)
        idx = np.arange(n)
        c: np.ndarray | None = None
        ct = 0.0
        s = np.zeros(self.spec.n_inputs)
        s2 = np.zeros(self.spec.n_inputs)
        st = st2 = 0.0
        for i in range(0, n, chunk):
            x, t = self.batch(idx[i : i + chunk], axis)
            if c is None:
                c, ct = x.mean(axis=0), float(t.mean())
            d, dt = x - c, t - ct
            s += d.sum(axis=0)
            s2 += (d * d).sum(axis=0)
            st += float(dt.sum())
            st2 += float((dt * dt).sum())
        if c is None:  # no window: refused there, naming the count
            return Scaling._from_moments(n, s, s2, 0.0, 0.0)
        m, mt = s / n, st / n
        var = np.maximum(s2 / n - m * m, 0.0)
        vt = max(st2 / n - mt * mt, 0.0)
        return Scaling._from_moments(n, c + m, var, ct + mt, vt)

    def command_accel_max(self) -> list[float]:
        """Largest |second difference| / dt² of the 400 Hz commands per axis, m/s²."""
        return [float(v) for v in self._accel_max]
