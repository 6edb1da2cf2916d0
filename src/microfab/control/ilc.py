"""Frequency-domain iterative learning control on the harmonics of a periodic task.

Implements seed 000 §3.2, eqs. (2)-(7): the input is updated harmonic by harmonic with the
inverse frequency response of the stabilised machine,

``U_{i+1}[n] = U_i[n] + rho * P^-1[n] * E_i[n]`` for ``n`` in the selected set ``S``,
``U_{i+1}[n] = 0`` otherwise, except the mean (``n = 0``), which keeps ``U_i[0]``,

with ``E_i = Y_d - Y_i``. Two sign typos of the seed are corrected here: with its eq. (3),
``E = Y - Y_d``, the ``+`` of eq. (2) would make ``E_{i+1} = (1 + rho) E_i`` and diverge,
whereas its convergence condition eq. (5), ``|1 - rho P P^-1| <= 1``, belongs to the update
written above; and the inverse DFT of eq. (6) must carry ``e^{+j 2 pi k n / N}``, not
``e^{-j...}``, which would time-reverse the input. The inverse model is taken from the first
trial by complex division (eq. 7), or from a given model.

Harmonic selection (the ``Q`` filter of the seed): harmonics ``0 <= n`` with
``n f_r <= cutoff_hz`` (seed §4: 8 kHz), of which are kept only those where

1. the first trial's input has content: ``|U_1[n]| > content_tol * max |U_1|`` (a square
   traced at constant speed has no even harmonics, whose inverse would be noise over
   noise), and
2. the first trial's output stands out of the noise: ``|Y_1[n]| > snr_min * noise``, where
   ``noise`` is the RMS magnitude of ``Y_1`` over the bins below Nyquist in which the input
   has no content; when fewer than 8 such bins exist (a path with content at every
   harmonic, such as a letter), it is estimated from the median magnitude of the top
   quarter of the output spectrum above the cutoff, where a closed loop passes little of
   its input (skipped when that leaves fewer than 8 bins).

With a given model only rule 1 applies.

Harmonic 0, the mean of the reference, is learned like any other harmonic (with the same
eq. 5 check): a path off the origin, such as a triangle whose y mean is -1/3 V, keeps its
offset. When the mean is not learned (no content, or buried in noise) it keeps the input
as applied, which stays the user's reference (``u_1 = y_d``), so an offset is never
dropped. Every other harmonic not learned is set to 0, as the seed's eq. (2) says (the
seed 000 tables are computed so; keeping the reference there instead changed them by up
to 4 % at 100 features/s).
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from microfab.control.ilc_spectra import _lag_s, _noise_from_top, _overflow_message
from microfab.control.ilc_state import checked_state
from microfab.control.ilc_types import _ARRAY_KEY as _ARRAY_KEY
from microfab.control.ilc_types import (
    ConvergenceError,
    FRFModel,
    ILCConfig,
    Trial,
    _arrays_in,
    _arrays_out,
    _State,
)
from microfab.control.ilc_types import Law as Law
from microfab.core.validate import check_positive
from microfab.io.checkpoint import StateFileError, read_state, save_state
from microfab.io.schema import SchemaError

__all__ = ["ConvergenceError", "FrequencyILC", "ILCConfig", "Trial"]

STATE_FILE = "ilc_state.npz"
#: Format of the saved state; `FrequencyILC.load` reads this one and the earlier ones.
#: Format 4: arrays in ``meta`` (the learning loop's signals) are archive members, not
#: JSON lists.
STATE_VERSION = 4
#: What `microfab.io.checkpoint` calls an ILC state file.
STATE_KIND = "ILC state"


class FrequencyILC:
    """Trial-to-trial learner of seed 000 eqs. (2)-(7).

    Parameters
    ----------
    reference : numpy.ndarray
        One period of the desired output, shape (N, n_axes).
    dt : float
        Sample time, s.
    axes : tuple of str
        Axis names.
    config : ILCConfig
        Cutoff, gain and harmonic-selection settings.
    model : callable, optional
        Model ``P(f)`` of the stabilised machine to invert instead of the first trial.
    true_frf : callable, optional
        The true ``P(f)`` when known (a digital twin): eq. (5) is then checked at every
        learned harmonic and a violating gain is refused with `ConvergenceError`.

    Examples
    --------
    >>> ilc = FrequencyILC(ref, dt=1e-6, axes=("x", "y"))       # doctest: +SKIP
    >>> u = ilc.initial_input()                                 # doctest: +SKIP
    >>> for _ in range(30):                                     # doctest: +SKIP
    ...     y = machine.run(u).output
    ...     u = ilc.update(Trial(dt=1e-6, reference=ref, input=u, output=y, axes=("x", "y")))

    References
    ----------
    Seed 000 §3.2, eqs. (2)-(7); §4 (8 kHz cutoff, rho = 0.4, u_1 = y_d).
    """

    def __init__(
        self,
        reference: np.ndarray,
        dt: float,
        axes: tuple[str, ...],
        config: ILCConfig | None = None,
        model: FRFModel | None = None,
        true_frf: FRFModel | None = None,
    ) -> None:
        ref = np.asarray(reference, dtype=float)
        if ref.ndim == 1:
            ref = ref[:, None]
        if ref.ndim != 2 or ref.shape[0] < 8:
            raise ValueError(f"reference must be (N >= 8, n_axes), got shape {ref.shape}")
        if not np.all(np.isfinite(ref)):
            raise ValueError("reference holds NaN or inf")
        if len(axes) != ref.shape[1]:
            raise ValueError(f"{ref.shape[1]} reference columns but {len(axes)} axis names")
        check_positive("dt", dt, "s")
        self.config = config or ILCConfig()
        unknown = sorted(set(self.config.axis_gains or {}) - set(axes))
        if unknown:
            raise ValueError(f"a gain is given for axis {unknown}, but the axes are {list(axes)}")
        self.model = model
        self.true_frf = true_frf
        self.state = _State(dt=float(dt), axes=tuple(axes), reference=ref.copy())
        self.state.inputs = [ref.copy()]  # seed 000 §4: u_1 = y_d
        if model is not None:  # tabulated at the harmonics once: saved with the state
            f = self.harmonic_freq_hz
            frf = np.asarray(model(f), dtype=complex).reshape(f.size, -1)
            if frf.shape[1] != len(axes):
                raise ValueError(f"model gives {frf.shape[1]} axes, expected {len(axes)}")
            self.state.model_frf = np.where(np.isfinite(frf), frf, 0.0)

    # ----------------------------------------------------------------- basics
    @property
    def reference(self) -> np.ndarray:
        """One period of the desired output ``y_d``, shape (N, n_axes) (a copy)."""
        return self.state.reference.copy()

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return self.state.dt

    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names."""
        return self.state.axes

    @property
    def meta(self) -> dict[str, object]:
        """Data saved with the state (the learning loop's record).

        JSON-ready values and NumPy arrays, in dicts and lists; the arrays are saved as
        members of the archive, bit for bit.
        """
        return self.state.meta

    @property
    def n_samples(self) -> int:
        """Samples per period ``N``."""
        return int(self.state.reference.shape[0])

    @property
    def period_s(self) -> float:
        """Period ``N dt`` in s."""
        return self.n_samples * self.state.dt

    @property
    def iteration(self) -> int:
        """Number of trials learned from so far."""
        return self.state.iteration

    @property
    def harmonic_freq_hz(self) -> np.ndarray:
        """Frequencies of the rfft bins, Hz, shape (N // 2 + 1,)."""
        return np.fft.rfftfreq(self.n_samples, self.state.dt)

    def initial_input(self) -> np.ndarray:
        """``u_1 = y_d`` (seed 000 §4)."""
        return self.state.inputs[0].copy()

    def current_input(self) -> np.ndarray:
        """The input to apply next, ``u_{i+1}``."""
        return self.state.inputs[-1].copy()

    @property
    def rms_history(self) -> np.ndarray:
        """RMS error per learned trial, shape (n_trials, n_axes)."""
        return np.array(self.state.rms).reshape(-1, len(self.state.axes))

    @property
    def events(self) -> list[str]:
        """What the divergence monitor did, one line per event (oldest first)."""
        return list(self.state.events)

    @property
    def harmonic_gains(self) -> np.ndarray:
        """Learning gain per rfft bin and axis, shape (N // 2 + 1, n_axes).

        0 where nothing is learned; empty before the first update.
        """
        return self.state.gain.copy()

    @property
    def pp_history(self) -> np.ndarray:
        """Peak-to-peak error per learned trial, shape (n_trials, n_axes)."""
        return np.array(self.state.pp).reshape(-1, len(self.state.axes))

    @property
    def harmonics(self) -> list[np.ndarray]:
        """Learned harmonic numbers per axis (empty before the first update)."""
        return [np.nonzero(self.state.mask[:, a])[0] for a in range(self.state.mask.shape[1])]

    # ------------------------------------------------------------- selection
    def _band(self) -> np.ndarray:
        f = self.harmonic_freq_hz
        band = f <= self.config.cutoff_hz  # harmonic 0 (the mean) included
        if self.n_samples % 2 == 0:
            band[-1] = False  # never learn the Nyquist bin
        return band

    def _select_and_invert(self, U1: np.ndarray, Y1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        band = self._band()
        n_bins, n_axes = U1.shape
        mask = np.zeros((n_bins, n_axes), bool)
        pinv = np.zeros((n_bins, n_axes), complex)
        model = self.state.model_frf
        if self.config.law == "p-type":
            tau = self.config.advance_s
            if tau is None:
                tau = _lag_s(self.state.inputs[0], Y1, self.state.dt)
            lead = np.exp(2j * np.pi * self.harmonic_freq_hz * tau)
        for a in range(n_axes):
            mag_u = np.abs(U1[:, a])
            content = mag_u > self.config.content_tol * mag_u.max()
            keep = band & content
            if model is None:
                empty = ~content
                empty[0] = False
                if self.n_samples % 2 == 0:
                    empty[-1] = False
                if empty.sum() >= 8:
                    noise = np.sqrt(np.mean(np.abs(Y1[empty, a]) ** 2))
                else:  # every bin has content (e.g. a letter): see _noise_from_top
                    noise = _noise_from_top(Y1[:, a], self._band())
                if noise is not None:
                    keep &= np.abs(Y1[:, a]) > self.config.snr_min * noise
                keep &= np.abs(Y1[:, a]) > 0
            else:
                keep &= np.abs(model[:, a]) > 0
            if self.config.law == "p-type":
                pinv[keep, a] = lead[keep]
            elif model is None:
                pinv[keep, a] = U1[keep, a] / Y1[keep, a]  # seed 000 eq. (7)
            else:
                pinv[keep, a] = 1.0 / model[keep, a]
            mask[:, a] = keep
        return pinv, mask

    def _eq5(self, P: np.ndarray, what: str, fix: str) -> None:
        """Refuse when ``|1 - rho P P^-1| > 1`` at a learned harmonic (seed 000 eq. 5)."""
        f = self.harmonic_freq_hz
        for a, name in enumerate(self.state.axes):
            m = self.state.mask[:, a] & np.isfinite(P[:, a])
            if not m.any():
                continue
            rho = self.state.gain[m, a]
            q = P[m, a] * self.state.pinv[m, a]
            val = np.abs(1 - rho * q)  # seed 000 eq. (5)
            if np.any(val > 1.0 + 1e-9):
                worst = int(np.argmax(val))
                n = int(np.nonzero(m)[0][worst])
                with np.errstate(divide="ignore", invalid="ignore"):
                    rho_max = np.where(q.real > 0, 2 * q.real / np.abs(q) ** 2, 0.0).min()
                hint = (
                    f"largest admissible gain {rho_max:.4g}"
                    if rho_max > 0
                    else f"no gain satisfies it there: set cutoff_hz below {f[n]:.6g} Hz"
                )
                raise ConvergenceError(
                    f"axis {name}: learning gain {rho[worst]:g} violates |1 - rho P P^-1| <= 1 "
                    f"(seed 000 eq. 5) with {what} at harmonic {n} ({f[n]:.6g} Hz): "
                    f"{val[worst]:.4f}; {hint}{fix}"
                )

    def _check_convergence(self, U1: np.ndarray, Y1: np.ndarray) -> None:
        """Eq. 5 against the true FRF (a twin), else against trial 1 for a model or P-type.

        With the first-trial inverse, ``P P^-1`` is 1 on trial 1 by construction; a given
        model or the P-type law can disagree with the machine, which trial 1 measures.
        """
        f = self.harmonic_freq_hz
        if self.true_frf is not None:
            # the true response is needed on the learned harmonics only
            rows = np.flatnonzero(self.state.mask.any(axis=1))
            P = np.full((f.size, len(self.state.axes)), np.nan, dtype=complex)
            if rows.size:
                P[rows] = np.asarray(self.true_frf(f[rows]), dtype=complex).reshape(rows.size, -1)
            self._eq5(P, "the true machine", "")
        elif self.state.model_frf is not None or self.config.law == "p-type":
            with np.errstate(divide="ignore", invalid="ignore"):
                P = np.where(np.abs(U1) > 0, Y1 / U1, np.nan)
            law = "the model" if self.config.law == "inverse" else "the P-type law"
            self._eq5(
                P,
                f"trial 1 (measured P = Y_1/U_1) and {law}",
                "; or learn from trial 1 alone (no FRF file, law 'inverse')",
            )

    def _monitor(self, E: np.ndarray) -> list[int]:
        """Axes whose error grew twice in a row: halve gains there, log, return them."""
        st, cfg = self.state, self.config
        mag = np.abs(E)
        st.recent_errors = [*st.recent_errors[-2:], mag]
        if not cfg.monitor or len(st.recent_errors) < 3:  # three trials since a fallback
            return []
        r = np.array(st.rms[-3:])
        grow = 1.0 + cfg.monitor_growth
        fallen: list[int] = []
        for a, name in enumerate(st.axes):
            if not (r[2, a] > grow * r[1, a] and r[1, a] > grow * r[0, a]):
                continue
            f = self.harmonic_freq_hz
            m = st.mask[:, a]
            e0, e1, e2 = (x[:, a] for x in st.recent_errors)
            worse = m & (e2 > e1) & (e1 > e0)
            if not worse.any():
                worse = m
            st.gain[worse, a] *= 0.5
            harm = np.nonzero(worse)[0]
            shown = ", ".join(f"{int(n)} ({f[n]:.4g} Hz)" for n in harm[:6])
            more = f" and {harm.size - 6} more" if harm.size > 6 else ""
            best = int(np.argmin(np.array(st.rms)[:, a])) + 1
            st.events.append(
                f"trial {len(st.rms)}: axis {name}: RMS error grew twice in a row "
                f"({r[0, a]:.4g} -> {r[1, a]:.4g} -> {r[2, a]:.4g}); next input is the best "
                f"seen (trial {best}, RMS {st.best_rms[a]:.4g}); gain halved at harmonic(s) "
                f"{shown}{more}"
            )
            fallen.append(a)
        if fallen:
            st.recent_errors = []  # start counting again from the fallback
        return fallen

    # ---------------------------------------------------------------- update
    def update(self, trial: Trial) -> np.ndarray:
        """Learn from one trial and return the next input ``u_{i+1}``.

        Parameters
        ----------
        trial : Trial
            The measured period; its ``input`` is the input actually applied.

        Returns
        -------
        numpy.ndarray
            Next input, shape (N, n_axes).

        Raises
        ------
        ValueError
            Signals of the wrong shape, NaN or inf, or so large that the update overflows.
        ConvergenceError
            On the first trial, with ``true_frf``, a gain that violates eq. (5).
        """
        st = self.state
        u = np.asarray(trial.input, dtype=float)
        y = np.asarray(trial.output, dtype=float)
        if u.shape != st.reference.shape or y.shape != st.reference.shape:
            raise ValueError(
                f"trial signals must be shaped {st.reference.shape}, "
                f"got input {u.shape} and output {y.shape}"
            )
        if not (np.isfinite(u).all() and np.isfinite(y).all()):
            raise ValueError("trial holds NaN or inf")
        first = st.iteration == 0
        # signals of absurd magnitude overflow below: refused, as not finite, before the
        # state changes. The output's own spectrum is needed on the first trial only (to
        # choose and invert the harmonics); later trials need E and U alone.
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            U = np.fft.rfft(u, axis=0)
            Y = np.fft.rfft(y, axis=0) if first else None
            E = np.fft.rfft(st.reference - y, axis=0)  # E_i = Y_d - Y_i (see module doc)
            err = np.ascontiguousarray((y - st.reference).T)  # one row per axis: fast
            rms = np.sqrt(np.mean(err**2, axis=1))
            pp = err.max(axis=1) - err.min(axis=1)
            spectra = (U, E, rms, pp) if Y is None else (U, Y, E, rms, pp)
            finite = all(np.isfinite(a).all() for a in spectra)
        if not finite:
            raise ValueError(_overflow_message(u, y))
        if Y is not None:
            pinv, mask = self._select_and_invert(U, Y)
            gain = np.array([self.config.gain_of(a) for a in st.axes])
            st.pinv, st.mask = pinv, mask
            st.gain = np.where(mask, gain[None, :], 0.0)
            self._check_convergence(U, Y)
            st.best_input = u.copy()
            st.best_rms = np.full(len(st.axes), np.inf)
        # eq. (2) on the learned harmonics, 0 on the others (the seed's Q filter), except
        # the mean: when not learned it keeps the input as applied (u_1 = y_d, the user's).
        # Worked out up to the highest learned bin only (below the cutoff): above it
        # every bin is 0.
        learned = np.flatnonzero(st.mask)  # flat C-order indices: bin * n_axes + axis
        hi = int(learned[-1]) // st.mask.shape[1] + 1 if learned.size else 1
        with np.errstate(over="ignore", invalid="ignore"):
            U_next = np.zeros_like(U)
            U_next[0] = U[0]
            step = U[:hi] + st.gain[:hi] * st.pinv[:hi] * E[:hi]
            U_next[:hi] = np.where(st.mask[:hi], step, U_next[:hi])
            u_next = np.fft.irfft(U_next, n=self.n_samples, axis=0)  # eq. (6), +j sign
        if not np.isfinite(u_next).all():
            raise ValueError(_overflow_message(u, y))
        st.rms.append([float(v) for v in rms])
        st.pp.append([float(v) for v in pp])
        better = rms < st.best_rms
        st.best_rms = np.where(better, rms, st.best_rms)
        st.best_input[:, better] = u[:, better]
        for a in self._monitor(E):
            u_next[:, a] = st.best_input[:, a]
        st.iteration += 1
        st.inputs.append(u_next)
        return u_next.copy()

    # ----------------------------------------------------------- persistence
    def save(self, directory: str | Path, extra: dict[str, object] | None = None) -> Path:
        """Write the whole learning state to ``directory/ilc_state.npz`` atomically.

        Parameters
        ----------
        directory : str or Path
            State directory (created if missing).
        extra : dict, optional
            Metadata kept with the state (e.g. machine limits), merged into `meta`:
            JSON-serialisable values and NumPy arrays (saved as archive members, so a
            signal costs its bytes rather than a JSON list of floats).
        """
        st = self.state
        if extra is not None:
            st.meta.update(extra)
        meta_arrays: dict[str, np.ndarray] = {}
        meta = {
            "iteration": st.iteration,
            "dt": st.dt,
            "axes": list(st.axes),
            "config": asdict(self.config),
            "model": st.model_frf is not None,
            "events": st.events,
            "meta": _arrays_out(st.meta, meta_arrays),
        }
        arrays: dict[str, np.ndarray] = {
            "reference": st.reference,
            "inputs": np.stack(st.inputs),
            "pinv": st.pinv,
            "mask": st.mask,
            "rms": np.array(st.rms, dtype=float).reshape(-1, len(st.axes)),
            "pp": np.array(st.pp, dtype=float).reshape(-1, len(st.axes)),
            "gain": st.gain,
            "best_input": st.best_input,
            "best_rms": st.best_rms,
            "recent_errors": (
                np.stack(st.recent_errors) if st.recent_errors else np.zeros((0, *st.pinv.shape))
            ),
        }
        if st.model_frf is not None:
            arrays["model_frf"] = st.model_frf
        arrays.update(meta_arrays)
        return save_state(
            Path(directory) / STATE_FILE,
            kind=STATE_KIND,
            version=STATE_VERSION,
            arrays=arrays,
            meta=meta,
        )

    @classmethod
    def exists(cls, directory: str | Path) -> bool:
        """True when ``directory`` holds a saved learning state.

        Raises
        ------
        microfab.io.checkpoint.StateFileError
            When something that is not a file stands where the state goes.
        """
        path = Path(directory) / STATE_FILE
        if path.exists() and not path.is_file():
            raise StateFileError(
                f"{path}: expected an ILC state file, found a folder; remove it, or give a "
                "new state folder, to start learning again"
            )
        return path.is_file()

    @classmethod
    def load(cls, directory: str | Path, true_frf: FRFModel | None = None) -> FrequencyILC:
        """Resume a learner saved with `save`.

        Raises
        ------
        FileNotFoundError
            No state in ``directory``.
        ValueError
            The state file is unreadable.
        """
        path = Path(directory) / STATE_FILE
        saved = read_state(
            path,
            kind=STATE_KIND,
            versions=(1, 2, 3, STATE_VERSION),
            fix="remove it, or give a new state folder, to start learning again (a job: "
            "microfab run --fresh)",
        )
        if saved is None:
            raise FileNotFoundError(f"no ILC state in {directory} (expected {STATE_FILE})")
        try:
            meta, data = checked_state(path, saved.meta, saved.arrays)
        except SchemaError as exc:
            raise StateFileError(
                f"{exc}; remove it, or give a new state folder, to start learning again"
            ) from None
        try:
            user_meta = _arrays_in(meta.get("meta", {}), data)
        except KeyError as exc:
            raise StateFileError(f"{path}: an ILC state without member {exc}; remove it") from None
        try:
            config = ILCConfig(**meta["config"])
        except (TypeError, ValueError) as exc:
            raise StateFileError(f"{path}: the saved ILC settings are not valid: {exc}") from None
        obj = cls(data["reference"], meta["dt"], tuple(meta["axes"]), config, true_frf=true_frf)
        st = obj.state
        st.iteration = int(meta["iteration"])
        st.inputs = list(data["inputs"])
        st.pinv = data["pinv"]
        st.mask = data["mask"]
        st.rms = data["rms"].tolist()
        st.pp = data["pp"].tolist()
        st.meta = dict(user_meta)
        st.events = list(meta.get("events", []))
        st.model_frf = data.get("model_frf")
        if "gain" in data:  # format 3
            st.gain = data["gain"]
            st.best_input = data["best_input"]
            st.best_rms = data["best_rms"]
            st.recent_errors = list(data["recent_errors"])
        elif st.iteration > 0:  # formats 1-2: the config gain, no monitor memory yet
            gains = np.array([obj.config.gain_of(a) for a in st.axes])
            st.gain = np.where(st.mask, gains[None, :], 0.0)
            rms = np.array(st.rms).reshape(-1, len(st.axes))
            st.best_rms = rms.min(axis=0)
            best = rms.argmin(axis=0)
            st.best_input = np.column_stack([st.inputs[b][:, a] for a, b in enumerate(best)])
        return obj
