"""Calibration of the NaAlg relaxation law from the seed's two breakup times.

Serves ``microfab droplet calibrate``: the fit is written into the printhead machine's
data file, ``naalg.toml`` (`microfab.machines.printhead.DATA_FILES`).

The relaxation time is the one fluid property that nothing measured pins down, so the law
``λ(c) = λ_ref · (c / 1 %)^m`` (:mod:`microfab.process.inkjet.fluids`) is inferred from the
only two numbers the seed quotes (seed 003 part 1,
``../shared/seeds/003_4915b267b12a78d4.txt``, "Typical droplet formation process", Fig. 2,
50 V; `SEED_BREAKUP`): the first breakup of 0.15 % NaAlg at 95 µs and of 1 %
NaAlg at 230 µs. Everything else the model predicts (pinch-off modes, the other
four concentrations, the voltage trend) is then checked, not fitted.

The procedure is deterministic and runs the full drop-on-demand model
(`microfab.machines.printhead.run_point`, the one path every droplet command takes):

1. ``λ_ref`` from the 1 % time alone (at 1 % the law gives ``λ = λ_ref`` whatever ``m``).
   The breakup time is not monotone in λ: a larger λ means a smaller polymer modulus
   ``η_p / λ``, and once the FENE-P stress ceiling ``G L²`` falls below the capillary
   pressure of the breakup neck the thread snaps early. So λ is scanned upwards from the
   lower bound in steps of ``scan_factor`` until the model breaks up at or after the
   target, and the crossing is refined by Brent's method on ``log λ``: the smallest
   relaxation time that reproduces the time.
2. ``m`` from the 0.15 % time, by bounded scalar minimisation of
   ``(ln t_model − ln t_seed)²`` over the exponent bounds. When the model cannot reach
   the target the optimum lands on a bound, which the fit reports.

``write_relaxation`` stores the result in a copy of the table (or the packaged one) with
status ``"calibrated"`` and a note naming the command.
"""

from __future__ import annotations

import functools
import math
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from scipy import optimize

from microfab.core.provenance import Calibration, quantity
from microfab.core.validate import check_in_range
from microfab.io.atomic import atomic_write_text
from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point
from microfab.process.inkjet.breakup import BreakupMode
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL
from microfab.process.inkjet.fluids import NaAlgTable, _parse_table, load_table, naalg

__all__ = [
    "CALIBRATIONS",
    "SEED_BREAKUP",
    "SEED_VOLTAGE_V",
    "Evaluation",
    "RelaxationFit",
    "breakup_quantity",
    "calibrate_relaxation",
    "model_breakup",
    "simulated_breakup",
    "write_relaxation",
]

#: Drive voltage of the seed's quoted breakup times, V.
SEED_VOLTAGE_V = 50.0  # seed 003 part 1, Fig. 2 and 4

#: First breakup at 50 V: concentration % w/v → (time s, mode). Seed 003 part 1,
#: "Typical droplet formation process" and Fig. 2: 0.15 % at 95 µs by front-pinching,
#: 1 % at 230 µs by exit-pinching. The calibration's targets.
SEED_BREAKUP: dict[float, tuple[float, BreakupMode]] = {
    0.15: (95e-6, "front"),
    1.0: (230e-6, "exit"),
}


def breakup_quantity(concentration_pct: float, what: str = "time") -> str:
    """Id of one seed breakup number at 50 V: ``what`` is ``"time"`` or ``"mode"``."""
    return quantity("003", "Fig. 4", f"{concentration_pct:g} %", what)


#: One fit per jet model (each writes its own relaxation law): the times of `SEED_BREAKUP`;
#: the modes are not fitted.
CALIBRATIONS = tuple(
    Calibration(
        command=f"microfab droplet calibrate --model {m}",
        data_file="naalg.toml",
        targets=frozenset(breakup_quantity(c) for c in SEED_BREAKUP),
        what=f"relaxation-time law of the {m} jet model",
    )
    for m in ("lagrangian", "eulerian")
)

#: Simulated time per calibration run, s: long enough for a breakup 70 % later than the
#: latest target.
_DURATION_S = 400e-6

BreakupFn = Callable[[float, float], tuple[float | None, BreakupMode | None]]


def simulated_breakup(
    concentration_pct: float, relaxation_time_s: float, model: str = DEFAULT_JET_MODEL
) -> tuple[float | None, BreakupMode | None]:
    """First breakup time and mode of NaAlg at the seed's 50 V drive.

    Parameters
    ----------
    concentration_pct : float
        NaAlg concentration, % w/v.
    relaxation_time_s : float
        Relaxation time to use instead of the table's law, s.
    model : {"lagrangian", "eulerian"}, optional
        Jet model (:func:`microfab.process.inkjet.droplet.simulate_droplet`).

    Returns
    -------
    (float or None, str or None)
        Breakup time in s and mode; ``(None, None)`` without breakup in 400 µs.
    """
    res = run_point(
        SweepPoint(concentration_pct, SEED_VOLTAGE_V),
        DropletSettings(duration_s=_DURATION_S, after_breakup_s=2e-6, model=model),
        fluid=naalg(concentration_pct, relaxation_time_s=relaxation_time_s),
    )
    return res.breakup_time_s, res.breakup_mode


def model_breakup(model: str) -> BreakupFn:
    """:func:`simulated_breakup` with one jet model, as `calibrate_relaxation` takes it."""
    return functools.partial(simulated_breakup, model=model)


@dataclass(frozen=True)
class Evaluation:
    """One model run of the calibration."""

    concentration_pct: float
    relaxation_time_s: float
    breakup_time_s: float | None
    breakup_mode: BreakupMode | None


@dataclass(frozen=True, kw_only=True)
class RelaxationFit:
    """Result of :func:`calibrate_relaxation`.

    Attributes
    ----------
    lambda_ref_s, exponent : float
        The fitted law ``λ(c) = lambda_ref_s · (c / reference_pct)^exponent``.
    reference_pct : float
        Concentration of ``lambda_ref_s``, % w/v.
    model_breakup : dict
        Concentration → (time s or None, mode or None) of the model with the fitted law.
    at_bound : tuple of str
        Names of the parameters that ended on a bound of the table.
    evaluations : tuple of Evaluation
        Every model run, in order.
    """

    lambda_ref_s: float
    exponent: float
    reference_pct: float
    model_breakup: dict[float, tuple[float | None, BreakupMode | None]]
    at_bound: tuple[str, ...]
    evaluations: tuple[Evaluation, ...] = field(repr=False)

    def summary(self) -> str:
        """One line per target: model against seed."""
        lines = [
            f"λ_ref = {self.lambda_ref_s * 1e6:.3g} µs at {self.reference_pct:g} %, "
            f"exponent m = {self.exponent:.3g}"
            + (f" (at bound: {', '.join(self.at_bound)})" if self.at_bound else "")
        ]
        for c, (t_seed, mode_seed) in SEED_BREAKUP.items():
            t, mode = self.model_breakup.get(c, (None, None))
            got = "no breakup" if t is None else f"{t * 1e6:.1f} µs {mode}"
            lines.append(f"  {c:g} %: model {got}; seed {t_seed * 1e6:g} µs {mode_seed}")
        return "\n".join(lines)


def calibrate_relaxation(
    table: NaAlgTable | None = None,
    *,
    breakup: BreakupFn = simulated_breakup,
    scan_factor: float = 1.25,
    rtol: float = 0.01,
    progress: Callable[[Evaluation], None] | None = None,
) -> RelaxationFit:
    """Fit ``λ_ref`` and the exponent to the seed's two breakup times.

    Parameters
    ----------
    table : NaAlgTable, optional
        Property table with the bounds (default: the packaged one).
    breakup : callable, optional
        ``(concentration %, λ s) → (breakup time s or None, mode)``; default: the full
        drop-on-demand model at 50 V (:func:`simulated_breakup`).
    scan_factor : float, optional
        Ratio between successive relaxation times of the upward scan (> 1).
    rtol : float, optional
        Relative tolerance on ``λ_ref`` and absolute tolerance on the exponent.
    progress : callable, optional
        Called with each :class:`Evaluation`.

    Returns
    -------
    RelaxationFit

    Raises
    ------
    ValueError
        If ``scan_factor <= 1`` or ``rtol`` is not in (0, 0.5).

    Examples
    --------
    A stand-in model where the breakup time grows as ``100 µs + 10 λ``:

    >>> def fake(c, lam):
    ...     return 100e-6 + 10.0 * lam, "exit"
    >>> fit = calibrate_relaxation(breakup=fake)
    >>> round(fit.lambda_ref_s * 1e6, 1)
    13.0
    """
    if not scan_factor > 1.0:
        raise ValueError(f"scan_factor must be > 1, got {scan_factor}")
    check_in_range("rtol", rtol, 0.0, 0.5, low_closed=False, high_closed=False)
    t = table or load_table()
    evals: list[Evaluation] = []
    cache: dict[tuple[float, float], tuple[float | None, BreakupMode | None]] = {}

    def run(c: float, lam: float) -> tuple[float | None, BreakupMode | None]:
        key = (float(c), float(lam))
        c, lam = key
        if key not in cache:
            tb, mode = breakup(c, lam)
            cache[key] = (None if tb is None else float(tb), mode)
            ev = Evaluation(c, lam, *cache[key])
            evals.append(ev)
            if progress is not None:
                progress(ev)
        return cache[key]

    ref_c = t.reference_pct
    low_c = min(SEED_BREAKUP)
    target_ref = SEED_BREAKUP[ref_c][0]
    target_low = SEED_BREAKUP[low_c][0]

    def late(c: float, lam: float, target: float) -> float:
        tb, _ = run(c, lam)
        return 1.0 if tb is None else tb / target - 1.0

    lo_b, hi_b = t.lambda_ref_bounds_s
    at_bound: list[str] = []
    lam = lo_b
    prev = None
    while True:
        if late(ref_c, lam, target_ref) >= 0.0:
            break
        prev = lam
        if lam >= hi_b:
            break
        lam = min(lam * scan_factor, hi_b)
    if late(ref_c, lam, target_ref) < 0.0:
        lam_ref = hi_b
        at_bound.append("lambda_ref_s")
    elif prev is None:
        lam_ref = lo_b
        at_bound.append("lambda_ref_s")
    else:
        root = optimize.brentq(
            lambda x: late(ref_c, math.exp(x), target_ref),
            math.log(prev),
            math.log(lam),
            xtol=rtol,
        )
        lam_ref = math.exp(root)

    m_lo, m_hi = t.exponent_bounds

    def misfit(m: float) -> float:
        tb, _ = run(low_c, lam_ref * (low_c / ref_c) ** m)
        return 1e6 if tb is None else math.log(tb / target_low) ** 2

    best = optimize.minimize_scalar(
        misfit, bounds=(m_lo, m_hi), method="bounded", options={"xatol": rtol}
    )
    m = float(best.x)
    # the bounded search never evaluates the bounds themselves: compare them too
    for edge in (m_lo, m_hi):
        if misfit(edge) < misfit(m):
            m = edge
    if m - m_lo <= 2 * rtol or m_hi - m <= 2 * rtol:
        at_bound.append("exponent")
    model = {
        ref_c: run(ref_c, lam_ref),
        low_c: run(low_c, lam_ref * (low_c / ref_c) ** m),
    }
    return RelaxationFit(
        lambda_ref_s=lam_ref,
        exponent=m,
        reference_pct=ref_c,
        model_breakup=model,
        at_bound=tuple(at_bound),
        evaluations=tuple(evals),
    )


_BLOCK = re.compile(r"^\[relaxation\]\n(.*?)(?=^\[relaxation\.bounds\])", re.S | re.M)


def check_property_table(path: str | Path) -> None:
    """Refuse, before a calibration runs, a file `write_relaxation` could not update.

    Parameters
    ----------
    path : str or Path
        The ``--write`` file: a readable TOML property table with the layout of
        ``microfab/data/naalg.toml`` (a ``[relaxation]`` table followed by
        ``[relaxation.bounds]``) that loads as one.

    Raises
    ------
    ValueError
        Naming the file and what is wrong with it.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
        table = tomllib.loads(text)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{p}: not a readable property table ({exc})") from exc
    if not _BLOCK.search(text):
        raise ValueError(f"{p}: no [relaxation] table followed by [relaxation.bounds]")
    _parse_table(table, str(p))


def write_relaxation(
    fit: RelaxationFit, path: str | Path, *, command: str, model: str = DEFAULT_JET_MODEL
) -> None:
    """Store a fitted relaxation law in a property-table file, atomically.

    Only the law of ``model`` is rewritten (``status = "calibrated"``): ``[relaxation]`` for
    the Lagrangian jet model, ``[relaxation_<model>]`` for another (added at the end of
    the file if missing); comments, bounds and every other value are kept.

    Parameters
    ----------
    fit : RelaxationFit
        The calibration result.
    path : str or Path
        A TOML file with the layout of ``microfab/data/naalg.toml``.
    command : str
        The command that produced ``fit``, recorded in the note.
    model : str, optional
        The jet model the fit was made with.

    Raises
    ------
    ValueError
        If the file has no ``[relaxation]`` table followed by ``[relaxation.bounds]``, or
        the result does not load back.
    """
    p = Path(path)
    text = p.read_text(encoding="utf-8")
    if not _BLOCK.search(text):
        raise ValueError(f"{p}: no [relaxation] table followed by [relaxation.bounds]")
    if not re.fullmatch(r"[a-z]+", model):
        raise ValueError(f"model must be a lower-case name, got {model!r}")
    result = "; ".join(
        f"{c:g} %: " + ("no breakup" if tb is None else f"{tb * 1e6:.1f} µs {mode}")
        for c, (tb, mode) in fit.model_breakup.items()
    )
    seed = "; ".join(f"{c:g} %: {tb * 1e6:g} µs {mode}" for c, (tb, mode) in SEED_BREAKUP.items())
    bound = f" Parameters at a bound: {', '.join(fit.at_bound)}." if fit.at_bound else ""
    block = (
        # every digit: a rounded λ_ref moves a breakup near its threshold (the Lagrangian
        # 1 % run broke at 338 µs with the fit and 350 µs with λ_ref to five digits)
        f"lambda_ref_s = {fit.lambda_ref_s!r}\n"
        f"reference_pct = {fit.reference_pct:g}\n"
        f"exponent = {fit.exponent!r}\n"
        'status = "calibrated"\n'
        f'note = """fitted by `{command}` (microfab.machines.printhead.calibration) '
        f"with the {model} jet model to the seed's first-breakup times at 50 V (seed 003 "
        f"part 1, Fig. 2: {seed}). Model with the fit: "
        f'{result}.{bound}"""\n\n'
    )
    if model == "lagrangian":
        new = _BLOCK.sub(lambda _: "[relaxation]\n" + block, text, count=1)
    else:
        head = f"[relaxation_{model}]\n"
        own = re.compile(rf"^\[relaxation_{model}\]\n(.*?)(?=^\[|\Z)", re.S | re.M)
        if own.search(text):
            new = own.sub(lambda _: head + block, text, count=1)
        else:
            new = text.rstrip("\n") + "\n\n" + head + block.rstrip("\n") + "\n"
    _parse_table(tomllib.loads(new), str(p))  # refuse to write a table that would not load
    atomic_write_text(p, new)
