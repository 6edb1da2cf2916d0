"""Cases the option fuzz (`fuzz_options`) found, kept as regressions: each is refused
cleanly now (exit 2, one ``error:`` line, every file as it was).

Before the fixes: tracebacks (MemoryError of PiB, OverflowError, HiGHS and settling
errors), hangs (a pattern of 2**31 circles, 2**31 stage-1 points, 1e30 worker processes,
a scheduler address that never answers), refusals after a table or a progress bar had
been printed, and refusals that had already written the sweep's settings.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fuzz_cases  # noqa: F401  (registers the workspace fixture through fuzz_options)
from fuzz_driver import Case, run_case
from fuzz_workspace import RECIPES

NANO = RECIPES["nanomanipulator analyze"].argv


def _but(argv: tuple[str, ...], opt: str) -> tuple[str, ...]:
    """``argv`` without ``opt`` and its value (an option is given once)."""
    i = argv.index(opt)
    return argv[:i] + argv[i + 2 :]


OPT = ("optimize", "circle:radius=0.002", "--model", "models", "--out", "optimized",
       "--stage", "1", "--n", "20")  # fmt: skip
TRAJ = ("trajectory", "part.dxf", "--time-optimal", "--n-grid", "50", "--rate", "2000",
        "--out", "reference.csv", "--plot", "profile.png")  # fmt: skip
SWEEP = ("droplet", "sweep", "--concentrations", "0.15", "--voltages", "50", "--duration",
         "10", "--out", "sweep")  # fmt: skip
SLM = ("slm", "build", "--layers", "1", "--outline-radius-mm", "1", "--results-dir",
       "slm_layers")  # fmt: skip
LASER = ("laser", "analyze", "laser_trace.h5", "--drawing", "circle:radius=30e-6",
         "--replay", "--out", "laser_report", "--json", "laser.json")  # fmt: skip

CHIRP = ("identify", "chirp", "--f0", "100", "--f1", "2000", "--period", "0.01", "--band",
         "100:2000", "--json", "chirp_model.json", "--plot", "chirp_fit.png",
         "opt_played/command.h5")  # fmt: skip

FOUND: dict[str, tuple[tuple[str, ...], str]] = {
    # issue 44: now refused before the FFT, as the file does not repeat with that period
    "chirp fit of a stage command (a period with a zero bin)": (CHIRP, "repeats every"),
    # issue 44: refused while parsed, by the [pattern] keys' ranges (NANO without the option)
    "pattern of 2**31 circles": (
        (*_but(NANO, "--circles"), "--circles", "2147483648"),
        "2147483648 circles is outside the allowed range [1, 100]",
    ),
    "pattern of 1e30 circles": (
        (*_but(NANO, "--circles"), "--circles", "1" + "0" * 30),
        "'--circles': 1" + "0" * 30 + " circles is outside the allowed range",
    ),
    "pattern with 1e12 s moves": (
        (*_but(NANO, "--move-s"), "--move-s", "1e12"),
        "1e+12 s is outside the allowed range (0, 60] s",
    ),
    "stage-1 points 2**31": (
        (*_but(OPT, "--n"), "--n", "2147483648"),
        "2147483648 is outside the allowed range",
    ),
    "a_max 1e-12": ((*OPT, "--amax", "1e-12"), "'--amax': 1e-12 m/s² is outside"),
    "tolerance 5e-324": ((*OPT, "--tolerance", "5e-324"), "'--tolerance': 4.94066e-324 m is"),
    "inverse shaper of 1e30 poles": (
        (
            "shaper",
            "design",
            "model.json",
            "--kind",
            "inverse",
            "--out",
            "d.json",
            "--order",
            "1" + "0" * 30,
        ),
        "'--order': 1" + "0" * 30 + " is outside the allowed range [1, 16]",
    ),
    "settling band 1e-12 %": (
        ("shaper", "compare", "--json", "c.json", "--band-pct", "1e-12"),
        "has not settled",
    ),
    "a_max 1e-308": ((*TRAJ, "--amax", "1e-308"), "'--amax': 1e-308 m/s² is outside"),
    "jerk 1e308": ((*TRAJ, "--jmax", "1e308"), "'--jmax': 1e+308 m/s³ is outside"),
    "1e30 slm workers": ((*SLM, "--workers", "1" + "0" * 30), "--workers"),
    "sweep scheduler ' '": ((*SWEEP, "--scheduler", " "), "not a Dask scheduler address"),
    "sweep scheduler '10:1'": ((*SWEEP, "--scheduler", "10:1"), "no Dask scheduler answered"),
    "sweep scheduler '-5:-1'": ((*SWEEP, "--scheduler", "-5:-1"), "not a Dask scheduler"),
    "slm scheduler 'x=1e308'": ((*SLM, "--scheduler", "x=1e308"), "not a Dask scheduler"),
    "laser --job not TOML": ((*LASER, "--job", "chirp.csv"), "chirp.csv"),
    "laser --job of another kind": ((*LASER, "--job", "job.toml"), "not a laser"),
    "a text of a NUL byte as a drawing": (
        ("path", "show", "text:\x00", "--out", "part.png"),
        "not a printable character",
    ),
    "a polygon turned by an infinite angle (seed 1)": (
        ("path", "show", "polygon:n_sides=6,radius=0.01,theta0=Infinity", "--out", "p.png"),
        "finite",
    ),
    "a butterfly of scale 1e308 (seed 1)": (
        ("path", "show", "butterfly:scale=1e+308", "--out", "p.png"),
        "finite",
    ),
    # make fuzz, issue 44: a velocity limit far below --speed sized the reference from
    # --speed and planned 8e7 samples for minutes (a hang)
    "a cruise held to 1e-6 m/s": (
        (
            "trajectory",
            "square:side=0.01,corner_radius=0.002",
            "--speed",
            "0.05",
            "--vmax",
            "1e-06",
            "--rate",
            "2000",
            "--out",
            "ref.csv",
        ),
        "at 1.41421e-06 m/s and 2000 Hz takes more than",
    ),
    "droplet render of no liquid": (
        (
            "droplet",
            "render",
            "rendered",
            "--duration",
            "100",
            "--frame-interval",
            "25",
            "--concentration",
            "1e-12",
            # the Lagrangian solver stops early on this water-like jet and leaves no frame
            # with liquid; the default (Eulerian) model follows it out and renders it
            "--model",
            "lagrangian",
        ),
        "no liquid outside the nozzle",
    ),
}


# in-process a NumPy warning goes to pytest's log, not to the command's stderr where the
# fuzz driver sees it as a messy refusal: here it is an error, so it shows as one
@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("name", list(FOUND))
def test_found_case_is_refused_cleanly(name: str) -> None:
    argv, says = FOUND[name]
    out = run_case(Case(kind="found", argv=argv, setup=("workspace",), note=name))
    assert out.outcome == "refused", f"{out.outcome}: {out.detail}"
    assert says in out.detail, out.detail


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_drawing_flat_along_one_axis_is_drawn() -> None:
    """make fuzz, issue 44: a Lissajous curve 6e-236 m high gave matplotlib a singular
    transform (LinAlgError): the picture's spans are now at least 1 % of each other."""
    spec = "lissajous:ax=0.01,ay=5.931277608488788e-236,fx=3,fy=2,phase=1.5"
    argv = ("path", "show", spec, "--out", "part.png")
    out = run_case(Case(kind="found", argv=argv, note="flat lissajous"))
    assert out.outcome == "accepted", f"{out.outcome}: {out.detail}"


def test_a_calibration_refuses_a_property_table_it_could_not_update_before_running() -> None:
    out = run_case(
        Case(kind="found", argv=("droplet", "calibrate", "--model", "eulerian", "--write",
                                 "afile"), files=(("afile", b"kept?\n"),), setup=("workspace",))
    )  # fmt: skip
    assert out.outcome == "refused" and out.seconds < 5, out.detail


def test_a_baseline_model_of_absurd_coefficients_is_refused_without_warnings() -> None:
    """make fuzz --seed 2: a model with coefficients of 1e300 as the baseline of --frf
    was a LinAlgError traceback (and printed scipy's BadCoefficients first)."""
    model = b'{"num": [1e300], "den": [1.0, 1e300, 1e300, 1e300]}'
    argv = ("shaper", "design", "m.json", "--kind", "ei", "--frf", "frf.csv", "--out", "s.json")
    out = run_case(Case(kind="found", argv=argv, files=(("m.json", model),), setup=("workspace",)))
    assert out.outcome == "refused" and "no finite response" in out.detail, out.detail
