"""``microfab path show`` and ``microfab trajectory`` through typer's CliRunner."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.trace import read_columns

runner = CliRunner()


def test_path_show_json_summary_and_png(tmp_path: Path) -> None:
    png = tmp_path / "sq.png"
    res = runner.invoke(app, ["path", "show", "square:side=0.02", "--json", "--out", str(png)])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    (c,) = data["contours"]
    assert c["closed"] is True
    assert c["length_m"] == pytest.approx(0.08)
    assert c["bbox_m"] == pytest.approx([-0.01, -0.01, 0.01, 0.01], abs=1e-9)
    assert c["n_points"] >= 5
    assert data["skipped"] == []
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_path_show_text_and_errors(tmp_path: Path) -> None:
    res = runner.invoke(app, ["path", "show", "blob:radius=1", "--out", str(tmp_path / "x.png")])
    assert res.exit_code == 2 and "cannot tell what" in res.output
    res = runner.invoke(app, ["path", "show", str(tmp_path / "missing.dxf")])
    assert res.exit_code == 2 and "not found" in res.output


def test_trajectory_time_optimal_writes_a_limit_safe_reference(tmp_path: Path) -> None:
    out = tmp_path / "ref.csv"
    res = runner.invoke(
        app,
        [
            "trajectory",
            "square:side=0.01",
            "--time-optimal",
            "--amax",
            "5",
            "--vmax",
            "0.2",
            "--out",
            str(out),
            "--rate",
            "5000",
        ],
    )
    assert res.exit_code == 0, res.output
    cols = read_columns(out)
    x, y = cols["x"], cols["y"]
    dt = np.diff(cols["time"]).mean()
    v = np.diff(np.column_stack([x, y]), axis=0) / dt
    a = np.diff(np.column_stack([x, y]), 2, axis=0) / dt**2
    assert np.abs(v).max() <= 0.2 * (1 + 1e-9)
    assert np.abs(a).max() <= 5 * (1 + 1e-9)
    assert np.abs(v).max() > 0.15  # the limit is actually used somewhere
    assert set(np.unique(cols["laser"])) <= {0.0, 1.0}
    assert (tmp_path / "ref_profile.png").exists()


def test_trajectory_at_speed_runs_within_the_limits(tmp_path: Path) -> None:
    """--speed ramps from and to rest and stops at the square's corners: no refusal."""
    out = tmp_path / "ref.csv"
    res = runner.invoke(
        app, ["trajectory", "square:side=0.01", "--speed", "0.1", "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "4 corner stops" in res.output
    cols = read_columns(out)
    assert cols["v_x"][0] == 0.0 and cols["v_x"][-1] == 0.0
    # a jerk limit is not planned for by --speed: refused, pointing to --time-optimal
    out2 = tmp_path / "ref2.csv"
    res = runner.invoke(
        app,
        ["trajectory", "square:side=0.01", "--speed", "0.1", "--jmax", "10", "--out", str(out2)],
    )
    assert res.exit_code == 2
    assert "exceeds the limit" in res.output and "--time-optimal" in res.output
    assert not out2.exists()


def test_trajectory_time_optimal_refusal_does_not_advise_itself(tmp_path: Path) -> None:
    res = runner.invoke(
        app,
        ["trajectory", "circle:radius=0.01", "--time-optimal", "--workspace", "0.001"],
    )
    assert res.exit_code == 2
    assert "use --time-optimal" not in res.output.lower()


def test_trajectory_option_errors(tmp_path: Path) -> None:
    res = runner.invoke(app, ["trajectory", "circle:radius=0.01"])
    assert res.exit_code == 2 and "exactly one" in res.output
    res = runner.invoke(app, ["trajectory", "circle:radius=0.01", "--time-optimal", "--amax", "-1"])
    assert (
        res.exit_code == 2
        and "error: Invalid value for '--amax': -1 m/s² is outside the allowed range "
        "[1e-06, 1e+08] m/s²"
        in res.output
    )
    # issue 13: every hint names the option and its unit, never a Python name
    for opt, unit, bounds in (
        ("--speed", "m/s", "[1e-06, 1000]"),
        ("--vmax", "m/s", "[1e-06, 1000]"),
        ("--jmax", "m/s³", "[1e-06, 1e+13]"),
        ("--workspace", "m", "[1e-06, 10]"),
        ("--chord", "m", "[1e-06, 10]"),
        ("--text-height", "m", "[1e-06, 10]"),
    ):
        argv = ["trajectory", "airfoil:e344", opt, "-2"]  # refused while parsed
        res = runner.invoke(app, argv)
        says = f"'{opt}': -2 {unit} is outside the allowed range {bounds} {unit}"
        assert says in res.output, argv
    for opt, value in (("--amax", "1e9"), ("--jmax", "1e308"), ("--vmax", "5e-324")):
        res = runner.invoke(app, ["trajectory", "text:A", "--time-optimal", opt, value])
        assert res.exit_code == 2 and "is outside the allowed range" in res.output, opt
    dxf = str(tmp_path / "part.dxf")  # --units is a DXF file's
    res = runner.invoke(app, ["trajectory", dxf, "--speed", "0.01", "--units", "furlong"])
    assert (
        res.exit_code == 2
        and "error: Invalid value for '--units': 'furlong' is not one of m, cm, mm" in res.output
    )
    res = runner.invoke(app, ["trajectory", "text:A", "--speed", "0.01", "--feed", "0.1"])
    assert res.exit_code == 2 and "it caps the speed of --time-optimal" in res.output
    res = runner.invoke(
        app, ["trajectory", "circle:radius=0.01", "--time-optimal", "--contour", "3"]
    )
    assert res.exit_code == 2 and "out of range" in res.output


def test_piped_summary_lines_are_not_wrapped(tmp_path: Path) -> None:
    res = runner.invoke(
        app,
        [
            "path",
            "show",
            "rectangle:width=0.05,height=0.03,corner_radius=0.005",
            "--out",
            str(tmp_path / "p.png"),
        ],
    )
    assert res.exit_code == 0, res.output
    (row,) = [ln for ln in res.output.splitlines() if ln.startswith("#0")]
    assert len(row) > 80 and row.rstrip().endswith("segments"), res.output


def test_absurd_speed_is_held_within_the_limits(tmp_path: Path) -> None:
    # --speed only asks: the acceleration limit caps the speed in the curve
    out = tmp_path / "ref.csv"
    args = ["circle:radius=0.005", "--speed", "1e3", "--vmax", "1e3", "--out", str(out)]
    res = runner.invoke(app, ["trajectory", *args])
    assert res.exit_code == 0, res.output
    assert np.abs(read_columns(out)["v_x"]).max() < 1.0


@pytest.mark.parametrize(
    "argv, says",
    [
        (["circle:radius=0.5", "--speed", "1e-6", "--workspace", "1"], "a reference may hold"),
        (["text:ab", "--speed", "0.01", "--rate", "7.7e-258"], "allowed range [100, 1e+08] Hz"),
        (["circle:radius=0.5", "--speed", "0.01"], "outside the workspace"),
        (["circle:radius=0.01", "--speed", "0.01", "--workspace", "0"], "workspace"),
    ],
)
def test_trajectory_refuses_absurd_options_before_sampling(
    tmp_path: Path, argv: list[str], says: str
) -> None:
    out = tmp_path / "ref.csv"
    res = runner.invoke(app, ["trajectory", *argv, "--out", str(out)])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], res.output
    assert not out.exists()


def test_path_show_refuses_absurd_and_empty_drawings(tmp_path: Path) -> None:
    big = tmp_path / "big.svg"
    big.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg"><g transform="scale(1e308)">'
        '<path d="M 0 0 L 100 0 L 100 100 Z"/></g></svg>'
    )
    empty = tmp_path / "empty.svg"
    empty.write_text('<svg xmlns="http://www.w3.org/2000/svg"></svg>')
    for f, says in ((big, "beyond ±1000 m"), (empty, "no importable geometry")):
        png = tmp_path / "x.png"
        res = runner.invoke(app, ["path", "show", str(f), "--out", str(png)])
        assert res.exit_code == 2 and says in res.output, res.output
        assert not png.exists()


def test_path_show_of_a_dxf_cut_after_insunits_is_one_error_line(tmp_path: Path) -> None:
    import ezdxf

    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    doc.modelspace().add_lwpolyline([(0, 0), (10, 0), (10, 10)], close=True)
    full = tmp_path / "full.dxf"
    doc.saveas(full)
    data = full.read_bytes()
    cut = tmp_path / "trunc.dxf"
    cut.write_bytes(data[: data.index(b"$INSUNITS") + 12])
    res = runner.invoke(app, ["path", "show", str(cut), "--out", str(tmp_path / "t.png")])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "trunc.dxf: not a readable DXF file" in lines[0]


def test_path_show_lists_the_first_contours_and_counts_the_rest(tmp_path: Path) -> None:
    from microfab.cli.geometry import LISTED

    # 225 squares, every fourth (57) with a square hole in it
    body = "".join(
        f'<path d="M {3 * (i % 20)} {3 * (i // 20)} h 2 v 2 h -2 z"/>'
        + (
            f'<path d="M {3 * (i % 20) + 0.5} {3 * (i // 20) + 0.5} h 1 v 1 h -1 z"/>'
            if i % 4 == 0
            else ""
        )
        for i in range(225)
    )
    svg = tmp_path / "many.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="60mm" height="60mm" '
        f'viewBox="0 0 60 60">{body}</svg>'
    )
    png = tmp_path / "many.png"
    res = runner.invoke(app, ["path", "show", str(svg), "--out", str(png)])
    assert res.exit_code == 0, res.output
    rows = [ln for ln in res.stdout.splitlines() if ln.startswith("#")]
    assert (
        len(rows) == LISTED
        and rows[0].startswith("#0 outer closed")
        and rows[1].startswith("#1 hole")
    )
    (more,) = [ln for ln in res.stdout.splitlines() if ln.startswith("...")]
    assert more == (
        f"... and {282 - LISTED} more contours (of 282: 225 outer, 57 holes, 0 open); "
        "--json lists them all"
    )
    assert res.stdout.splitlines()[-1] == f"wrote {png}"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    res = runner.invoke(app, ["path", "show", str(svg), "--out", str(png), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert len(data["contours"]) == 282 and data["skipped"] == []
    assert all(c["closed"] and c["n_segments"] == 4 for c in data["contours"])
