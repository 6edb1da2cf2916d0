"""``microfab slm scan-time`` on the galvo twin (seed 003 part 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.control.shaper_io import read_shaper, shaper_lti
from microfab.plants.galvo_slm import galvo_slm_twin
from microfab.process.slm.estimate import estimate_scan_time, series
from microfab.process.slm.source import scan_program
from microfab.process.slm.timing import RTCSettings

runner = CliRunner()


@pytest.mark.parametrize("source", ["lattice:z=4e-4,radius=3e-3", "circle:radius=2e-3"])
def test_scan_time_with_and_without_a_shaper(model_file: Path, tmp_path: Path, source: str):
    shaper = tmp_path / "inv.json"
    res = runner.invoke(
        app,
        ["shaper", "design", str(model_file), "--discretization", "zpetc", "--out", str(shaper)],
    )
    assert res.exit_code == 0, res.output
    out = tmp_path / "scan.json"
    res = runner.invoke(
        app, ["slm", "scan-time", source, "--shaper", str(shaper), "--json", str(out)]
    )
    assert res.exit_code == 0, res.output
    for word in ("naive", "fixed delays", "dynamics-aware, shaped", "jump_delay", "total"):
        assert word in res.output
    got = json.loads(out.read_text())
    # the command adds nothing to the library's estimates
    path = scan_program(source)
    twin = galvo_slm_twin()
    want = estimate_scan_time(path, twin)
    shaped = estimate_scan_time(
        path,
        series(shaper_lti(read_shaper(shaper), 1e-5), twin.axis_model),
        RTCSettings().with_delays(jump_s=250e-6),  # the seed's jump delay with its shaper
    )
    for name, c in (("unshaped", want), ("shaped", shaped)):
        for e in (c.naive, c.fixed, c.dynamics):
            assert got[name][e.method]["total_s"] == pytest.approx(e.total_s, rel=1e-12)
            assert got[name][e.method]["breakdown_s"] == pytest.approx(e.breakdown_s, rel=1e-12)
    assert got["shaped"]["fixed delays"]["breakdown_s"]["jump_delay"] == pytest.approx(
        path.n_jumps * 250e-6
    )
    assert got["program"]["n_jumps"] == path.n_jumps > 0
    # the shaper shortens the dynamics-aware jump delays
    assert shaped.dynamics.breakdown_s["jump_delay"] < want.dynamics.breakdown_s["jump_delay"]


@pytest.mark.parametrize(
    "extra, says",
    [
        (["--jump-delay-us", "755"], "--jump-delay-us = 755 µs is not a whole number of 10 µs"),
        (["--mark-delay-us", "-10"], "--mark-delay-us"),
        (["SHAPER=model", "--shaped-jump-delay-us", "254"], "the nearest is 250 µs"),
        (["--mark-speed", "0"], "'--mark-speed': 0 m/s is outside the allowed range"),
        (["--jump-speed", "-5"], "'--jump-speed': -5 m/s is outside the allowed range"),
        (["--sky-writing", "4"], "'--sky-writing': 4 is outside the allowed range [0, 3]"),
        (["--tolerance-pct", "0"], "'--tolerance-pct': 0 % is outside the allowed range (0"),
        (["SOURCE=lattice:size=1"], "unknown lattice key 'size'; known: z, radius"),
        (["SOURCE=spiral"], "1 of its 1 contours are open: #0"),
        (["SOURCE=lattice:radius=0.1"], "outside the scanner's field"),
        # fuzz: each of these ran out of memory or for minutes instead of refusing
        (["--sky-writing", "1", "--sky-prev", "1000000000"], "range [0, 1000] ticks"),
        (["--sky-writing", "2", "--sky-post", "1001"], "'--sky-post': 1001 ticks is outside"),
        (["--hatch-um", "1e-3"], "'--hatch-um': 0.001 µm is outside the allowed range [1.5,"),
        (["SOURCE=lattice:radius=1e-3,hatch=1e-12"], "finer than one bit of the scanner"),
        (["SOURCE=lattice:radius=1e-3,strut=1e-9"], "strut=1e-09 m is finer than one bit"),
        (["SOURCE=lattice:radius=3e-3,strut=1e-5"], "strut nodes in the outline, more than 5000"),
        (["SOURCE=lattice:strut=1e308"], "strut_m = 1e+308 m is too large"),  # OverflowError
        (["SHAPER=model"], "this is a transfer-function model (JSON), not a shaper"),
        # issue 32: a ValueError and an OverflowError traceback before
        (["--mark-speed", "1e-300"], "'--mark-speed': 1e-300 m/s is outside the allowed"),
        (["--jump-speed", "1e308"], "'--jump-speed': 1e+308 m/s is outside"),
        (["SOURCE=lattice:z=1e308"], "lattice z = 1e+308 m is outside the build, 0 to 1 m"),
        (["SOURCE=lattice:z=-1e-3"], "lattice z = -0.001 m is outside the build"),
        (["SHAPER=deep"], "nested too deeply to be a shaper"),  # fuzz
        (["SHAPER=dt"], "designed for dt = 2e-05 s"),
    ],
)
def test_scan_time_refusals(
    model_file: Path, tmp_path: Path, one_error_line, extra: list[str], says: str
):
    source, argv = "circle:radius=2e-3", []
    for a in extra:
        if a.startswith("SOURCE="):
            source = a.split("=", 1)[1]
        elif a == "SHAPER=model":
            argv += ["--shaper", str(model_file)]
        elif a == "SHAPER=deep":
            (tmp_path / "deep.json").write_text('{"a":' * 100_000)
            argv += ["--shaper", str(tmp_path / "deep.json")]
        elif a == "SHAPER=dt":
            sh = tmp_path / "dt.json"
            r = runner.invoke(app, ["shaper", "design", str(model_file), "--dt", "2e-5",
                                    "--out", str(sh)])  # fmt: skip
            assert r.exit_code == 0, r.output
            argv += ["--shaper", str(sh)]
        else:
            argv.append(a)
    out = tmp_path / "scan.json"
    res = runner.invoke(app, ["slm", "scan-time", source, *argv, "--json", str(out)])
    one_error_line(res, says)
    assert not out.exists()


def test_build_command_gives_the_library_build(tmp_path: Path):
    from microfab.process.slm.build import BuildSettings, run_build

    out = tmp_path / "build.json"
    args = ["slm", "build", "--layers", "2", "--outline-radius-mm", "1.5", "--json", str(out),
            "--results-dir", str(tmp_path / "rows")]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "Whole build, 2 lattice layers" in res.output
    got = json.loads(out.read_text())
    want = run_build(BuildSettings(n_layers=2, outline_radius_m=1.5e-3))
    assert got["totals_s"] == pytest.approx(want.totals(), rel=1e-12)
    again = runner.invoke(app, args)  # resumed: both layers skipped
    assert again.exit_code == 0, again.output
    assert json.loads(out.read_text())["n_skipped"] == 2


@pytest.mark.parametrize(
    "extra, says",
    [
        (["--layers", "0"], "'--layers': 0 is outside the allowed range [1,"),
        (["--shaper", "ei"], "Invalid value for '--shaper': 'ei' is not one of none, zoh, zpetc"),
        (["--outline-radius-mm", "60"], "60 mm is outside the allowed range (0, 49.152] mm"),
        (["--jump-speed", "12"], "12 m/s is outside the allowed range [0.0001, 10] m/s"),
    ],
)
def test_build_command_refusals(extra: list[str], says: str):
    res = runner.invoke(app, ["slm", "build", *extra])
    assert res.exit_code == 2 and says in res.output, res.output
