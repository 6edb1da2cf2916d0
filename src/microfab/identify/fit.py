"""Fit of a continuous transfer function to a measured FRF (seed 003 part 2 §1).

The seed fits ``1.242e11 / (s^3 + 9517 s^2 + 5.773e7 s + 1.272e11)`` to its chirp FRF with
"a 'non-linear least squares' system estimator" (Matlab). `fit_tf` does that for any
numbers of zeros and poles (``n_zeros <= n_poles``):

1. **Start: Sanathanan-Koerner (SK) iterations.** The relative error
   ``(N/D - H) / H`` is linear in the coefficients once multiplied by ``D``; iteration
   ``i`` solves the weighted linear least squares problem
   ``min sum_k |w_k (N(s_k) - H_k D(s_k)) / (H_k D_{i-1}(s_k))|^2`` (``D_0 = 1``, Levy's
   fit) until the coefficients stop changing. With ``sampling`` other than "none" the data
   is first advanced by half a sample, ``H exp(+j w T / 2)``, the hold's main effect.
   When the start has poles in the right half plane, a second start has them reflected
   into the left (numerator refitted).
2. **Non-linear least squares.** `scipy.optimize.least_squares` (Levenberg-Marquardt,
   from each start; the lower cost wins)
   minimises ``sum_k |w_k (H_model(f_k) - H_k) / H_k|^2`` over the numerator and monic
   denominator coefficients, with ``w_k`` the coherence ``gamma_k^2`` (1 where it is
   unknown): a relative error, so that every frequency of a Bode plot counts alike, and
   noisy bins count less. ``H_model`` is the candidate as the sampled data shows it
   (`microfab.identify.model.response_scaled`): its ZOH discretisation at ``dt``
   (``sampling="zoh"``, the default when ``dt`` is known), the continuous response with a
   half-sample delay (``"delay"``), or the plain continuous response (``"none"``).

Coefficients are handled in ``s' = s / w_s`` (``w_s`` the geometric mean of the SK
start's pole magnitudes), where they are of order one. When the best fit has a pole at
or right of the imaginary axis it is refused (`UnstableFitError`), not replaced by a
worse stable one.

**Why sampling matters (seed's own data rate).** A 100 kHz record of the seed's model is
its ZOH discretisation, which differs from ``G(j w)`` by up to 6 % in 10 Hz - 2 kHz (the
half-sample delay's phase, 3.6 deg at 2 kHz). A plain continuous fit absorbs that into the
coefficients and misses them by 3.5 - 6.3 % (issue 16 says 3 - 6 %); the half-sample delay
model by 0.03 %; the ZOH model recovers them to rounding (tests/identify/test_fit.py
measures all three).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize

from microfab.core.threads import single_threaded
from microfab.core.validate import check_int, check_positive
from microfab.identify.frf import FRF
from microfab.identify.model import Sampling, TFModel, check_sampling, response_scaled
from microfab.identify.plotting import bode_axes, draw_coherence, draw_response

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["FitResult", "UnstableFitError", "fit_tf"]

_SK_RTOL = 1e-12  # SK stops when no coefficient moves by more than this (relative)
_LSQ_TOL = 1e-14  # ftol, xtol, gtol of the non-linear least squares
_BIG = 1e6  # residual substituted for a candidate whose response is not finite


class UnstableFitError(ValueError):
    """The fitted model has a pole at or right of the imaginary axis.

    Attributes
    ----------
    poles : numpy.ndarray
        The fitted model's poles, rad/s.
    """

    def __init__(self, message: str, poles: np.ndarray) -> None:
        super().__init__(message)
        self.poles = poles


@dataclass(frozen=True, eq=False)
class FitResult:
    """A transfer function fitted to an FRF, with the data and how well it fits.

    Attributes
    ----------
    model : TFModel
        The fitted continuous model (coefficients, poles, gain, bandwidth).
    start : TFModel
        The Sanathanan-Koerner start the fit came from (as found, or with its unstable
        poles reflected).
    frf : FRF
        The data fitted (the band used).
    sampling : {"zoh", "delay", "none"}
        How the model was compared with the data.
    dt : float or None
        Sample time of that comparison, s.
    residual_rms : float
        RMS over the frequencies of the coherence-weighted relative complex error
        ``gamma^2 |H_model / H - 1|`` (what was minimised).
    max_relative_error : float
        Largest unweighted ``|H_model / H - 1|`` over the band.
    n_evaluations : int
        Model evaluations of the non-linear least squares (all starts).
    sk_iterations : int
        Sanathanan-Koerner iterations done.
    """

    model: TFModel
    start: TFModel
    frf: FRF
    sampling: Sampling
    dt: float | None
    residual_rms: float
    max_relative_error: float
    n_evaluations: int
    sk_iterations: int

    def fitted_response(self) -> np.ndarray:
        """The model's response at the data's frequencies as compared (``sampling``)."""
        return self.model.frequency_response(self.frf.freq_hz, sampling=self.sampling, dt=self.dt)

    def relative_error(self) -> np.ndarray:
        """``H_model / H - 1`` per frequency (complex), shape (n,)."""
        return self.fitted_response() / self.frf.response - 1.0

    def plot(self, *, title: str | None = None) -> Figure:
        """Bode plot of data and fit, and the coherence (seed 003 part 2 Fig. 4).

        Shows the data (dots), the model as compared with it (line) and, when that is a
        sampled form, the continuous model (dashed).

        Returns
        -------
        matplotlib.figure.Figure
            Magnitude, phase and coherence axes; an Agg canvas, no pyplot.
        """
        fig, axes = bode_axes(title)
        f = self.frf.freq_hz
        draw_response(axes, f, self.frf.response, label=f"measured ({self.frf.method})", style=".")
        draw_response(axes, f, self.fitted_response(), label=f"fit ({self.sampling})", style="-")
        if self.sampling != "none":
            draw_response(
                axes, f, self.model.frequency_response(f), label="fit, continuous", style="--"
            )
        draw_coherence(axes[2], self.frf)
        axes[0].legend(loc="best")
        return fig

    def to_dict(self) -> dict[str, Any]:
        """The model's dict (`TFModel.to_dict`) with a ``fit`` block; JSON-ready.

        `TFModel.from_dict` reads it back (the ``fit`` block is informational).
        """
        out = self.model.to_dict()
        out["fit"] = {
            "n_zeros": self.model.n_zeros,
            "n_poles": self.model.n_poles,
            "sampling": self.sampling,
            "dt_s": self.dt,
            "band_hz": [float(self.frf.freq_hz[0]), float(self.frf.freq_hz[-1])],
            "n_frequencies": int(self.frf.freq_hz.size),
            "frf_method": self.frf.method,
            "n_averages": self.frf.n_averages,
            "residual_rms": self.residual_rms,
            "max_relative_error": self.max_relative_error,
        }
        return out


def _sk(
    s: np.ndarray, h: np.ndarray, w: np.ndarray, n_zeros: int, n_poles: int, iterations: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """Sanathanan-Koerner iterations; ``b``, monic ``a`` (highest first), iterations done."""
    cols = [s**k for k in range(n_zeros + 1)] + [-h * s**k for k in range(n_poles)]
    m = np.column_stack(cols)
    rhs = h * s**n_poles
    base = w / np.abs(h)
    x_prev = np.full(n_zeros + 1 + n_poles, np.nan)
    d_prev = np.ones_like(s)
    done = 0
    while done < iterations:
        sc = base / np.abs(d_prev)
        ms, rs = m * sc[:, None], rhs * sc
        x = np.linalg.lstsq(
            np.vstack([ms.real, ms.imag]), np.concatenate([rs.real, rs.imag]), rcond=None
        )[0]
        done += 1
        d_prev = np.polyval(np.concatenate([[1.0], x[n_zeros + 1 :][::-1]]), s)
        if np.all(np.abs(x - x_prev) <= _SK_RTOL * np.abs(x)):
            break
        x_prev = x
    return x[: n_zeros + 1][::-1], np.concatenate([[1.0], x[n_zeros + 1 :][::-1]]), done


def _stable_start(
    s: np.ndarray, h: np.ndarray, w: np.ndarray, b: np.ndarray, a: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Reflect right-half-plane poles of ``a`` and refit the numerator (linear)."""
    p = np.roots(a)
    if np.all(p.real < 0):
        return b, a
    p = np.where(p.real >= 0, -np.abs(p.real) - 1e-6 * np.abs(p) + 1j * p.imag, p)
    a = np.real(np.poly(p))
    d = np.polyval(a, s)
    sc = w / np.abs(h)
    m = np.column_stack([s**k / d for k in range(b.size)]) * sc[:, None]
    rs = h * sc
    x = np.linalg.lstsq(np.vstack([m.real, m.imag]), np.concatenate([rs.real, rs.imag]))[0]
    return x[::-1], a


@single_threaded  # 4x4 matrix work: a BLAS thread team costs 100x (8 ms per expm)
def fit_tf(
    frf: FRF,
    *,
    n_poles: int = 3,
    n_zeros: int = 0,
    sampling: Sampling | None = None,
    dt: float | None = None,
    band_hz: tuple[float, float] | None = None,
    min_coherence: float = 0.8,
    sk_iterations: int = 50,
    max_evaluations: int | None = None,
) -> FitResult:
    """Fit ``G(s)`` with ``n_zeros`` zeros and ``n_poles`` poles to an FRF (module doc).

    Parameters
    ----------
    frf : FRF
        The data (`microfab.identify.frf.estimate_frf`, or `FRF.from_table`).
    n_poles : int
        Poles of the model (>= 1; the seed's model has 3).
    n_zeros : int
        Finite zeros (0 <= n_zeros <= n_poles; the seed's model has none).
    sampling : {"zoh", "delay", "none"}, optional
        How the candidate is compared with the data; default "zoh" when a sample time
        is known (``dt`` or ``frf.dt``), else "none".
    dt : float, optional
        Sample time of the data, s (default ``frf.dt``).
    band_hz : (float, float), optional
        Band to fit, Hz (default the whole FRF); checked by `FRF.band`.
    min_coherence : float
        Coherence the band must reach (default 0.8; 0 checks nothing).
    sk_iterations : int
        Most Sanathanan-Koerner iterations (>= 1).
    max_evaluations : int, optional
        Most model evaluations of the least squares (default 200 per coefficient).

    Returns
    -------
    FitResult
        The model, the SK start, the data, and the residuals.

    Raises
    ------
    ValueError
        Orders out of range, a sampling mode without ``dt``, a band above the Nyquist
        frequency of ``dt`` or outside the FRF's excitation, fewer data than coefficients,
        a zero response.
    LowCoherenceError
        The coherence falls below ``min_coherence`` over a range of the band (named).
    UnstableFitError
        The fitted model has a pole with a non-negative real part.
    """
    n_p = check_int("n_poles", n_poles, 1)
    n_z = check_int("n_zeros", n_zeros, 0)
    if n_z > n_p:
        raise ValueError(f"n_zeros must not exceed n_poles = {n_p} (a proper model), got {n_z}")
    n_iter = check_int("sk_iterations", sk_iterations, 1)
    dt = frf.dt if dt is None else check_positive("dt", dt, "s")
    mode: str = ("zoh" if dt is not None else "none") if sampling is None else sampling
    dt = check_sampling(mode, dt)
    if band_hz is not None:
        data = frf.band(*band_hz, min_coherence=min_coherence)
    else:
        data = frf
        if min_coherence > 0:
            data.check_coherence(min_coherence)
    f, h = data.freq_hz, data.response
    if dt is not None and f[-1] > 0.5 / dt:
        raise ValueError(
            f"the FRF reaches {f[-1]:g} Hz, above the Nyquist frequency {0.5 / dt:g} Hz of "
            f"dt = {dt:g} s: give a band below it"
        )
    n_coef = n_z + 1 + n_p
    if 2 * f.size < n_coef + 1:
        raise ValueError(
            f"the band holds {f.size} frequencies ({2 * f.size} real data), too few for "
            f"{n_coef} coefficients: widen the band or lower the orders"
        )
    zero = np.nonzero(np.abs(h) == 0)[0]
    if zero.size:
        raise ValueError(f"the response is zero at {f[zero[0]]:g} Hz: a relative fit cannot use it")
    coh = np.where(np.isnan(data.coherence), 1.0, data.coherence)

    # 1. SK start in s' = s / w1 (w1 the band's geometric centre)
    pos = f[f > 0]
    if pos.size == 0:
        raise ValueError("the FRF holds no positive frequency")
    w1 = 2 * math.pi * math.sqrt(pos[0] * pos[-1])
    s1 = 2j * math.pi * f / w1
    h_sk = h if mode == "none" else h * np.exp(1j * math.pi * f * dt)
    b, a, n_sk = _sk(s1, h_sk, coh, n_z, n_p, n_iter)
    starts = [TFModel.from_scaled(b, a, w1, unit=data.unit)]
    if not starts[0].is_stable:  # also try it with its unstable poles reflected
        starts.append(TFModel.from_scaled(*_stable_start(s1, h_sk, coh, b, a), w1, unit=data.unit))

    # 2. non-linear least squares in s' = s / ws (ws from the start's poles)
    ws = starts[0].scale_rad_s
    w = 2 * math.pi * f / ws
    period = None if dt is None else dt * ws
    weight = coh / np.abs(h)

    def residual(x: np.ndarray) -> np.ndarray:
        hm = response_scaled(x[: n_z + 1], np.concatenate([[1.0], x[n_z + 1 :]]), w, mode, period)
        e = weight * (hm - h)
        r = np.concatenate([e.real, e.imag])
        return np.nan_to_num(r, nan=_BIG, posinf=_BIG, neginf=-_BIG)

    runs = []
    for start in starts:
        b0, a0 = start.scaled(ws)
        if b0.size < n_z + 1:  # leading zero coefficients were dropped: keep the order
            b0 = np.concatenate([np.zeros(n_z + 1 - b0.size), b0])
        sol = scipy.optimize.least_squares(
            residual,
            np.concatenate([b0, a0[1:]]),
            method="lm",
            x_scale="jac",
            ftol=_LSQ_TOL,
            xtol=_LSQ_TOL,
            gtol=_LSQ_TOL,
            max_nfev=max_evaluations or 200 * n_coef,
        )
        x = sol.x
        model = TFModel.from_scaled(
            x[: n_z + 1], np.concatenate([[1.0], x[n_z + 1 :]]), ws, unit=data.unit
        )
        runs.append((float(sol.cost), model, start, int(sol.nfev)))
    cost, model, start, _ = min(runs, key=lambda r: r[0])
    if not model.is_stable:
        poles = model.poles
        bad = ", ".join(f"{p:.4g}" for p in poles[poles.real >= 0])
        stable = [r for r in runs if r[1].is_stable]
        alt = (
            f" (weighted residual rms {math.sqrt(2 * cost / f.size):.3g}; the best stable fit "
            f"found leaves {math.sqrt(2 * stable[0][0] / f.size):.3g})"
            if stable
            else ""
        )
        raise UnstableFitError(
            f"the fitted model is unstable: pole(s) {bad} rad/s have a non-negative real "
            f"part{alt}; the data may come from an unstable system or a closed loop, or "
            f"(n_zeros, n_poles) = ({n_z}, {n_p}) does not suit it: change the orders or the band",
            poles,
        )
    rel = model.frequency_response(f, sampling=mode, dt=dt) / h - 1.0
    return FitResult(
        model=model,
        start=start,
        frf=data,
        sampling=mode,  # type: ignore[arg-type]
        dt=dt,
        residual_rms=float(np.sqrt(np.mean(np.abs(coh * rel) ** 2))),
        max_relative_error=float(np.max(np.abs(rel))),
        n_evaluations=sum(r[3] for r in runs),
        sk_iterations=n_sk,
    )
