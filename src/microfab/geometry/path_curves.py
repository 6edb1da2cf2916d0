"""Segment-level helpers of `microfab.geometry.path.Path`: packed curves, shifted segments.

`_CurveGroup` packs the polynomial curve segments of one degree so that `Path` evaluates
any number of them at once (Clenshaw's recurrence, `_clenshaw`, on the stacked Chebyshev
coefficients; arc length inverted by Newton's method; the chain rule to arc-length
derivatives); `_shifted_segment` moves one segment by a vector, keeping the tables a
translation leaves unchanged. They work on single segments or groups of them, not on a
path, and are kept apart from the contour class that uses them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from microfab.geometry.segments import (
    GL_W,
    GL_X,
    N_PANELS,
    ArcSegment,
    CurveSegment,
    LineSegment,
    Segment,
)

__all__: list[str] = []


def _clenshaw(coef: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Evaluate rows of Chebyshev series: coef (n, d + 1, 2), x (n, m) -> (n, m, 2)."""
    b1 = np.zeros((*x.shape, 2))
    b2 = np.zeros_like(b1)
    x2 = 2.0 * x[..., None]
    for k in range(coef.shape[1] - 1, 0, -1):
        b1, b2 = coef[:, None, k, :] + x2 * b1 - b2, b1
    return coef[:, None, 0, :] + x[..., None] * b1 - b2


class _CurveGroup:
    """Curve segments of one degree, packed for vectorised evaluation."""

    def __init__(self, curves: Sequence[CurveSegment]) -> None:
        self.coef = np.stack([c.coef for c in curves])
        d1, d2, d3 = zip(*(c.derivative_coefs for c in curves), strict=True)
        self.d = [self.coef, np.stack(d1), np.stack(d2), np.stack(d3)]
        self.table = np.stack([c.length_table for c in curves])

    def u_of_sigma(self, rows: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Invert the arc length by Newton's method, per query (rows index the group)."""
        tab = self.table[rows]
        j = np.clip((tab <= sigma[:, None]).sum(axis=1) - 1, 0, N_PANELS - 1)
        s_lo = tab[np.arange(rows.size), j]
        s_hi = tab[np.arange(rows.size), j + 1]
        span = np.where(s_hi > s_lo, s_hi - s_lo, 1.0)
        u_lo = j / N_PANELS
        u = u_lo + np.clip((sigma - s_lo) / span, 0.0, 1.0) / N_PANELS
        d1 = self.d[1][rows]
        for _ in range(6):
            h = u - u_lo
            nodes = u_lo[:, None] + h[:, None] * (GL_X[None, :] + 1.0) / 2.0
            sp = np.linalg.norm(_clenshaw(d1, 2.0 * nodes - 1.0), axis=2)
            f = s_lo + (sp * GL_W).sum(axis=1) * h / 2.0 - sigma
            g = np.linalg.norm(_clenshaw(d1, (2.0 * u - 1.0)[:, None])[:, 0, :], axis=1)
            step = f / np.maximum(g, 1e-300)
            u = np.clip(u - step, u_lo, u_lo + 1.0 / N_PANELS)
            if np.all(np.abs(f) <= 1e-15 * np.maximum(tab[:, -1], 1e-300)):
                break
        return u

    def derivs(self, rows: np.ndarray, sigma: np.ndarray, order: int) -> list[np.ndarray]:
        """Arc-length derivatives q, q_s, q_ss, q_sss at local arc length sigma.

        At a cusp (the curve stops, ``|dq/du| = 0``) the second and third derivatives
        are unbounded: they come out inf or NaN there, without a warning, for the caller
        to refuse or to bound.
        """
        u = self.u_of_sigma(rows, sigma)
        x = (2.0 * u - 1.0)[:, None]
        f = [_clenshaw(self.d[k][rows], x)[:, 0, :] for k in range(order + 1)]
        if order == 0:
            return [f[0]]
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            return self._chain(f, order)

    @staticmethod
    def _chain(f: list[np.ndarray], order: int) -> list[np.ndarray]:
        """Arc-length derivatives from the parameter derivatives ``f`` (chain rule)."""
        out = [f[0]]
        g = np.maximum(np.linalg.norm(f[1], axis=1), 1e-300)[:, None]
        out.append(f[1] / g)
        if order == 1:
            return out
        gp = (f[1] * f[2]).sum(axis=1, keepdims=True) / g
        out.append(f[2] / g**2 - f[1] * gp / g**3)
        if order == 2:
            return out
        f22 = (f[2] ** 2).sum(axis=1, keepdims=True)
        f13 = (f[1] * f[3]).sum(axis=1, keepdims=True)
        gpp = (f22 + f13 - gp**2) / g
        q3u = f[3] / g**2 - 3 * f[2] * gp / g**3 - f[1] * gpp / g**3 + 3 * f[1] * gp**2 / g**4
        out.append(q3u / g)
        return out


def _shifted_segment(seg: Segment, d: np.ndarray) -> Segment:
    """A segment moved by ``d`` (m, finite, shape (2,)), keeping what a shift leaves alone."""
    if isinstance(seg, LineSegment):
        p0, p1 = seg.p0 + d, seg.p1 + d
        p0.setflags(write=False)
        p1.setflags(write=False)
        return LineSegment._unchecked(p0, p1)
    if isinstance(seg, ArcSegment):
        c = seg.center + d
        return ArcSegment.from_numbers(c[0], c[1], seg.radius, seg.theta0, seg.sweep)
    coef = seg.coef.copy()
    coef[0] += d
    coef.setflags(write=False)
    out = object.__new__(CurveSegment)
    attrs, have = out.__dict__, seg.__dict__  # frozen: set the field as __init__ would
    attrs["coef"] = coef
    # the constant coefficient is not in the derivatives, so neither in the lengths
    for name in ("derivative_coefs", "length_table", "length"):
        if name in have:
            attrs[name] = have[name]
    return out
