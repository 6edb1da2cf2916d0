"""Plug-in repetitive control (RC) of seed 001 §3.3, Figs. 6-7.

The RC wraps an inner feedback controller (the RBF controller of seed 001 §3.2, or a
`microfab.control.pid.PID`) and adds its output ``c`` to the inner loop's **reference**,
as Fig. 7 draws it (seed 001 Remark 2 says instead that RC "only adjusts the input
(x, x̄)" of the network: the same point seen from the network, whose position inputs then
see the corrected tracking error; the stability argument of Theorem 1 is untouched either
way). Per axis, at phase ``p`` of period ``j`` (``N`` samples a period):

``c_j[p] = Q( c_{j-1}[p] + k_r e_{j-1}[(p + m) mod N] )``,

with ``e = r - y`` the tracking error against the original (uncorrected) reference,
``B(s) = 1`` (seed 001 §3.3: the RBF loop's complementary sensitivity is taken as 1),
the learning gain ``k_r`` (seed: none given; 1 by default), an optional phase lead of
``m`` samples (0 by default), and the seed's low-pass ``Q(s) = 1 / (tau s + 1)``
(seed 001 §3.3) discretised with its pole matched, ``q = exp(-dt / tau)``, unit gain at
DC and no delay:

``Q(z) = (1 - q) / (1 - q z^-1)``, i.e. ``w_k = q w_{k-1} + (1 - q) x_k``

(the ZOH discretisation advanced by one sample, so that Q adds no pure delay inside the
period loop). The filter runs along the period: its previous output is the correction
just applied, ``c_j[p-1]`` (``c_{j-1}[N-1]`` at ``p = 0``), so the state of the RC is just
its one-period memory of corrections and errors. The lead reads the previous period's
error circularly (``(p + m) mod N``), so a period's correction uses that period's
predecessor only: the per-sample rule and the file-based `rc_update` (one measured period
-> next correction) are the same computation (`rc_sample`).

Where ``|Q(e^jw) (1 - k_r e^{jwm dt} T(e^jw))| < 1`` (`learning_factor`; ``T`` the inner
loop's complementary sensitivity) the periodic error contracts from period to period; at
the harmonics of the period the remaining error is ``|1 - Q| / |1 - Q + Q k_r e^{jwm dt} T|``
of the inner loop's.

Derivatives of the correction for the inner controller's reference window
(`RCConfig.derivatives`): ``"zero"`` (default) adds the correction to the position only,
as Remark 2 reads; ``"memory"`` adds central differences of the correction memory along
the period (velocity ``(c[p+1] - c[p-1]) / 2dt``, acceleration
``(c[p+1] - 2c[p] + c[p-1]) / dt²``, ``c[p+1]`` from the previous period), which are
usable without noise only: measurement noise that passes ``Q`` is amplified by ``1/dt²``.
Rows of a preview window beyond the current sample get the memory at those phases.

Paused circles (`RCConfig.windows`): the RC is active in given windows of whole periods
(in samples since `PluginRC.init`), passes the reference through unchanged outside them,
and by default (``carry=False``) starts each window with an empty memory: each circle of
the seed's job lies elsewhere in the field, where the stiffness nonlinearity (seed 001
§3.1) differs, so a memory learned on one circle is not the next circle's.

The law and its settings (`RCConfig`, `period_samples`, `learning_factor`, `rc_sample`,
`rc_update`) live in `microfab.control.rc_law`, below both this module and the saved state
(`microfab.control.rc_memory`), and are re-exported here.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.control.rc_law import (
    DERIV_MODES,
    RCConfig,
    learning_factor,
    period_samples,
    rc_sample,
    rc_update,
)
from microfab.control.rc_memory import RCMemory
from microfab.core.validate import check_int

__all__ = [
    "PluginRC",
    "RCConfig",
    "learning_factor",
    "period_samples",
    "rc_sample",
    "rc_update",
]


_HDR = 13  # header of PluginRC.params, see PluginRC
_MAX_ORDERS = 4  # position, velocity, acceleration, jerk


@functools.cache
def _rc_class(inner_kernel: Any) -> type[PluginRC]:
    """The `PluginRC` subclass whose kernel calls ``inner_kernel`` (one per inner kernel).

    The compiled loop takes one controller kernel; the inner one is bound into it as a
    constant, as `microfab.sim.kernels.compiled_loop` binds its kernels.
    """

    @njit(cache=True)
    def rc_step(
        p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
    ) -> None:
        n = int(p[0])
        na = int(p[1])
        n_win = int(p[9])
        pin = p[int(p[10]) :]
        xin = x[int(p[11]) :]
        pv = int(p[12])
        cnt = int(x[0])
        x[0] = cnt + 1.0
        active = n_win == 0
        start = 0
        for w in range(n_win):
            s = int(p[_HDR + w])
            if s <= cnt < int(p[_HDR + n_win + w]):
                active = True
                start = s
                break
        if not active:
            inner_kernel(pin, xin, ref, k, ym, u)
            return
        ph = (cnt - start) % n
        sz = n * na
        M = x[1 : 1 + sz]
        Ep = x[1 + sz : 1 + 2 * sz]
        Ec = x[1 + 2 * sz : 1 + 3 * sz]
        if cnt == start and p[6] == 0.0:  # a window starts: empty memory unless carried
            for i in range(3 * sz):
                x[1 + i] = 0.0
        rc_sample(M, Ep, ph, na, n, p[2], p[3], p[4], int(p[5]))
        for a in range(na):
            Ec[ph * na + a] = ref[k, 0, a] - ym[a]
        if ph == n - 1:
            for i in range(sz):
                Ep[i] = Ec[i]
        no = ref.shape[1]
        w0 = 1 + 3 * sz
        W = x[w0 : w0 + pv * no * na].reshape((pv, no, na))
        dt = p[8]
        for i in range(pv):
            j = ph + i
            while j >= n:  # the preview may exceed a (short) period
                j -= n
            jp = j + 1 if j + 1 < n else 0
            jm = j - 1 if j > 0 else n - 1
            for d in range(no):
                for a in range(na):
                    W[i, d, a] = ref[k + i, d, a]
            for a in range(na):
                W[i, 0, a] += M[j * na + a]
                if p[7] != 0.0:
                    cp, c0, cm = M[jp * na + a], M[j * na + a], M[jm * na + a]
                    if no > 1:
                        W[i, 1, a] += (cp - cm) / (2.0 * dt)
                    if no > 2:
                        W[i, 2, a] += (cp - 2.0 * c0 + cm) / (dt * dt)
        inner_kernel(pin, xin, W, 0, ym, u)

    return type(
        f"PluginRC[{getattr(inner_kernel, '__name__', 'kernel')}]",
        (PluginRC,),
        {"kernel_step": rc_step, "__module__": __name__},
    )


class PluginRC(CompiledController):
    """Plug-in repetitive controller around an inner compiled controller (module).

    Parameters
    ----------
    inner : CompiledController
        The feedback controller whose reference the RC corrects (measurement and
        reference axes alike, mm).
    config : RCConfig
        The RC settings.
    n_axes : int, optional
        Reference axes; default the inner controller's ``n_axes`` (or ``n_inputs``), else
        2 (x, y).

    Notes
    -----
    ``params = [N, n_axes, k_r, q, 1 - q, m, carry, derivative mode, dt, n_windows,
    inner params offset, inner state offset, preview, window starts, window ends, inner
    params]``. State: ``[samples since init, memory c (N, n_axes), previous period's error
    (N, n_axes), this period's error (N, n_axes), window scratch (preview, 4, n_axes),
    inner state]``, flat ``float64``. ``PluginRC(inner, config)`` returns an instance of
    a subclass made once per inner kernel class (`_rc_class`); it pickles as
    ``PluginRC(inner, config)``.
    """

    kernel_step: Any = None  # set on the subclass made for each inner kernel

    def __new__(
        cls, inner: CompiledController, config: RCConfig, n_axes: int | None = None
    ) -> PluginRC:
        """Instantiate the subclass made for ``type(inner).kernel_step``."""
        if cls is PluginRC:
            if not isinstance(inner, CompiledController):
                raise TypeError(
                    "PluginRC wraps a CompiledController (RBF, PID, LTIController); got "
                    f"{type(inner).__name__}"
                )
            cls = _rc_class(type(inner).kernel_step)
        return super().__new__(cls)

    def __init__(
        self, inner: CompiledController, config: RCConfig, n_axes: int | None = None
    ) -> None:
        if not isinstance(config, RCConfig):
            raise TypeError(f"config must be an RCConfig, got {type(config).__name__}")
        self.inner = inner
        self.config = config
        self.preview = int(inner.preview)
        self.n = config.period_samples
        if n_axes is None:  # the inner controller's, else the two axes (x, y) of seed 001
            n_axes = getattr(inner, "n_axes", None) or getattr(inner, "n_inputs", None) or 2
        self.n_axes = check_int("n_axes", n_axes, 1)
        inner_p = inner.packed_params()
        wins = config.windows or ()
        starts = [float(s) for s, _ in wins]
        ends = [float(s + k * self.n) for s, k in wins]
        ip = _HDR + 2 * len(wins)
        self._inner_offset = 1 + 3 * self.n * self.n_axes + self.preview * _MAX_ORDERS * self.n_axes
        q = config.q
        header = [
            self.n,
            self.n_axes,
            config.gain,
            q,
            1.0 - q,
            config.lead_samples,
            float(config.carry),
            float(DERIV_MODES.index(config.derivatives)),
            config.dt,
            len(wins),
            ip,
            self._inner_offset,
            self.preview,
        ]
        self.params = np.array([*header, *starts, *ends, *inner_p], dtype=np.float64)

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle as ``PluginRC(inner, config)`` (the subclass is made per process)."""
        return (PluginRC, (self.inner, self.config, self.n_axes))

    # ------------------------------------------------------------------ state machine
    def init(self) -> np.ndarray:
        """Empty memory, zero counter, the inner controller at rest."""
        inner0 = np.asarray(self.inner.init(), dtype=np.float64).ravel()
        return np.concatenate([np.zeros(self._inner_offset), inner0])

    def _window(self, cnt: int) -> tuple[bool, int]:
        wins = self.config.windows
        if wins is None:
            return True, 0
        for s, k in wins:
            if s <= cnt < s + k * self.n:
                return True, s
        return False, 0

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample (the kernel's arithmetic in Python); ``state`` is not modified."""
        new = np.array(state, dtype=np.float64, copy=True)
        n, na, cfg = self.n, self.n_axes, self.config
        ym = np.asarray(measurement, dtype=float)
        io = self._inner_offset
        cnt = int(new[0])
        new[0] = cnt + 1.0
        active, start = self._window(cnt)
        if not active:
            u, s_in = self.inner.step(new[io:], window, ym)
            new[io:] = s_in
            return np.asarray(u, dtype=float), new
        ph = (cnt - start) % n
        sz = n * na
        if cnt == start and not cfg.carry:
            new[1 : 1 + 3 * sz] = 0.0
        M = new[1 : 1 + sz]
        Ep = new[1 + sz : 1 + 2 * sz]
        Ec = new[1 + 2 * sz : 1 + 3 * sz]
        p = self.params
        rc_sample(M, Ep, ph, na, n, p[2], p[3], p[4], int(p[5]))
        Ec[ph * na : (ph + 1) * na] = window.position[0] - ym
        if ph == n - 1:
            Ep[:] = Ec
        Mm = M.reshape(n, na)
        rows = (ph + np.arange(window.preview)) % n
        pos = window.position + Mm[rows]
        vel, acc = window.velocity, window.acceleration
        if cfg.derivatives == "memory":
            cp, c0, cm = Mm[(rows + 1) % n], Mm[rows], Mm[(rows - 1) % n]
            if vel is not None:
                vel = vel + (cp - cm) / (2.0 * cfg.dt)
            if acc is not None:
                acc = acc + (cp - 2.0 * c0 + cm) / (cfg.dt * cfg.dt)
        win = ReferenceWindow(position=pos, velocity=vel, acceleration=acc, jerk=window.jerk)
        orders = [o for o in (pos, vel, acc, window.jerk) if o is not None]
        w0 = 1 + 3 * sz  # the kernel's scratch window, kept the same in both
        new[w0 : w0 + len(orders) * pos.size] = np.stack(orders, axis=1).ravel()
        u, s_in = self.inner.step(new[io:], win, ym)
        new[io:] = s_in
        return np.asarray(u, dtype=float), new

    def inner_state(self, state: np.ndarray) -> np.ndarray:
        """The inner controller's part of ``state`` (a view, no checks: for logging)."""
        return state[self._inner_offset :]

    # ------------------------------------------------------------------ persistence
    def memory_of(self, state: np.ndarray) -> RCMemory:
        """The saved form of a state (`RCMemory`), inner controller state included."""
        st = np.asarray(state, dtype=np.float64)
        sz = self.n * self.n_axes
        if st.ndim != 1 or st.size < self._inner_offset:
            raise ValueError(
                f"state must be flat with at least the RC's {self._inner_offset} values, "
                f"got shape {st.shape}"
            )
        return RCMemory(
            config=self.config,
            memory=st[1 : 1 + sz].reshape(self.n, self.n_axes).copy(),
            error=st[1 + sz : 1 + 2 * sz].reshape(self.n, self.n_axes).copy(),
            error_current=st[1 + 2 * sz : 1 + 3 * sz].reshape(self.n, self.n_axes).copy(),
            samples=int(st[0]),
            inner=st[self._inner_offset :].copy(),
        )

    def state_from(self, memory: RCMemory) -> np.ndarray:
        """The controller state of a saved `RCMemory` (checked against this RC).

        A memory without inner state (the file-based RC's, ``microfab rc step``, which
        cannot know the hardware's inner controller) starts the inner controller at rest.

        Raises
        ------
        ValueError
            When the memory was saved with another config, axis count or inner state size.
        """
        if memory.config != self.config:
            raise ValueError(
                "the saved RC state was made with another RC config "
                f"({memory.config}) than this run's ({self.config}): start a new state "
                "or use the saved settings"
            )
        if memory.memory.shape != (self.n, self.n_axes):
            raise ValueError(
                f"the saved RC memory is shaped {memory.memory.shape}, this RC needs "
                f"{(self.n, self.n_axes)}"
            )
        n_inner = self.inner.init().size
        if memory.inner.size not in (0, n_inner):
            raise ValueError(
                f"the saved inner controller state has {memory.inner.size} values, "
                f"{type(self.inner).__name__} needs {n_inner}: it was saved with another "
                "inner controller"
            )
        st = self.init()
        sz = self.n * self.n_axes
        st[0] = float(memory.samples)
        st[1 : 1 + sz] = memory.memory.ravel()
        st[1 + sz : 1 + 2 * sz] = memory.error.ravel()
        st[1 + 2 * sz : 1 + 3 * sz] = memory.error_current.ravel()
        if memory.inner.size:  # else the file-based RC's memory: the inner loop at rest
            st[self._inner_offset :] = memory.inner
        return st

    def save_state(self, state: np.ndarray, path: str | Path) -> Path:
        """Write ``state`` to ``path`` atomically (`RCMemory.save`)."""
        return self.memory_of(state).save(path)

    def load_state(self, path: str | Path) -> np.ndarray:
        """Read a state written by `save_state` (checked against this RC)."""
        return self.state_from(RCMemory.load(path))
