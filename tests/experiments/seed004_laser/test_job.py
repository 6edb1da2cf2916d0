"""The laser-micromachining job: defaults, example, refusals, run, resume, report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.core.limits import LimitViolation
from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS, load_job
from microfab.experiments.kinds import no_progress
from microfab.experiments.seed004_laser.job import LaserJob
from microfab.io.job import JobFileError
from microfab.machines.laser_stage.machine import ContourJob
from microfab.trajectory.contour_laps import ContourMotion

EXAMPLE = Path(__file__).parents[3] / "examples" / "laser_micromachining.toml"


def _job(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "job.toml"
    p.write_text('[job]\nkind = "laser-micromachining"\n' + body, encoding="utf-8")
    return p


def test_registered_with_its_reproduction():
    assert "laser-micromachining" in JOB_KINDS
    assert "laser-micromachining" in REPRODUCTIONS


def test_example_and_empty_sections_are_the_defaults(tmp_path):
    cfg = load_job(EXAMPLE).config
    assert isinstance(cfg, LaserJob)
    # the library's default profile is the seed's constant speed; a job's is auto
    assert cfg.run == ContourJob(motion=ContourMotion(profile="auto"))
    assert load_job(_job(tmp_path, "")).config == cfg


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("[control]\nspeed = 1\n", r"unknown key"),
        ("[focusing]\n", r"unknown section"),
        ('[control]\nlaw = "fuzzy"\n', r"law = .fuzzy.: expected one of preview-dob, contour"),
        ("[control]\nbandwidth_hz = 0.0\n", r"bandwidth_hz"),
        ("[control]\ndob_bandwidth_hz = 6000.0\n", r"Nyquist"),
        ('[drawing]\nsource = "circle:radius=1e-4"\ncontour = 2\n', r"contour = 2"),
        ("[trajectory]\nspeed_mm_s = 0.0\n", r"speed_m_s"),
        ('[drawing]\nsource = "circle:radius=2e-3"\n[trajectory]\nspeed_mm_s = 99.0\n'
         'profile = "constant"\n', r"axis [xy]: (acceleration|RMS force|force)"),
        ("[sweep]\nspeeds_mm_s = [0.0]\n", r"speeds_mm_s"),
        ("[focus]\nduration_s = 0.5\n", r"focus duration_s must exceed 1 s"),
        ("[focus]\npart_speed_mm_s = 0.0\n", r"part_speed_mm_s must be positive"),
        ("[focus]\nrun = 1\n", r"run"),
    ],
)  # fmt: skip
def test_bad_input_is_refused(tmp_path, body, match):
    with pytest.raises((ValueError, JobFileError, LimitViolation), match=match):
        load_job(_job(tmp_path, body))


def test_cli_refuses_a_reference_beyond_table_one_and_writes_nothing(tmp_path):
    out = tmp_path / "out"
    p = tmp_path / "job.toml"
    p.write_text(
        f'[job]\nkind = "laser-micromachining"\nout = "{out.as_posix()}"\n'
        '[drawing]\nsource = "circle:radius=2e-3"\n[trajectory]\nspeed_mm_s = 99.0\n'
        'profile = "constant"\n',  # the seed's set-up; auto would slow down instead
        encoding="utf-8",
    )
    res = CliRunner().invoke(app, ["run", str(p)])
    assert res.exit_code == 2, res.output
    assert res.output.startswith("error:") and "axis x" in res.output and "3 N" in res.output
    assert not out.exists()


def test_a_job_runs_resumes_its_sweep_and_writes_its_report(tmp_path):
    kind = JOB_KINDS["laser-micromachining"]
    cfg = load_job(_job(tmp_path, "[trajectory]\nlaps = 2\n[sweep]\nspeeds_mm_s = [0.5]\n")).config
    out = tmp_path / "out"
    first = kind.run(cfg, out, no_progress)
    assert len(first.sweep) == 2 and not first.failures()  # both laws at 0.5 mm/s
    assert first.baseline is not None
    points = sorted((out / "sweep" / "points").iterdir())
    stamps = [p.stat().st_mtime_ns for p in points]
    again = kind.run(cfg, out, no_progress)
    assert [p.stat().st_mtime_ns for p in sorted((out / "sweep" / "points").iterdir())] == stamps
    assert again.sweep == first.sweep
    report = kind.write_report(again, out, "laser")
    assert report.exists() and (out / "ballbar.png").exists()
    assert (out / "focus.png").exists() and (out / "disturbance.png").exists()
    assert "Autofocus" in report.read_text(encoding="utf-8")
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    # the autofocus against the project's targets, stated (measured 5.90 µm, 1.53x: not met)
    assert summary["focus_targets"]["ptp_met"] == (summary["focus_targets"]["ptp_um"] <= 5.0)
    g = summary["focus_targets"]
    assert ("NOT met" in report.read_text(encoding="utf-8")) == (
        not (g["ptp_met"] and g["ratio_met"])
    )
    # a circle at its speed: no slow-down, no acceleration lowered
    assert summary["slowdowns"] == [] and summary["acceleration_lowered"] is None


def test_reproduction_prints_the_seed_beside_ours():
    rep = REPRODUCTIONS["laser-micromachining"]
    # the Fig. 7 speed study (20 s) is tested in tests/experiments/seed004_laser/test_fig7.py
    res = rep.run(rep.parse_options({"speed_study": False}), no_progress)
    d = res.data
    assert d is not None
    # every row labelled; the Fig. 3 peak and the share within 0.5 µm are fitted (jointly,
    # calibrate laser), Fig. 7 predicted
    main = res.tables[0]
    origin = {row[0]: lab.origin for row, lab in zip(main.rows, main.labels, strict=True)}
    assert origin["Fig. 3 peak, x / y [µm]"] == "fitted"
    from microfab.machines.laser_stage.calibration import CALIBRATION

    fitted = {q for lab in main.labels for q in lab.fitted}
    assert fitted == set(CALIBRATION.targets)  # every target shown, and labelled fitted
    assert origin["Fig. 3 within ±0.5 µm, x / y [%]"] == "fitted"
    assert all(len(t.labels) == len(t.rows) for t in res.tables)
    assert abs(d["depth_of_focus_um"] - 54.0) <= 0.05 * 54.0
    for v in d["fig7_nm"].values():
        assert v["preview-dob"] >= 2.0 * v["contour"]
    # Fig. 7 on the paper's model (its direction: tests/experiments/seed004_laser/test_fig7.py)
    assert [r["speed_mm_s"] for r in d["fig7_paper_model"]] == [0.5, 1.0, 2.0, 5.0, 10.0, 20.0]
    assert origin[next(k for k in origin if k.startswith("Fig. 7 on the paper's model"))] == (
        "predicted"
    )
    assert d["focus_targets"]["ptp_max_um"] == 5.0 and "ratio_met" in d["focus_targets"]


def test_a_one_lap_job_without_sweep_writes_its_report(tmp_path):
    kind = JOB_KINDS["laser-micromachining"]
    body = "[trajectory]\nlaps = 1\n[sweep]\nspeeds_mm_s = []\n[focus]\nrun = false\n"
    cfg = load_job(_job(tmp_path, body)).config
    out = tmp_path / "out"
    res = kind.run(cfg, out, no_progress)
    assert res.sweep == () and res.focus is None
    assert kind.write_report(res, out, "one lap").exists()
    assert not (out / "focus.png").exists()


def test_a_sharp_star_runs_at_20_mm_s_through_microfab_run(tmp_path: Path) -> None:
    """Issue 33 item 3: a 3 mm five-point star (no fillets) at 20 mm/s cruise, planned
    with the limited profile, runs with no limit refused, reports its contour error and
    where it slowed; at constant speed the same job is refused on the acceleration; the
    default profile (auto) takes the limited one."""
    import json

    from typer.testing import CliRunner

    from microfab.cli import app

    job = tmp_path / "star.toml"
    body = (
        '[job]\nkind = "laser-micromachining"\n[drawing]\nsource = '
        '"star:points=5,radius=1.5e-3"\n[trajectory]\nspeed_mm_s = 20.0\nlaps = 2\n'
        "{profile}[control]\ncompare = false\n[sweep]\nspeeds_mm_s = []\n[focus]\nrun = false\n"
    )
    job.write_text(body.format(profile='profile = "limited"\n'))
    res = CliRunner().invoke(app, ["run", str(job), "--out", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output
    assert "Slowed below 90 % of 20 mm/s" in res.output
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["profile"] == "limited" and len(summary["slowdowns"]) == 10
    # each of the star's ten corners named, once (issue 45), and the force check stated
    assert [r["corners"] for r in summary["slowdowns"]] == [[k] for k in range(1, 11)]
    assert summary["corners"] == 10 and "acceleration_lowered" in summary
    assert "corner 1, start from rest" in res.output
    assert 0 < max(summary["contour_lap_max_nm"]) < 3000  # measured 1437 nm
    job.write_text(body.format(profile='profile = "constant"\n'))
    res = CliRunner().invoke(app, ["run", str(job), "--out", str(tmp_path / "c")])
    assert res.exit_code == 2 and "acceleration" in res.output, res.output
    # the default, auto: the constant reference breaks the limits, so the laps are limited
    job.write_text(body.format(profile=""))
    res = CliRunner().invoke(app, ["run", str(job), "--out", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    auto = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert auto["profile"] == "limited" and auto["slowdowns"] == summary["slowdowns"]


SWEEP_EXAMPLE = EXAMPLE.with_name("laser_speed_sweep.toml")


def test_the_example_sets_its_preview_dob_run_beside_fig3_as_the_reproduction_does():
    """Issue 33 item 4/C: the example's main run is the contour law (0.22 µm peak, 100 %
    within ±0.5 µm: not the seed's Fig. 3 set-up); its Fig. 3 row is the uncorrected
    preview + DOB run, which is the reproduction's run (`FIG3_JOB`) to the bit."""
    import dataclasses

    from microfab.experiments.seed004_laser.results import (
        FIG3_JOB,
        LaserResult,
        seed_fig3_setup,
    )
    from microfab.machines.laser_stage.contour import run_contour
    from microfab.machines.laser_stage.machine import ControlSettings

    cfg = load_job(EXAMPLE).config
    assert not seed_fig3_setup(cfg.run)  # the contour law
    base_job = cfg.run.with_(control=dataclasses.replace(cfg.run.control, law="preview-dob"))
    assert seed_fig3_setup(base_job)
    main, base = run_contour(cfg.run), run_contour(base_job)
    ref = run_contour(FIG3_JOB)
    res = LaserResult(config=cfg, main=main, baseline=base, sweep=())
    assert res.fig3_run() is base
    assert list(base.axis.peak_m) == list(ref.axis.peak_m)
    table = res.axis_table()
    assert "seed 004" in table.title and "preview-dob" in table.title
    assert f"{ref.axis.peak_m[1] * 1e6:.2f}" in str(table.rows)
    summary = res.summary()["fig3"]
    assert summary["peak_um"] == [v * 1e6 for v in ref.axis.peak_m]
    # without the comparison run, the contour run is not set beside Fig. 3
    alone = LaserResult(config=cfg, main=main, baseline=None, sweep=())
    assert alone.fig3_run() is None and alone.summary()["fig3"] is None
    assert "ours / seed" not in alone.axis_table().columns
    assert "0.8" not in str(alone.axis_table().rows)
    # a noise seed still is the seed's set-up; another speed or controller gain is not
    assert seed_fig3_setup(FIG3_JOB.with_(twin=dataclasses.replace(FIG3_JOB.twin, seed=3)))
    slow = FIG3_JOB.with_(motion=dataclasses.replace(FIG3_JOB.motion, speed_m_s=2e-3))
    assert not seed_fig3_setup(slow)
    assert not seed_fig3_setup(
        FIG3_JOB.with_(control=ControlSettings(law="preview-dob", bandwidth_hz=40.0))
    )


def test_the_speed_sweep_example_is_not_set_beside_the_seeds_30_um_figures():
    from microfab.experiments.seed004_laser.results import seed_fig3_setup

    cfg = load_job(SWEEP_EXAMPLE).config
    assert cfg.run.drawing == "circle:radius=5e-3"
    assert not seed_fig3_setup(cfg.run)
    assert not seed_fig3_setup(cfg.run.with_(control=ContourJob().control.__class__(
        law="preview-dob")))  # fmt: skip


def test_friction_feedforward_is_a_job_setting(tmp_path):
    cfg = load_job(_job(tmp_path, "[control]\nfriction_ff = true\n")).config
    assert cfg.run.control.friction_ff
    assert not load_job(EXAMPLE).config.run.control.friction_ff  # the seed's eqs. 3-4


def test_the_fig7_study_table_and_note_read_the_studys_rows():
    from microfab.experiments.seed004_laser.fig7 import fig7_study
    from microfab.experiments.seed004_laser.job import _study_note
    from microfab.report.contour_fig7 import fig7_study_table

    rows = fig7_study(["circle:radius=1e-4"], [1.0, 10.0, 20.0])
    table = fig7_study_table(rows)
    assert table.columns[2:] == ("1 mm/s", "10 mm/s", "20 mm/s", "ours is")
    assert all(lab.origin == "predicted" for lab in table.labels)
    assert [r[1] for r in table.rows] == ["friction on", "friction on, feedforward", "friction off"]
    # the cells and the note are the study's rows as printed (not recomputed)
    first = next(r for r in rows if r["friction"] and not r["friction_ff"])
    cell = f"{first['without_nm']:.0f} / {first['with_nm']:.0f}"
    assert table.rows[0][2].startswith(cell) and table.rows[0][4] == "refused (Table I)"
    low = [r for r in rows if r["speed_mm_s"] <= 2.0 and r.get("with_nm") is not None]
    on = max(
        abs(r["without_nm"] - r["with_nm"]) for r in low if r["friction"] and not r["friction_ff"]
    )
    off = max(abs(r["without_nm"] - r["with_nm"]) for r in low if not r["friction"])
    note = _study_note(rows)
    assert f"up to {on:.0f} nm on the calibrated twin" in note
    assert f"{off:.0f} nm with the friction off" in note
