"""The identified model: discrete (A, B, C, D), its continuous form (d2c), poles, files.

`SubspaceModel` is what `identify/subspace.py` returns: the discrete model in the records'
units, the training runs' initial states, the singular values of the order check and the
training simulation error (seed 002 Table II's μ, σ). `SubspaceModel.to_continuous` gives
seed 002 eq. (6)'s continuous ``(A, B, C, D)`` by the inverse zero-order hold, as MATLAB's
``d2c`` does after ``n4sid``: ``[[A_c, B_c], [0, 0]] = logm([[A, B], [0, I]]) / dt``
(`scipy.linalg.logm`; python-control has no d2c, its ``sample_system`` is the check in the
tests). A real discrete pole at or below zero has no real logarithm and is refused.

**Decimated data** (``to_continuous(hold_dt=...)``). The inverse ZOH at the model's own
``dt`` assumes the input was held for ``dt``. A model fitted after an anti-alias
decimation (`microfab.identify.stage_data.decimate`, by ``q``) was not: the machine held
its set-point for the *raw* sample time ``dt / q`` (the stage's 10 kHz loop, seed 002
Table I), and the zero-phase FIR applied alike to input and output keeps their ratio in
the band, so the fitted model's response there is that of the system sampled with a ZOH at
``dt / q``: ``G_d(e^{jωdt}) ≈ G_{zoh, dt/q}(e^{jω dt/q})``, a half raw sample of lag
(``e^{-jω dt/2q}``). The inverse ZOH at ``dt`` reads it as half a *model* sample of lag and
gives a continuous model with a lead of ``ω (dt - dt/q) / 2``: 0.063 rad, 6.3 %, at 40 Hz
for 2 kHz data fitted at 1 kHz (``tests/identify/test_subspace_model.py``). Neither a
band-limited reading (``G_c(jω) = G_d``: half a raw sample of lag left in) nor a
first-order hold fixes that: only the raw hold does. So the conversion keeps the poles
(``A_c = logm(A) / dt``, exact for any intersample assumption) and ``C``, and chooses
``B_c``, ``D_c`` so that the ZOH discretisation of ``(A_c, B_c, C, D_c)`` at ``hold_dt``
has the fitted model's frequency response on the band ``[0, band x Nyquist]`` (linear
least squares: that response is linear in ``B_c`` and ``D_c``), the static gain held
exactly (weighted). With ``hold_dt = dt`` the least squares has the inverse ZOH as its
exact solution, and the closed form is used.

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

__all__ = ["CONTINUOUS_BAND", "FORMAT", "VERSION", "ContinuousModel", "SubspaceModel"]

FORMAT = "microfab.identify.SubspaceModel"
VERSION = 1
_REAL_POLE_TOL = 1e-12  # |Im z| <= this |z|: a real pole
#: Share of the model's Nyquist frequency on which `SubspaceModel.to_continuous` matches a
#: decimated model's response (assumed: half, well inside the decimation FIR's pass band,
#: which ends at about two thirds of the new Nyquist for order 20 q, Hamming; above it
#: the data held little and aliased power).
CONTINUOUS_BAND = 0.5
_BAND_POINTS = 256  # frequencies of that match, uniform from 0 (assumed: ~1 Hz apart at 1 kHz)
_DC_WEIGHT = 1e3  # weight of the static gain's row in that match (assumed: held to ~1e-6)


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

    def to_continuous(
        self, hold_dt: float | None = None, *, band: float = CONTINUOUS_BAND
    ) -> ContinuousModel:
        """Continuous ``(A, B, C, D)``: the inverse zero-order hold at the data's hold time.

        Without ``hold_dt`` (or with ``hold_dt == dt``), MATLAB's ``d2c``:
        ``[[A_c, B_c], [0, 0]] = logm([[A, B], [0, I]]) / dt``; ``C`` and ``D``
        unchanged. The principal matrix logarithm (`scipy.linalg.logm`) is real when no
        eigenvalue of A is real and negative or zero. With a shorter ``hold_dt`` (a model
        fitted to decimated data: the raw sample time), ``A_c`` and ``C`` as above and
        ``B_c``, ``D_c`` such that the ZOH discretisation at ``hold_dt`` matches this
        model's frequency response on ``[0, band x Nyquist]`` (module docstring).

        Parameters
        ----------
        hold_dt : float, optional
            Time the input of the data was held for, s (the raw sample time
            ``dt / decimate``); at most ``dt``. Default ``dt``.
        band : float
            Share of the model's Nyquist frequency matched (0 < band <= 1; default
            `CONTINUOUS_BAND`). Used only when ``hold_dt < dt``.

        Raises
        ------
        ValueError
            A real pole at or below zero: a sampled continuous system has none (the
            discrete model has a mode that alternates sign every sample); a ``hold_dt``
            not in (0, dt] or a ``band`` not in (0, 1].
        """
        _check_log(np.linalg.eigvals(self.a))
        if hold_dt is not None:
            check_positive("hold_dt", hold_dt, "s")
            if hold_dt > self.dt * (1.0 + 1e-9):
                raise ValueError(
                    f"hold_dt {hold_dt:g} s is longer than the model's dt {self.dt:g} s"
                )
            if not 0.0 < band <= 1.0:
                raise ValueError(f"band must be in (0, 1] of the Nyquist frequency, got {band!r}")
            if hold_dt < self.dt * (1.0 - 1e-9):
                return self._held_continuous(float(hold_dt), band)
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

    def _held_continuous(self, hold_dt: float, band: float) -> ContinuousModel:
        """`to_continuous` for data held for ``hold_dt < dt`` (module docstring)."""
        n, m, p = self.order, self.n_inputs, self.n_outputs
        lg = scipy.linalg.logm(self.a)
        a_c = np.real(lg) / self.dt
        # ZOH at hold_dt: A0 = e^{A_c h}, Gamma0 = int_0^h e^{A_c s} ds (per unit B_c)
        big = np.zeros((2 * n, 2 * n))
        big[:n, :n] = a_c * hold_dt
        big[:n, n:] = np.eye(n) * hold_dt
        e = scipy.linalg.expm(big)
        a0, gamma0 = e[:n, :n], e[:n, n:]
        w = np.linspace(0.0, band * math.pi / self.dt, _BAND_POINTS)  # rad/s
        eye = np.eye(n)
        z, z0 = np.exp(1j * w * self.dt), np.exp(1j * w * hold_dt)
        target = self.c @ np.linalg.solve(z[:, None, None] * eye - self.a, self.b) + self.d
        basis = self.c @ np.linalg.solve(z0[:, None, None] * eye - a0, gamma0)  # (K, p, n)
        rows = np.concatenate([basis, np.broadcast_to(np.eye(p), (w.size, p, p))], axis=2)
        weight = np.ones((w.size, 1, 1))
        weight[0] = _DC_WEIGHT  # the static gain held (the stage's y ~ rho)
        lhs = np.concatenate([(weight * rows).real, (weight * rows).imag]).reshape(-1, n + p)
        rhs = np.concatenate([(weight * target).real, (weight * target).imag]).reshape(-1, m)
        sol = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
        return ContinuousModel(a=readonly(a_c), b=readonly(sol[:n]), c=self.c, d=readonly(sol[n:]))

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
