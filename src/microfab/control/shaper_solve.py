"""Numerical EI-family shapers: the constraints solved where the closed forms miss.

Klipper's closed forms of EI, 2-hump and 3-hump EI hold for small damping; near the seed
003 galvo's ζ 0.5 they miss their 5 % constraint (`microfab.control.shapers`). Here the
constraints of each family (`ShaperForm`: impulses, zeros, side humps) are solved by
`scipy.optimize.least_squares`, by continuation from the undamped 5 % shaper to the asked
``v_tol`` and damping; a family that ends before the damping asked is reported so.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
import scipy.optimize

from microfab.control.shaper_forms import (
    DEFAULT_V_TOL,
    SHAPERS,
    ShaperForm,
    ShaperName,
    _df,
    residual_vibration,
)

__all__ = ["numeric_unit"]

_CONTINUATION_STEP = 0.05  # largest damping step of the numerical continuation
_SOLVE_TOL = 1e-10  # largest constraint residual accepted from the numerical solve


def _structure_residual(
    form: ShaperForm, damping: float, v_tol: float
) -> Callable[[np.ndarray], np.ndarray]:
    """Residuals of the EI-family constraints, unknowns in time units of ``1/f``.

    Unknowns ``x``: amplitudes (n), times T_1..T_{n-1}, zero frequencies, side-hump
    frequencies (rad per time unit; ``f`` itself is ``2 pi``).
    """
    n, nz, nh = form.n_impulses, form.n_zeros, form.n_side_humps
    s = _df(damping)

    def res(x: np.ndarray) -> np.ndarray:
        A = x[:n]
        T = np.concatenate([[0.0], x[n : 2 * n - 1]])
        w = np.concatenate([x[2 * n - 1 : 2 * n - 1 + nz], [2.0 * np.pi], x[2 * n - 1 + nz :]])
        g = damping * (T - T[-1]) + 1j * s * T  # d(exponent)/dw per impulse
        E = A[None, :] * np.exp(np.outer(w, g))
        W = E.sum(axis=1)
        dW = (E * g).sum(axis=1)
        out = [A.sum() - 1.0]
        for k in range(nz):
            out += [W[k].real, W[k].imag]
        if form.centre == "hump":
            out += [abs(W[nz]) ** 2 - v_tol**2, (np.conj(W[nz]) * dW[nz]).real]
        else:
            out += [W[nz].real, W[nz].imag]
        for k in range(nz + 1, nz + 1 + nh):
            out += [abs(W[k]) ** 2 - v_tol**2, (np.conj(W[k]) * dW[k]).real]
        return np.array(out)

    return res


def _structure_ok(form: ShaperForm, x: np.ndarray) -> bool:
    """Positive amplitudes, increasing times, zeros and humps alternating around ``f``."""
    n, nz = form.n_impulses, form.n_zeros
    A, T = x[:n], x[n : 2 * n - 1]
    zeros, humps = x[2 * n - 1 : 2 * n - 1 + nz], x[2 * n - 1 + nz :]
    if np.any(A <= 0.0) or np.any(np.diff(np.concatenate([[0.0], T])) <= 0.0):
        return False
    w_n = 2.0 * np.pi
    lo = np.sort(np.concatenate([zeros[zeros < w_n], humps[humps < w_n]]))
    hi = np.sort(np.concatenate([zeros[zeros > w_n], humps[humps > w_n]]))
    marks = np.concatenate([lo, [w_n], hi])
    return bool(lo.size == hi.size and np.all(np.diff(marks) > 1e-6) and lo.size and lo[0] > 0)


def _undamped_start(form: ShaperForm) -> np.ndarray:
    """Unknowns of the undamped 5 % closed form, zeros and side humps read off its ``V``."""
    A, T = form.closed_form(1.0, 0.0, DEFAULT_V_TOL)
    f = np.linspace(0.3, 1.9, 16001)
    v = residual_vibration(A, T, f, 0.0)
    inner = slice(1, -1)
    is_min = (v[inner] < v[:-2]) & (v[inner] < v[2:])
    is_max = (v[inner] > v[:-2]) & (v[inner] > v[2:])
    fz = f[1:-1][is_min]
    fh = f[1:-1][is_max]
    fz = fz[np.abs(fz - 1.0) > 0.02]
    fh = fh[np.abs(fh - 1.0) > 0.02]
    if fz.size != form.n_zeros or fh.size != form.n_side_humps:  # pragma: no cover
        raise RuntimeError(f"{form.name}: unexpected undamped structure {fz}, {fh}")
    return np.concatenate([A, T[1:], 2.0 * np.pi * fz, 2.0 * np.pi * fh])


def _solve(form: ShaperForm, x0: np.ndarray, damping: float, v_tol: float) -> np.ndarray | None:
    res = _structure_residual(form, damping, v_tol)
    sol = scipy.optimize.root(res, x0, method="hybr", options={"xtol": 1e-13})
    ok = np.all(np.isfinite(sol.fun)) and np.max(np.abs(sol.fun)) < _SOLVE_TOL
    return sol.x if ok and _structure_ok(form, sol.x) else None


@functools.lru_cache(maxsize=512)
def numeric_unit(name: ShaperName, damping: float, v_tol: float) -> tuple[tuple, tuple, float]:
    """Normalised (``f = 1``) numerical shaper: ``(A, T, reached_damping)``.

    Continuation: the undamped 5 % shaper, then ``v_tol``, then ``damping``, in steps of
    at most `_CONTINUATION_STEP` (halved on failure). If the family ends first, ``A`` and
    ``T`` are empty and ``reached_damping`` is the largest damping solved.
    """
    form = SHAPERS[name]
    x = _solve(form, _undamped_start(form), 0.0, DEFAULT_V_TOL)
    assert x is not None  # the undamped 5 % structure always solves
    for param, goal in (("v_tol", v_tol), ("damping", damping)):
        cur = DEFAULT_V_TOL if param == "v_tol" else 0.0
        step = _CONTINUATION_STEP if param == "damping" else abs(goal - cur) / 4 or 1.0
        while cur != goal:
            nxt = goal if abs(goal - cur) <= step else cur + math.copysign(step, goal - cur)
            args = (nxt, v_tol) if param == "damping" else (0.0, nxt)
            trial = _solve(form, x, *args)
            if trial is None:
                step /= 2.0
                if step < 1e-4:
                    reached = cur if param == "damping" else 0.0
                    return (), (), reached
                continue
            x, cur = trial, nxt
            step = min(step * 1.5, _CONTINUATION_STEP) if param == "damping" else step
    n = form.n_impulses
    return tuple(x[:n]), (0.0, *x[n : 2 * n - 1]), damping
