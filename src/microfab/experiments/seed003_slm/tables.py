"""Tables of an ``slm-shaping`` run: the seed's numbers beside ours, the layer's scan times.

The run's JSON is `microfab.machines.slm_galvo.shaping.ShapingRun.summary`.
"""

from __future__ import annotations

import numpy as np

from microfab.core.provenance import Shows, quantity
from microfab.experiments.seed003_slm import paper
from microfab.machines.slm_galvo.shaping import ShapingRun
from microfab.process.slm.estimate import implied_jumps
from microfab.report import slm_tables
from microfab.report.provenance import OURS, labelled
from microfab.report.tables import Table, versus

__all__ = ["NOTES", "scan_table", "seed_table"]

#: What differs from the seed and why, one line each (report and ``reproduce``).
NOTES = (
    "Twin: the seed's G(s) at 10 µs, 0.3 bit noise, ±32768 bit field "
    "(microfab/data/galvo_slm.toml); the fit and the shaper run on our chirp data.",
    "The seed's shaper poles are at 2π·4000 rad/s (its coefficients), not the printed "
    "3000 rad/s. Its ZOH filter on the 10 µs axis settles far later than the continuous "
    "design (the 23.7x spike reaches the axis as a 10 µs staircase); ZPETC, an inverse of "
    "the sampled axis, keeps the design's speed. Sampled figures count ZPETC's look-ahead "
    "as delay, which a controller that sends the command early would not pay.",
    "Lattice: simple cubic, strut 250 µm, 5 % volume fraction (seed §4), clipped to a disc "
    "outline (no bunny mesh is shipped); hatch 100 µm; mark 0.6 m/s, jump 5 m/s (assumed).",
)


#: The seed's G(s) as the twin holds it (``galvo_slm.toml``): a row that recovers it shows
#: these inputs.
_MODEL = tuple(
    ("galvo_slm.toml", f"model.{k}")
    for k in ("numerator", "denominator_s2", "denominator_s1", "denominator_s0")
)
_RECOVERED = Shows(parameters=_MODEL)


def _q(*parts: str) -> Shows:
    return Shows((quantity("003", "part 2", *parts),))


def _digits(ours: np.ndarray, seed: tuple[float, ...]) -> str:
    return ", ".join(f"{o:.4g}" for o in ours) + " / " + ", ".join(f"{v:.4g}" for v in seed)


def seed_table(run: ShapingRun) -> Table:
    """The issue's acceptance rows: ours / seed (seed 003 part 2 §§1-4)."""
    m = run.identification.fit.model
    zoh, zpetc = run.shapers["zoh"], run.shapers["zpetc"]
    met = run.metrics
    lag0, lag1 = met["lag"]
    set0, set1 = met["settling"]
    spd0, spd1 = met["speed95"]
    ss = met["settling_sampled"]
    jd = run.jump_delay_s
    us = "{:.1f}".format
    rows: list[tuple[str, str, Shows]] = []
    err = run.fit_error()
    if err is not None:
        seed_coef = (paper.MODEL_NUM[0], *paper.MODEL_DEN[1:])
        rows += [
            (
                "fit b0; a2, a1, a0 (twin, ZOH-aware)",
                _digits(run.fit_coefficients(), seed_coef),
                _RECOVERED,
            ),
            (
                "fit error, largest [%]",
                f"{100 * err:.3g} (target 2 with noise, 0.01 without)",
                OURS,
            ),
        ]
    else:
        rows.append(("fit", m.formula(), _RECOVERED))
    if m.real_poles_hz:
        rows.append(
            ("real pole [Hz]", versus(m.real_poles_hz[0], 550.5, "{:.1f}".format), _RECOVERED)
        )
    if m.complex_modes:
        md = m.complex_modes[0]
        rows.append(
            (
                "complex pair [Hz], ζ",
                f"{md.frequency_hz:.1f}, {md.damping:.4f} / 965.2, 0.4995",
                _RECOVERED,
            )
        )
    rows += [
        ("−3 dB bandwidth [Hz]", versus(m.bandwidth_hz(), 710.6, "{:.1f}".format), _RECOVERED),
        ("continuous shaper num", _digits(zoh.num, paper.CONTINUOUS_SHAPER_NUM),
         _q("§2", "continuous shaper numerator")),
        ("continuous shaper den", _digits(zoh.den, paper.CONTINUOUS_SHAPER_DEN),
         _q("§2", "continuous shaper denominator")),
        ("discrete shaper num (ZOH)", _digits(zoh.num_d[1:], paper.DISCRETE_SHAPER_NUM),
         _q("§2", "discrete shaper numerator")),
        ("discrete shaper den (ZOH)", _digits(zoh.den_d, paper.DISCRETE_SHAPER_DEN),
         _q("§2", "discrete shaper denominator")),
        ("ramp position lag [µs], without → with", f"{lag0 * 1e6:.1f} → {lag1 * 1e6:.1f} "
         f"({lag0 / lag1:.2f}x; seed: a factor two)", _q("§3", "lag ratio")),
        ("2 % settling of a step [µs], continuous", f"{set0 * 1e6:.0f} → {set1 * 1e6:.0f} "
         f"({set0 / set1:.2f}x; seed: a factor two)", _q("§3", "settling ratio")),
        ("2 % settling, sampled shaper on the sampled axis [µs], none / ZOH / ZPETC",
         f"{ss['unshaped'] * 1e6:.0f} / {ss['zoh'] * 1e6:.0f} / {ss['zpetc'] * 1e6:.0f} "
         f"(ZPETC look-ahead {zpetc.preview * zpetc.dt * 1e6:g} µs included)", OURS),
        ("time to 95 % speed [µs]", f"{spd0 * 1e6:.0f} → {spd1 * 1e6:.0f} ({spd0 / spd1:.2f}x;"
         " seed: '25% faster' (Fig. 7), 'twice as fast' (conclusion))",
         _q("Fig. 7", "speed-up")),
        ("time to 95 % of the jump speed through the loop [µs]",
         "{:.0f} → {:.0f}".format(*(v * 1e6 for v in met["speed95_loop"])), OURS),
        (f"jump delay, {run.settings.jump_m * 1e3:.2f} mm at "
         f"{run.settings.rtc.speeds.jump_m_s:g} m/s, "
         f"{100 * run.settings.tolerance.relative:g} % band [µs]",
         f"{us(jd['unshaped'] * 1e6)} → ZOH {us(jd['zoh'] * 1e6)}, ZPETC "
         f"{us(jd['zpetc'] * 1e6)} / 750 → 250", _q("§4", "jump delay")),
    ]  # fmt: skip
    imp = implied_jumps()
    a, b = (run.scan[k].dynamics.total_s for k in ("unshaped", "shaped"))
    rows += [
        ("seed's scan time 4686 → 4219 s implies", f"{imp.n_jumps:.3g} jumps, jump delays "
         f"{100 * imp.delay_share:.2f} % of the time",
         Shows(from_seed=("seed 003 part 2 §4: scan times 4686 s and 4219 s, jump delays "
                          "750 µs and 250 µs",))),
        (f"layer ({run.layer_vectors} vectors) scan time, dynamics-aware [s]",
         f"{a:.4f} → {b:.4f} (−{100 * run.scan_cut:.1f} %; seed: −10 % on the whole bunny)",
         _q("§4", "scan time cut")),
    ]  # fmt: skip
    return labelled(
        Table(
            title="Seed 003 part 2 on the SLM galvo twin, ours / seed",
            columns=("figure", "ours / seed"),
            rows=[r[:2] for r in rows],
        ),
        [r[2] for r in rows],
    )


def scan_table(run: ShapingRun) -> Table:
    """The layer's three estimates per category, without and with the shaper, s."""
    table = slm_tables.scan_table(
        run.scan,
        title=f"Layer scan time by category [s] ({run.layer_vectors} vectors, "
        f"{run.settings.layer.source})",
        shaped=run.settings.shaper.discretization.upper(),
        note="Naive: Σ L/v (PySLM-like). Fixed: the RTC's timing with the set delays (jump "
        f"{run.settings.rtc.delays.jump_s * 1e6:g} µs without the shaper, the shaper's "
        "derived delay with it). Dynamics-aware: per-vector delays from exact propagation "
        "of the twin.",
    )
    return labelled(table, OURS)
