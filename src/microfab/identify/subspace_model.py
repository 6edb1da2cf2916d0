"""The identified model: discrete (A, B, C, D), its continuous form (d2c), poles, files.

`SubspaceModel` is what `identify/subspace.py` returns: the discrete model in the records'
units, the training runs' initial states, the singular values of the order check and the
training simulation error (seed 002 Table II's μ, σ). `SubspaceModel.to_continuous` gives
seed 002 eq. (6)'s continuous ``(A, B, C, D)`` by the inverse zero-order hold, as MATLAB's
``d2c`` does after ``n4sid``: ``[[A_c, B_c], [0, 0]] = logm([[A, B], [0, I]]) / dt``
(`scipy.linalg.logm`; python-control has no d2c, its ``sample_system`` is the check in the
tests). A real discrete pole at or below zero has no real logarithm and is refused.

`to_dict` / `from_dict` give the JSON form (format, version, ``dt`` and rate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from microfab.core.arrays import readonly
from microfab.core.validate import check_positive
from microfab.identify.subspace_data import check_runs
from microfab.identify.subspace_fit import error_moments, simulate_ss

__all__ = ["FORMAT", "VERSION", "ContinuousModel", "SubspaceModel"]

FORMAT = "microfab.identify.SubspaceModel"
VERSION = 1
_REAL_POLE_TOL = 1e-12  # |Im z| <= this |z|: a real pole


@dataclass(frozen=True, eq=False)
class ContinuousModel:
    """Continuous-time ``dz/dt = A z + B u``, ``y = C z + D u`` (seed 002 eq. 6), s.

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        Shapes (n, n), (n, m), (p, n), (p, m); ``a`` in 1/s, ``b`` in (state)/(input s).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray

    @property
    def poles(self) -> np.ndarray:
        """Eigenvalues of A, rad/s, sorted by magnitude."""
        return _sorted(np.linalg.eigvals(self.a))

    def to_control(self) -> Any:
        """The model as a python-control ``StateSpace``."""
        import control

        return control.ss(self.a, self.b, self.c, self.d)


def _sorted(z: np.ndarray) -> np.ndarray:
    return z[np.lexsort((z.imag, np.abs(z)))]


@dataclass(frozen=True, eq=False)
class SubspaceModel:
    """An identified discrete-time state-space model (frozen; arrays read-only).

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        Shapes (n, n), (n, m), (p, n), (p, m), in the records' units.
    dt : float
        Sample time, s.
    x0 : numpy.ndarray
        Initial state of each training run, shape (n_runs, n) (zeros if not estimated).
    singular_values : numpy.ndarray
        Singular values of the weighted oblique projection (scaled data), largest first:
        a gap after the n-th shows the order.
    block_rows : int
        ``i`` used.
    weighting : str
        ``"n4sid"``, ``"moesp"`` or ``"cva"``.
    fit_mean, fit_std : numpy.ndarray
        Mean and standard deviation per output of the simulation error ``y - y_model`` on
        the training runs (from each run's ``x0``), output units (seed 002 Table II μ, σ).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    dt: float
    x0: np.ndarray
    singular_values: np.ndarray
    block_rows: int
    weighting: str
    fit_mean: np.ndarray
    fit_std: np.ndarray

    def __post_init__(self) -> None:
        check_positive("dt", self.dt, "s")
        for name in _ARRAYS:
            arr = readonly(getattr(self, name))
            if not np.isfinite(arr).all():
                raise ValueError(f"{name} holds a NaN or infinite value")
            object.__setattr__(self, name, arr)
        n = self.a.shape[0] if self.a.ndim == 2 else -1
        shapes = {"a": (n, n), "b": (n, None), "c": (None, n), "d": (None, None)}
        for name, (r, c) in shapes.items():
            arr = getattr(self, name)
            if (
                arr.ndim != 2
                or (r is not None and arr.shape[0] != r)
                or (c is not None and arr.shape[1] != c)
            ):
                raise ValueError(
                    f"{name} has shape {arr.shape}, inconsistent with a of shape {self.a.shape}"
                )
        if self.d.shape != (self.c.shape[0], self.b.shape[1]):
            raise ValueError(
                f"d has shape {self.d.shape}, expected (p, m) = "
                f"{(self.c.shape[0], self.b.shape[1])}"
            )
        if self.x0.ndim != 2 or self.x0.shape[1] != n:
            raise ValueError(f"x0 must have shape (n_runs, {n}), got {self.x0.shape}")
        object.__setattr__(self, "dt", float(self.dt))

    @property
    def order(self) -> int:
        """Number of states n."""
        return int(self.a.shape[0])

    @property
    def n_inputs(self) -> int:
        """Number of inputs m."""
        return int(self.b.shape[1])

    @property
    def n_outputs(self) -> int:
        """Number of outputs p."""
        return int(self.c.shape[0])

    @property
    def poles(self) -> np.ndarray:
        """Discrete poles (eigenvalues of A), sorted by magnitude."""
        return _sorted(np.linalg.eigvals(self.a))

    def continuous_poles(self) -> np.ndarray:
        """Poles ``log(z) / dt``, rad/s (refuses negative real z: no real logarithm)."""
        z = self.poles
        _check_log(z)
        return _sorted(np.log(z.astype(complex)) / self.dt)

    def poles_hz(self) -> np.ndarray:
        """Natural frequency ``|s| / 2 pi`` of each continuous pole, Hz."""
        return np.abs(self.continuous_poles()) / (2.0 * math.pi)

    def time_constants_s(self) -> np.ndarray:
        """Time constant ``-1 / Re(s)`` of each continuous pole, s, slowest first."""
        return np.sort(-1.0 / self.continuous_poles().real)[::-1]

    def to_continuous(self) -> ContinuousModel:
        """Continuous ``(A, B, C, D)`` by the inverse zero-order hold (MATLAB ``d2c``).

        ``[[A_c, B_c], [0, 0]] = logm([[A, B], [0, I]]) / dt``; ``C`` and ``D`` unchanged.
        The principal matrix logarithm (`scipy.linalg.logm`) is real when no eigenvalue of
        A is real and negative or zero.

        Raises
        ------
        ValueError
            A real pole at or below zero: a sampled continuous system has none (the
            discrete model has a mode that alternates sign every sample).
        """
        _check_log(np.linalg.eigvals(self.a))
        n, m = self.order, self.n_inputs
        big = np.zeros((n + m, n + m))
        big[:n, :n] = self.a
        big[:n, n:] = self.b
        big[n:, n:] = np.eye(m)
        lg = scipy.linalg.logm(big)
        scale = max(1.0, float(np.abs(lg).max()))
        if np.iscomplexobj(lg):
            if np.abs(lg.imag).max() > 1e-9 * scale:  # pragma: no cover - guarded above
                raise ValueError("the matrix logarithm is not real")
            lg = lg.real
        lg = lg / self.dt
        return ContinuousModel(a=readonly(lg[:n, :n]), b=readonly(lg[:n, n:]), c=self.c, d=self.d)

    def simulate(self, u: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Output (N, p) for inputs ``u`` (N, m) from ``x0`` (default zero: at rest)."""
        u2 = np.asarray(u, dtype=np.float64)
        if u2.ndim == 1:
            u2 = u2[:, None]
        if u2.ndim != 2 or u2.shape[1] != self.n_inputs:
            raise ValueError(f"u must have shape (N, {self.n_inputs}), got {np.shape(u)}")
        x = np.zeros(self.order) if x0 is None else np.asarray(x0, dtype=np.float64)
        if x.shape != (self.order,):
            raise ValueError(f"x0 must have shape ({self.order},), got {x.shape}")
        return simulate_ss(self.a, self.b, self.c, self.d, u2, x)

    def prediction_error(
        self, u: np.ndarray, y: np.ndarray, x0: np.ndarray | None = None
    ) -> np.ndarray:
        """Simulation error ``y - simulate(u, x0)``, shape (N, p)."""
        y2 = np.asarray(y, dtype=np.float64)
        if y2.ndim == 1:
            y2 = y2[:, None]
        sim = self.simulate(u, x0)
        if y2.shape != sim.shape:
            raise ValueError(f"y must have shape {sim.shape}, got {np.shape(y)}")
        return y2 - sim

    def error_stats(self, runs: Any, x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Mean and standard deviation per output of the simulation error over ``runs``.

        Parameters
        ----------
        runs : IORun, (u, y) pair or a sequence of them
            Records (e.g. validation runs from rest).
        x0 : numpy.ndarray or None
            Initial state per run, shape (n_runs, n); None: zero (runs from rest).

        Returns
        -------
        mean, std : numpy.ndarray
            Shapes (p,), output units (seed 002 Table II μ, σ). No memory grows with N.
        """
        checked = check_runs(runs, 1)
        x = np.zeros((len(checked), self.order)) if x0 is None else np.asarray(x0, float)
        if x.shape != (len(checked), self.order):
            raise ValueError(f"x0 must have shape {(len(checked), self.order)}, got {x.shape}")
        return error_moments(self.a, self.b, self.c, self.d, checked, x)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (format, version, dt, rate; every array as nested lists)."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "dt": self.dt,
            "rate_hz": 1.0 / self.dt,
            "order": self.order,
            "block_rows": self.block_rows,
            "weighting": self.weighting,
            **{k: getattr(self, k).tolist() for k in _ARRAYS},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SubspaceModel:
        """Inverse of `to_dict`.

        Raises
        ------
        ValueError
            Another format or version, a rate that disagrees with ``dt``, unknown or
            missing keys, inconsistent shapes, a non-finite value.
        """
        if not isinstance(data, dict):
            raise ValueError(f"a subspace model must be a mapping, got {type(data).__name__}")
        if data.get("format") != FORMAT:
            raise ValueError(f"not a {FORMAT} (format {data.get('format')!r})")
        if data.get("version") != VERSION:
            raise ValueError(
                f"subspace model version {data.get('version')!r} is not supported "
                f"(this microfab reads version {VERSION})"
            )
        if set(data) != _KEYS:
            extra, missing = sorted(set(data) - _KEYS), sorted(_KEYS - set(data))
            raise ValueError(f"subspace model keys: unknown {extra}, missing {missing}")
        dt = check_positive("dt", data["dt"], "s")
        rate = check_positive("rate_hz", data["rate_hz"], "Hz")
        if abs(rate * dt - 1.0) > 1e-9:
            raise ValueError(f"rate_hz {rate} disagrees with dt {dt} s (1/dt = {1 / dt} Hz)")
        arrays = {k: np.asarray(data[k], dtype=np.float64) for k in _ARRAYS}
        if arrays["x0"].size == 0:
            arrays["x0"] = arrays["x0"].reshape(0, arrays["a"].shape[0])
        model = cls(
            dt=dt, block_rows=int(data["block_rows"]), weighting=str(data["weighting"]), **arrays
        )
        if model.order != data["order"]:
            raise ValueError(f"order {data['order']!r} disagrees with A of size {model.order}")
        return model


_ARRAYS = ("a", "b", "c", "d", "x0", "singular_values", "fit_mean", "fit_std")
_KEYS = frozenset(
    {"format", "version", "dt", "rate_hz", "order", "block_rows", "weighting", *_ARRAYS}
)


def _check_log(z: np.ndarray) -> None:
    bad = [p for p in z if abs(p.imag) <= _REAL_POLE_TOL * max(abs(p), 1e-300) and p.real <= 0]
    if bad:
        raise ValueError(
            f"discrete pole {complex(bad[0]).real:.6g} is real and not positive: it has no "
            "real logarithm, so no continuous model samples to it (an alternating mode, "
            "often a sign of too high an order or of noise); try a lower order"
        )
