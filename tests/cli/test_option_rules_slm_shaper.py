"""Option rules of ``slm scan-time|build`` and ``shaper design|compare`` (issue 44, C and D).

Every number is declared with its unit and range and refused while the command line is
parsed; an option the chosen mode does not use is refused, not ignored; options that
contradict each other or the input are refused naming both. Each refusal is one
``error:`` line, exit code 2, and nothing is written. The shared declarations are the
``slm-shaping`` job's keys (`microfab.experiments.seed003_slm.keys`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import typer
from click.testing import CliRunner

from microfab.cli import app
from microfab.cli._options import declared
from microfab.experiments.seed003_slm import keys

runner = CliRunner()
#: The ``microfab`` command built once (typer's runner builds it again per call, 0.2 s).
MICROFAB = typer.main.get_command(app)

SCAN = ("slm", "scan-time", "circle:radius=2e-3")
LATTICE = ("slm", "scan-time", "lattice:z=4e-4,radius=3e-3")
BUILD = ("slm", "build", "--layers", "1", "--outline-radius-mm", "1")
DESIGN = ("shaper", "design", "--kind", "zv", "--freq-hz", "3000")
COMPARE = ("shaper", "compare", "--true-mode", "--shapers", "zv")


def _refused(
    argv: tuple[str, ...], tmp_path: Path, one_error_line: Callable[[Any, str], None], says: str
) -> None:
    """Run ``argv`` with its outputs in ``tmp_path``; one error line, nothing written."""
    before = sorted(tmp_path.iterdir())
    outs = {
        "slm": ["--json", str(tmp_path / "out.json")],
        "shaper": ["--out" if argv[1] == "design" else "--json", str(tmp_path / "out.json")],
    }[argv[0]]
    if argv[1] == "build":
        outs += ["--results-dir", str(tmp_path / "layers")]
    res = runner.invoke(MICROFAB, [*argv, *outs], prog_name="microfab")
    one_error_line(res, says)
    assert sorted(tmp_path.iterdir()) == before


# ------------------------------------------------------------------ ranges, at parse time
@pytest.mark.parametrize(
    "argv, says",
    [
        # issue 44: a hatch direction is an angle modulo 180°, a galvo has a top speed
        ((*SCAN, "--hatch-angle-deg", "400"), "400 deg is outside the allowed range [-180, 180]"),
        ((*SCAN, "--hatch-angle-deg", "-180.5"), "--hatch-angle-deg"),
        ((*SCAN, "--mark-speed", "600"), "600 m/s is outside the allowed range [0.0001, 10] m/s"),
        ((*SCAN, "--jump-speed", "10.5"), "--jump-speed"),
        ((*SCAN, "--mark-speed", "1e-5"), "--mark-speed"),
        ((*SCAN, "--jump-delay-us", "20000"), "--jump-delay-us"),
        ((*SCAN, "--shaped-jump-delay-us", "-10"), "--shaped-jump-delay-us"),
        ((*SCAN, "--laser-off-delay-us", "nan"), "not a finite number"),
        ((*SCAN, "--sky-writing", "4"), "--sky-writing"),
        ((*SCAN, "--sky-writing", "1", "--sky-post", "1001"), "--sky-post"),
        ((*SCAN, "--tolerance-pct", "0"), "--tolerance-pct"),
        ((*SCAN, "--tolerance-pct", "60"), "--tolerance-pct"),
        ((*SCAN, "--hatch-um", "1"), "1 µm is outside the allowed range [1.5, 1000] µm"),
        ((*SCAN, "--hatch-um", "5000"), "--hatch-um"),
        ((*BUILD, "--hatch-rotation-deg", "400"), "--hatch-rotation-deg"),
        ((*BUILD, "--mark-speed", "600"), "--mark-speed"),
        ((*BUILD, "--layer-um", "0.5"), "--layer-um"),
        ((*BUILD, "--outline-radius-mm", "50"), "--outline-radius-mm"),
        ((*BUILD, "--layers", "0"), "--layers"),
        ((*BUILD, "--workers", "513"), "--workers"),
        ((*DESIGN, "--freq-hz", "0.5"), "--freq-hz"),
        ((*DESIGN, "--damping", "1"), "--damping"),
        ((*DESIGN, "--dt", "0.1"), "--dt"),
        (("shaper", "design", "--poles-hz", "0"), "--poles-hz"),
        (("shaper", "design", "--order", "17"), "--order"),
        ((*COMPARE, "--jump-bit", "0"), "--jump-bit"),
        # make fuzz: a step of 1e-12 bit was accepted by an open bound at 0
        ((*COMPARE, "--jump-bit", "0.5"), "0.5 bit is outside the allowed range [1, 65536] bit"),
        ((*COMPARE, "--start-bit", "40000"), "--start-bit"),
        ((*COMPARE, "--band-pct", "60"), "--band-pct"),
        (("shaper", "compare", "--shapers", "ei", "--v-tol", "0.3"), "--v-tol"),
        (("shaper", "compare", "--seed", "-1"), "--seed"),
    ],
)
def test_an_option_outside_its_range_is_refused(
    argv: tuple[str, ...], says: str, tmp_path: Path, one_error_line
) -> None:
    _refused(argv, tmp_path, one_error_line, says)


# ------------------------------------------------------------------ mode against option
@pytest.mark.parametrize(
    "argv, says",
    [
        ((*SCAN, "--sky-prev", "5"), "--sky-prev has no effect with --sky-writing 0"),
        ((*SCAN, "--sky-writing", "0", "--sky-post", "5"), "--sky-post has no effect"),
        ((*SCAN, "--sky-writing", "1", "--mark-delay-us", "100"), "--mark-delay-us has no"),
        ((*SCAN, "--sky-writing", "3", "--mark-delay-us", "100"), "--mark-delay-us has no"),
        ((*SCAN, "--sky-writing", "1", "--polygon-delay-us", "100"), "--polygon-delay-us"),
        ((*SCAN, "--sky-writing", "2", "--variable-polygon"), "--variable-polygon has no"),
        ((*SCAN, "--shaped-jump-delay-us", "200"), "has no effect without --shaper"),
        ((*LATTICE, "--no-contours"), "has no effect on a lattice source"),
        ((*BUILD, "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"), "--workers has no"),
        (("shaper", "design", "--freq-hz", "3000"), "--freq-hz has no effect with --kind inv"),
        (("shaper", "design", "--damping", "0.1"), "--damping has no effect with --kind inv"),
        (("shaper", "design", "--axis", "x"), "--axis has no effect with --kind inverse"),
        ((*DESIGN, "--poles-hz", "5000"), "--poles-hz has no effect with --kind zv"),
        ((*DESIGN, "--order", "3"), "--order has no effect with --kind zv"),
        ((*DESIGN, "--discretization", "zpetc"), "--discretization has no effect"),
        ((*DESIGN, "--axis", "x"), "--axis has no effect with --freq-hz"),
        ((*DESIGN, "--freq-range", "100:200"), "--freq-range has no effect with --freq-hz"),
        ((*COMPARE, "--seed", "3"), "--seed has no effect with --true-mode"),
        ((*COMPARE, "--v-tol", "0.1"), "--v-tol has no effect with --shapers zv"),
    ],
)
def test_an_option_without_effect_in_the_mode_is_refused(
    argv: tuple[str, ...], says: str, tmp_path: Path, one_error_line
) -> None:
    _refused(argv, tmp_path, one_error_line, says)


def test_axis_with_a_psd_is_refused(tmp_path: Path, one_error_line) -> None:
    from microfab.io.trace import write_columns

    psd = tmp_path / "psd.csv"
    write_columns(psd, {"freq_hz": [1.0, 2.0, 3.0], "psd": [1.0, 2.0, 1.0]})
    argv = ("shaper", "design", "--kind", "zv", "--psd", str(psd), "--axis", "x")
    _refused(argv, tmp_path, one_error_line, "--axis has no effect with --psd")


# ------------------------------------------------------------------ consistency rules
@pytest.mark.parametrize(
    "argv, says",
    [
        (
            ("slm", "scan-time", "lattice:z=4e-4,radius=3e-3,hatch=5e-5", "--hatch-um", "80"),
            "--hatch-um 80 µm and the source's hatch=5e-05 m both set the hatch spacing",
        ),
        (
            ("slm", "build", "--layers", "40000", "--layer-um", "30"),
            "--layers 40000 of --layer-um 30 µm make a part 1.2 m tall",
        ),
        (
            ("slm", "build", "--outline-radius-mm", "0.05", "--hatch-um", "100"),
            "--outline-radius-mm 0.05 mm is smaller than --hatch-um 100 µm",
        ),
        (
            (*COMPARE, "--start-bit", "32000", "--jump-bit", "1000"),
            "--start-bit 32000 bit + --jump-bit 1000 bit ends at 33000 bit, outside the twin's",
        ),
    ],
)
def test_options_that_contradict_are_refused_naming_both(
    argv: tuple[str, ...], says: str, tmp_path: Path, one_error_line
) -> None:
    _refused(argv, tmp_path, one_error_line, says)


# ------------------------------------------------------------------ one declaration
def _params(*words: str) -> dict[str, Any]:
    cmd: Any = MICROFAB
    for w in words:
        cmd = cmd.commands[w]
    return {p.name: p for p in cmd.params}


#: Options that set what an ``slm-shaping`` job key sets, in the same unit.
SHARED = [
    (("slm", "scan-time"), "mark_speed", "scan", keys.MARK_SPEED),
    (("slm", "scan-time"), "jump_speed", "scan", keys.JUMP_SPEED),
    (("slm", "scan-time"), "jump_delay_us", "scan", keys.JUMP_DELAY),
    (("slm", "scan-time"), "mark_delay_us", "scan", keys.MARK_DELAY),
    (("slm", "scan-time"), "polygon_delay_us", "scan", keys.POLYGON_DELAY),
    (("slm", "scan-time"), "laser_on_delay_us", "scan", keys.LASER_ON_DELAY),
    (("slm", "scan-time"), "laser_off_delay_us", "scan", keys.LASER_OFF_DELAY),
    (("slm", "scan-time"), "hatch_um", "layer", keys.HATCH_SPACING),
    (("slm", "scan-time"), "hatch_angle_deg", "layer", keys.HATCH_ANGLE),
    (("slm", "build"), "mark_speed", "scan", keys.MARK_SPEED),
    (("slm", "build"), "jump_speed", "scan", keys.JUMP_SPEED),
    (("slm", "build"), "hatch_um", "layer", keys.HATCH_SPACING),
    (("slm", "build"), "layer_um", "build", keys.LAYER_THICKNESS),
    (("slm", "build"), "outline_radius_mm", "build", keys.OUTLINE_RADIUS),
    (("slm", "build"), "hatch_rotation_deg", "build", keys.HATCH_ROTATION),
    (("slm", "build"), "workers", "build", keys.WORKERS),
    (("shaper", "design"), "poles_hz", "shaper", keys.POLE_HZ),
    (("shaper", "design"), "order", "shaper", keys.SHAPER_ORDER),
    (("shaper", "compare"), "seed", "twin", keys.TWIN_SEED),
]


@pytest.mark.parametrize("words, option, section, key", SHARED)
def test_an_option_shares_the_job_key_of_its_quantity(
    words: tuple[str, str], option: str, section: str, key: Any
) -> None:
    from microfab.experiments.seed003_slm.job import SCHEMA

    assert declared(_params(*words)[option]) is key
    assert any(k is key for k in SCHEMA[section])


def test_every_number_of_these_commands_is_declared() -> None:
    for words in (("slm", "scan-time"), ("slm", "build"), ("shaper", "design"),
                  ("shaper", "compare")):  # fmt: skip
        for name, p in _params(*words).items():
            if getattr(getattr(p, "type", None), "name", "") in ("float", "integer"):
                assert declared(p) is not None, f"{' '.join(words)} {name}"


def test_the_repeated_bounds_equal_their_sources() -> None:
    """The values `keys` repeats (to stay light) equal the data file's and the modules'."""
    from microfab.control.shaping import MAX_ADDED_POLES
    from microfab.machines.slm_galvo import machine as slm_galvo
    from microfab.process.slm.build import LAYER_RANGE_M
    from microfab.process.slm.source import MAX_HEIGHT_M

    cfg = slm_galvo.twin().config
    assert keys.BIT_M == cfg.bit_size_m
    assert keys.FIELD_BIT == cfg.field_bit
    assert keys.OUTLINE_RADIUS.high == pytest.approx(cfg.field_bit * cfg.bit_size_m * 1e3)
    lim = slm_galvo.limits()
    assert keys.MARK_SPEED.high == keys.JUMP_SPEED.high == max(lim.velocity)
    assert keys.OUTLINE_RADIUS.high * 1e-3 == pytest.approx(lim.workspace[0][1])
    lo, hi = LAYER_RANGE_M
    assert (keys.LAYER_THICKNESS.low, keys.LAYER_THICKNESS.high) == pytest.approx(
        (lo * 1e6, hi * 1e6)
    )
    assert keys.SHAPER_ORDER.high == MAX_ADDED_POLES
    assert keys.MAX_LAYERS * 10e-6 == pytest.approx(MAX_HEIGHT_M)
