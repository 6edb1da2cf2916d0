"""Auto-fit of a classic impulse shaper to a measured FRF or PSD (as Klipper's calibrate_shaper).

For each shaper type the design frequency (and, if several are given, the design
damping) is scanned; at each candidate the **remaining vibration** is computed the way
Klipper's ``_estimate_remaining_vibrations`` does:

* weights ``w(f)``: the PSD as given, or ``|H(f)|^2`` of an FRF, or ``|H(f) / H0(f)|^2``
  with a ``baseline`` magnitude ``|H0|`` (a servo axis's FRF is flat in its passband; the
  baseline -- e.g. the model the inverse shaper already cancels -- leaves the unmodelled
  resonances, which are what an impulse shaper is for);
* ``thr = max(w) / vibration_reduction`` (20: a shaper cannot reduce vibration more than
  that, so what lies below is ignored);
* ``V_max(f)``: the shaper's residual vibration maximised over the test dampings (the
  true damping is unknown);
* remaining = ``sum max(V_max w - thr, 0) / sum max(w - thr, 0)`` over the bins.

**Trade-off.** Klipper scores a candidate by its *smoothing* (a printer's corner offset at a
given acceleration); a galvo's jump pays for the shaper's **added delay** instead (its
centroid, `ImpulseShaper.delay`), so the score here is ``delay (v^1.5 + 0.2 v + 0.01)``
with Klipper's weights of the remaining vibration ``v``. Per type: the candidate with
the least remaining vibration, replaced by any with a lower score whose vibration is
within ``1.1 best + 0.0005`` (Klipper's rule). Across types: a type replaces the current
choice if its score is 20 % lower, or 5 % lower with 10 % less delay; a chosen ZV yields
to the first other type with 10 % less vibration (Klipper's rules, with delay for
smoothing).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from microfab.control.shapers import (
    DEFAULT_V_TOL,
    SHAPER_NAMES,
    ImpulseShaper,
    ShaperName,
    design_shaper,
)
from microfab.core.threads import one_blas_thread
from microfab.core.validate import check_in_range, check_int, check_positive

__all__ = ["ShaperCandidate", "ShaperFit", "ShaperFitConfig", "fit_shaper"]

#: Klipper's AUTOTUNE_SHAPERS (ZVD is in the registry but not auto-tuned there either).
_AUTOTUNE: tuple[ShaperName, ...] = ("zv", "mzv", "ei", "2hump_ei", "3hump_ei")


@dataclass(frozen=True, kw_only=True)
class ShaperFitConfig:
    """Settings of `fit_shaper`.

    Parameters
    ----------
    names : tuple of ShaperName
        Shaper types to fit (default Klipper's auto-tuned ones: zv, mzv, ei, 2hump_ei,
        3hump_ei).
    freq_range_hz : (float, float), optional
        Scanned design frequencies, Hz (default the data's positive range).
    n_freqs : int
        Number of evenly spaced design frequencies scanned (default 200).
    design_dampings : tuple of float
        Design damping ratios scanned (default ``(0.1,)``, Klipper's DEFAULT_DAMPING_RATIO;
        for a mirror mode of ``zeta`` ~ 0.02 give it).
    test_dampings : tuple of float
        Dampings the remaining vibration is maximised over (default Klipper's
        ``(0.075, 0.1, 0.15)``, for printers; give the range expected of the mode).
    vibration_reduction : float
        ``max(w) / thr`` (default 20, Klipper's SHAPER_VIBRATION_REDUCTION).
    v_tol : float
        Tolerance of the EI family (default 5 %).
    """

    names: tuple[ShaperName, ...] = _AUTOTUNE
    freq_range_hz: tuple[float, float] | None = None
    n_freqs: int = 200
    design_dampings: tuple[float, ...] = (0.1,)  # Klipper DEFAULT_DAMPING_RATIO
    test_dampings: tuple[float, ...] = (0.075, 0.1, 0.15)  # Klipper TEST_DAMPING_RATIOS
    vibration_reduction: float = 20.0  # Klipper SHAPER_VIBRATION_REDUCTION
    v_tol: float = DEFAULT_V_TOL

    def __post_init__(self) -> None:
        if not self.names:
            raise ValueError("names must list at least one shaper type")
        for n in self.names:
            if n not in SHAPER_NAMES:
                raise ValueError(f"unknown shaper {n!r}; known: {', '.join(SHAPER_NAMES)}")
        if self.freq_range_hz is not None:
            lo, hi = self.freq_range_hz
            check_positive("freq_range_hz low", lo, "Hz")
            check_positive("freq_range_hz high", hi, "Hz")
            if not hi > lo:
                raise ValueError(f"freq_range_hz must be (low, high) with high > low, got {lo, hi}")
        check_int("n_freqs", self.n_freqs, 2)
        dampings = (
            ("design_dampings", self.design_dampings),
            ("test_dampings", self.test_dampings),
        )
        for label, zs in dampings:
            if not zs:
                raise ValueError(f"{label} must hold at least one damping ratio")
            for z in zs:
                check_in_range(label, z, 0.0, 1.0, high_closed=False)
        check_positive("vibration_reduction", self.vibration_reduction)
        if self.vibration_reduction <= 1.0:
            raise ValueError(f"vibration_reduction must exceed 1, got {self.vibration_reduction}")
        check_in_range("v_tol", self.v_tol, 0.0, 0.25, "(fraction)", low_closed=False)


@dataclass(frozen=True, kw_only=True, eq=False)
class ShaperCandidate:
    """One scanned shaper and its figures.

    Attributes
    ----------
    shaper : ImpulseShaper
        The designed shaper.
    vibrations : float
        Remaining fraction of the weighted vibration (see the module), 0-1.
    delay : float
        Added delay, s (`ImpulseShaper.delay`).
    score : float
        ``delay (v^1.5 + 0.2 v + 0.01)``, s (lower is better).
    """

    shaper: ImpulseShaper
    vibrations: float
    delay: float
    score: float


@dataclass(frozen=True, kw_only=True, eq=False)
class ShaperFit:
    """Result of `fit_shaper`.

    Attributes
    ----------
    best : ShaperCandidate
        The chosen shaper over all types.
    per_type : dict of str to ShaperCandidate
        The chosen candidate of each type.
    scans : dict of str to tuple of ShaperCandidate
        Every candidate scanned, per type (design frequency, then damping).
    freq_hz, weights : numpy.ndarray
        The bins and vibration weights used, shape (n,).
    """

    best: ShaperCandidate
    per_type: dict[str, ShaperCandidate]
    scans: dict[str, tuple[ShaperCandidate, ...]]
    freq_hz: np.ndarray
    weights: np.ndarray

    def rows(self) -> list[tuple[str, float, float, float, float]]:
        """``(name, freq_hz, vibrations, delay_s, score)`` per type, for a table."""
        return [
            (n, c.shaper.freq_hz, c.vibrations, c.delay, c.score) for n, c in self.per_type.items()
        ]


def _weights(
    freq_hz: np.ndarray,
    response: np.ndarray,
    kind: Literal["psd", "frf"],
    baseline: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    f = np.asarray(freq_hz, dtype=float)
    r = np.asarray(response)
    if f.ndim != 1 or f.size < 3 or r.shape != f.shape:
        raise ValueError(
            f"freq_hz and response must be 1-D of one length >= 3, got {f.shape}, {r.shape}"
        )
    if not np.all(np.isfinite(f)) or np.any(np.diff(f) <= 0.0):
        raise ValueError("freq_hz must be finite and strictly increasing")
    if not np.all(np.isfinite(r)):
        raise ValueError("response holds NaN or inf")
    if kind == "psd":
        if np.iscomplexobj(r) or np.any(r < 0.0):
            raise ValueError("a PSD must be real and >= 0")
        w = r.astype(float)
    elif kind == "frf":
        a = np.abs(r).astype(float)
        if a.max(initial=0.0) > 1e150:  # its square overflows float64 (1.8e308)
            raise ValueError(
                f"|response| reaches {a.max():.3g}: its square overflows; give the FRF in a "
                "unit that keeps it below 1e150"
            )
        w = a**2
    else:
        raise ValueError(f"kind must be 'psd' or 'frf', got {kind!r}")
    if baseline is not None:
        b = np.abs(np.asarray(baseline))
        if b.shape != f.shape or not np.all(np.isfinite(b) & (b > 0.0)):
            raise ValueError("baseline must be positive, finite and shaped like freq_hz")
        with np.errstate(over="ignore", under="ignore", divide="ignore"):
            w = w / b**2  # b**2 underflows to 0 for b < 1e-162: inf, refused next
        if not np.all(np.isfinite(w)):
            raise ValueError("the response over the baseline overflows float64")
    keep = f > 0.0
    if not np.any(w[keep] > 0.0):
        raise ValueError("the response is zero at every positive frequency: nothing to shape")
    return f[keep], w[keep]


def _candidate(
    shaper: ImpulseShaper, f: np.ndarray, w: np.ndarray, thr: float, tests: Sequence[float]
) -> ShaperCandidate:
    if np.all(shaper.amplitudes >= 0.0):
        # V <= 1 for non-negative amplitudes: bins at or below the threshold add nothing
        above = w > thr
        f, w = f[above], w[above]
    vmax = np.max([shaper.vibration(f, z) for z in tests], axis=0)
    all_vib = np.maximum(w - thr, 0.0).sum()
    # > 0: w is finite (`_weights`) and thr = max(w) / reduction < max(w)
    v = float(np.maximum(vmax * w - thr, 0.0).sum() / all_vib)
    return ShaperCandidate(
        shaper=shaper,
        vibrations=v,
        delay=shaper.delay,
        score=shaper.delay * (v**1.5 + 0.2 * v + 0.01),  # Klipper's weights, delay for smoothing
    )


def _scan(
    cfg: ShaperFitConfig,
    design_freqs: np.ndarray,
    f: np.ndarray,
    w: np.ndarray,
    thr: float,
    scans: dict[str, tuple[ShaperCandidate, ...]],
    per_type: dict[str, ShaperCandidate],
) -> None:
    """Scan every type over the design frequencies and dampings; fill ``scans``, ``per_type``."""
    for name in cfg.names:
        cands = []
        for fd in design_freqs:
            for zd in cfg.design_dampings:
                try:
                    sh = design_shaper(name, float(fd), zd, v_tol=cfg.v_tol)
                except ValueError:  # the family does not exist at this damping
                    continue
                cands.append(_candidate(sh, f, w, thr, cfg.test_dampings))
        if not cands:
            continue
        best = min(cands, key=lambda c: c.vibrations)
        chosen = best
        for c in cands:
            if c.vibrations < best.vibrations * 1.1 + 0.0005 and c.score < chosen.score:
                chosen = c
        scans[name] = tuple(cands)
        per_type[name] = chosen


def fit_shaper(
    freq_hz: np.ndarray,
    response: np.ndarray,
    *,
    kind: Literal["psd", "frf"] = "psd",
    baseline: np.ndarray | None = None,
    config: ShaperFitConfig | None = None,
) -> ShaperFit:
    """Fit classic shapers to a measured vibration spectrum and choose one.

    Parameters
    ----------
    freq_hz : numpy.ndarray
        Frequencies, Hz, strictly increasing, shape (n,).
    response : numpy.ndarray
        PSD (``kind="psd"``, >= 0) or FRF (``kind="frf"``, complex or magnitude), shape (n,).
    kind : {"psd", "frf"}
        What ``response`` is (see the module for the weights).
    baseline : numpy.ndarray, optional
        Magnitude the response is divided by (e.g. ``|G(j 2 pi f)|`` of the model without
        the mode), shape (n,).
    config : ShaperFitConfig, optional
        Types, scanned frequencies and dampings (Klipper's defaults).

    Returns
    -------
    ShaperFit
        The chosen shaper, each type's, and every scanned candidate.

    Raises
    ------
    ValueError
        Bad arrays, or no type could be designed in the scanned range.
    """
    cfg = ShaperFitConfig() if config is None else config
    f, w = _weights(freq_hz, response, kind, baseline)
    thr = float(w.max()) / cfg.vibration_reduction
    lo, hi = cfg.freq_range_hz if cfg.freq_range_hz is not None else (float(f[0]), float(f[-1]))
    if lo < float(f[0]) or hi > float(f[-1]):
        raise ValueError(
            f"the design range {lo:g}-{hi:g} Hz reaches beyond the data, which span "
            f"{float(f[0]):g}-{float(f[-1]):g} Hz: a shaper there would be scored against "
            "vibration nobody measured; choose a range within the data"
        )
    design_freqs = np.linspace(lo, hi, cfg.n_freqs)
    scans: dict[str, tuple[ShaperCandidate, ...]] = {}
    per_type: dict[str, ShaperCandidate] = {}
    with one_blas_thread():  # many small evaluations: BLAS threads only cost here
        _scan(cfg, design_freqs, f, w, thr, scans, per_type)
    if not per_type:
        raise ValueError(f"none of {cfg.names} could be designed at dampings {cfg.design_dampings}")
    best_c: ShaperCandidate | None = None
    for c in per_type.values():
        if best_c is None or (
            c.score * 1.2 < best_c.score
            or (c.score * 1.05 < best_c.score and c.delay * 1.1 < best_c.delay)
        ):
            best_c = c
    assert best_c is not None
    if best_c.shaper.name == "zv":
        for c in per_type.values():
            if c.shaper.name != "zv" and c.vibrations * 1.1 < best_c.vibrations:
                best_c = c
                break
    return ShaperFit(best=best_c, per_type=per_type, scans=scans, freq_hz=f, weights=w)
