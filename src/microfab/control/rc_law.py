"""The law of the plug-in repetitive control (RC) of seed 001 §3.3 and its settings.

`RCConfig` (period, sample time, ``Q``'s time constant, learning gain, phase lead,
windows), `period_samples`, the contraction `learning_factor`, and the per-sample rule
`rc_sample` with its per-period form `rc_update`: what the simulated RC
(`microfab.control.repetitive.PluginRC`) and its saved state
(`microfab.control.rc_memory.RCMemory`, the file-based step on hardware) both compute
with. The law, its low-pass ``Q`` and the derivative modes are described in
`microfab.control.repetitive`, which re-exports these names.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
from numba import njit

from microfab.core.signals import period_samples
from microfab.core.validate import check_in_range, check_int, check_positive

__all__ = [
    "DERIV_MODES",
    "RCConfig",
    "learning_factor",
    "period_samples",
    "rc_sample",
    "rc_update",
]

#: What the correction adds to a reference window's derivatives (`RCConfig.derivatives`),
#: in the order `microfab.control.repetitive.PluginRC` encodes them in its params.
DERIV_MODES = ("zero", "memory")


@dataclass(frozen=True, kw_only=True)
class RCConfig:
    """Settings of the plug-in RC.

    Parameters
    ----------
    period_s : float
        Period of the repeated contour, s; a whole number ``N`` of samples.
    dt : float
        Sample time, s (10 kHz assumed for the seed 001 twin).
    tau_s : float
        Time constant of ``Q(s) = 1 / (tau s + 1)`` (seed 001 §3.3 gives the form, not
        the value), s. Default: a 100 Hz cutoff (assumed: below the loop bandwidth of the
        inner controllers, where ``|1 - T|`` stays below 1; check with `learning_factor`).
    gain : float
        Learning gain ``k_r`` in (0, 2] (seed: none; 1 taken).
    lead_samples : int
        Phase lead ``m`` in samples, ``0 <= m < N`` (default 0).
    carry : bool
        Keep the memory from one window to the next (default False: see
        `microfab.control.repetitive`).
    derivatives : {"zero", "memory"}
        What the correction adds to the window's velocity and acceleration
        (`microfab.control.repetitive`).
    windows : tuple of (int, int), optional
        Active windows ``(start_sample, n_periods)`` in samples since `PluginRC.init`,
        increasing and not overlapping; ``None``: active from sample 0 on.
    """

    period_s: float
    dt: float = 1e-4  # assumed: 10 kHz, as the twin's data file
    tau_s: float = 1.0 / (2.0 * np.pi * 100.0)  # assumed: Q cutoff 100 Hz
    gain: float = 1.0  # seed 001 §3.3 gives no gain; 1 taken
    lead_samples: int = 0
    carry: bool = False
    derivatives: Literal["zero", "memory"] = "zero"
    windows: tuple[tuple[int, int], ...] | None = None

    def __post_init__(self) -> None:
        n = period_samples(self.period_s, self.dt)
        check_positive("tau_s (RC low-pass Q time constant)", self.tau_s, "s")
        check_in_range("gain (RC learning gain k_r)", self.gain, 0.0, 2.0, low_closed=False)
        check_int("lead_samples", self.lead_samples, 0, "samples")
        if self.lead_samples >= n:
            raise ValueError(
                f"lead_samples must be below the period ({n} samples), got {self.lead_samples}"
            )
        if not isinstance(self.carry, bool):
            raise ValueError(f"carry must be true or false, got {self.carry!r}")
        if self.derivatives not in DERIV_MODES:
            raise ValueError(
                f"derivatives must be one of {', '.join(DERIV_MODES)}, got {self.derivatives!r}"
            )
        if self.windows is not None:
            wins = tuple(tuple(w) for w in self.windows)
            if not wins:
                raise ValueError("windows must hold at least one (start_sample, n_periods)")
            end = -1
            for i, w in enumerate(wins):
                if len(w) != 2:
                    raise ValueError(f"window {i} must be (start_sample, n_periods), got {w}")
                s = check_int(f"window {i} start", w[0], 0, "samples")
                k = check_int(f"window {i} n_periods", w[1], 1, "periods")
                if s < end:
                    raise ValueError(
                        f"window {i} starts at sample {s}, before the previous one ends "
                        f"({end}): windows must increase and not overlap"
                    )
                end = s + k * n
            object.__setattr__(self, "windows", wins)

    @property
    def period_samples(self) -> int:
        """``N``, samples per period."""
        return period_samples(self.period_s, self.dt)

    @property
    def q(self) -> float:
        """Pole of the discretised ``Q``: ``exp(-dt / tau_s)``."""
        return float(np.exp(-self.dt / self.tau_s))

    def to_json(self) -> dict[str, Any]:
        """The config as JSON-ready values."""
        d = asdict(self)
        d["windows"] = None if self.windows is None else [list(w) for w in self.windows]
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RCConfig:
        """Inverse of `to_json`."""
        d = dict(d)
        if d.get("windows") is not None:
            d["windows"] = tuple(tuple(w) for w in d["windows"])
        return cls(**d)


def learning_factor(config: RCConfig, freq_hz: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Period-to-period contraction ``|Q (1 - k_r e^{jwm dt} T)|`` of the periodic error.

    Parameters
    ----------
    config : RCConfig
        The RC.
    freq_hz : numpy.ndarray
        Frequencies, Hz, shape (n,).
    T : numpy.ndarray
        Complementary sensitivity (reference to output) of the inner loop there, shape (n,).

    Returns
    -------
    numpy.ndarray
        Shape (n,); below 1 where the error contracts.
    """
    w = 2 * np.pi * np.asarray(freq_hz, dtype=float)
    z = np.exp(1j * w * config.dt)
    q = config.q
    Q = (1 - q) / (1 - q / z)
    lead = np.exp(1j * w * config.lead_samples * config.dt)
    return np.abs(Q * (1 - config.gain * lead * np.asarray(T)))


@njit(cache=True)
def rc_sample(
    M: np.ndarray,
    Ep: np.ndarray,
    ph: int,
    na: int,
    n: int,
    kr: float,
    q: float,
    qc: float,
    m: int,
) -> None:
    """The correction at phase ``ph`` of every axis, written into ``M`` in place.

    ``M`` (n * na,) holds ``c_j[0:ph]`` and ``c_{j-1}[ph:N]``; ``Ep`` (n * na,) the error
    of period ``j - 1``; row-major (phase, axis). ``qc = 1 - q``.
    """
    prev = ph - 1 if ph > 0 else n - 1
    lead = ph + m  # 0 <= m < n (RCConfig): one wrap at most, no integer division
    if lead >= n:
        lead -= n
    for a in range(na):
        xk = M[ph * na + a] + kr * Ep[lead * na + a]
        M[ph * na + a] = q * M[prev * na + a] + qc * xk


def rc_update(memory: np.ndarray, error_period: np.ndarray, config: RCConfig) -> np.ndarray:
    """Next period's correction from the last one and its measured error (file-based RC).

    The per-sample rule of `PluginRC` over a whole period: ``c_{j+1} = rc_update(c_j, e_j)``.

    Parameters
    ----------
    memory : numpy.ndarray
        Correction applied over the last period, mm, shape (N, n_axes).
    error_period : numpy.ndarray
        Tracking error ``r - y`` measured over that period, mm, shape (N, n_axes).
    config : RCConfig
        The RC (``N`` from its period).

    Returns
    -------
    numpy.ndarray
        The correction to add to the reference over the next period, shape (N, n_axes).

    Raises
    ------
    ValueError
        On a shape that is not (N, n_axes) or a value that is NaN or inf.
    """
    n = config.period_samples
    M = np.array(memory, dtype=np.float64, copy=True)
    E = np.ascontiguousarray(error_period, dtype=np.float64)
    for name, arr in (("memory", M), ("error_period", E)):
        if arr.ndim != 2 or arr.shape[0] != n or arr.shape[1] < 1:
            raise ValueError(
                f"{name} must be shaped (N = {n} samples of a period, n_axes), got {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} holds NaN or inf")
    if M.shape != E.shape:
        raise ValueError(f"memory {M.shape} and error_period {E.shape} must have one shape")
    na = M.shape[1]
    Mf, Ef = M.reshape(-1), E.reshape(-1)
    q = config.q
    for ph in range(n):
        rc_sample(Mf, Ef, ph, na, n, config.gain, q, 1.0 - q, config.lead_samples)
    return M
