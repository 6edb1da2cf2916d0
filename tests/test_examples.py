import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).parent.parent / "examples").glob("[0-9][0-9]_*.py"))
# quick arguments per example, and what its output must contain
QUICK = {
    "01_galvo_ilc.py": (["3"], ["iteration  3"], "example_01_xy.png"),
    "02_letters_time_optimal.py": (["150"], ["text:r", "airfoil:e344"], "example_02_profile.png"),
    "03_droplet_breakup.py": (
        ["0.15"],
        ["breakup", "measured from frames"],
        "example_03_frames.png",
    ),
}


def test_examples_exist():
    assert EXAMPLES
    assert {e.name for e in EXAMPLES} == set(QUICK)


@pytest.mark.parametrize("ex", EXAMPLES, ids=[e.name for e in EXAMPLES])
def test_examples_run_headless(ex, tmp_path, monkeypatch, capsys):
    args, expected, png_name = QUICK[ex.name]
    monkeypatch.setattr(sys, "argv", [str(ex), *args, str(tmp_path)])
    runpy.run_path(str(ex), run_name="__main__")
    out = capsys.readouterr().out
    for text in expected:
        assert text in out
    assert (tmp_path / png_name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --- default outputs never collide (issue 43) --------------------------------------------


def _default_outputs() -> list[tuple[str, Path, str | None]]:
    """Every default output folder: (who writes it, folder, job kind or None for a command).

    The jobs: the default job, each example job file, and a job file without ``out`` of
    each kind; the commands: every option of every command whose default is a folder or
    file under ``report/``, read from the CLI itself.
    """
    import click
    import typer

    from microfab.cli import app
    from microfab.experiments.catalog import KIND_ENTRIES, default_job
    from microfab.io.job import read_job

    found: list[tuple[str, Path, str | None]] = []
    job = default_job()
    found.append(("microfab run", job.out, job.kind.name))
    for path in sorted((Path(__file__).parent.parent / "examples").glob("*.toml")):
        head = read_job(path)  # the [job] header only (load_job also builds the config)
        assert head.out is not None, f"examples/{path.name} names no out"
        found.append((f"examples/{path.name}", head.out, head.kind or "msl-ilc"))
    for kind in KIND_ENTRIES:
        import tomllib

        from microfab.experiments.catalog import _job
        from microfab.io.job import parse_job

        bare = _job(parse_job(tomllib.loads(f'[job]\nkind = "{kind}"\n'), "bare.toml"))
        found.append((f"a {kind} job without out", bare.out, kind))

    def walk(cmd: click.Command, name: str) -> None:
        subs = getattr(cmd, "commands", None)  # a group (typer's own group classes too)
        if subs is not None:
            for sub, c in subs.items():
                walk(c, f"{name} {sub}")
            return
        for p in cmd.params:
            d = p.default
            if isinstance(d, str | Path) and Path(d).parts[:1] == ("report",):
                found.append((f"{name} --{p.name}", Path(d), None))

    walk(typer.main.get_command(app), "microfab")
    return found


def test_default_outputs_never_collide():
    """No two writers share a default folder or nest one in the other (issue 43).

    The run store refuses a folder that is not empty and holds no run.json, and a run of
    other settings: a default folder inside another, or shared by two commands, would
    make the second refuse. Only two jobs of the same kind may share one (the same job:
    it resumes, or names the setting that differs).
    """
    outs = _default_outputs()
    assert any(w == "microfab droplet simulate --out" for w, _, _ in outs), outs
    assert len([o for o in outs if o[2] is None]) >= 3, outs
    for i, (w1, p1, k1) in enumerate(outs):
        assert p1.parts[0] == "report" and len(p1.parts) >= 2, (w1, p1)
        for w2, p2, k2 in outs[i + 1 :]:
            if p1 == p2:
                assert k1 is not None and k1 == k2, f"{w1} and {w2} both write {p1}"
            else:
                assert p1 not in p2.parents and p2 not in p1.parents, (
                    f"{w1} writes {p1}, {w2} writes {p2}: one inside the other"
                )


def test_the_default_job_runs_after_the_droplet_commands(tmp_path, monkeypatch):
    """`make run` after `droplet simulate` and `droplet sweep` with their default outputs.

    Issue 43: `microfab run` refused ("report is not empty and holds no run.json") after
    `microfab droplet simulate` had written report/droplet. The commands run for real
    (short), the default job with 2 iterations at one rate; then every example job's
    folder is checked as its run would open it (`check_run`, the store's own refusal of
    a folder that is not empty and holds no run.json) and the droplet command runs again
    after the job.
    """
    from typer.testing import CliRunner

    import microfab.experiments.catalog as catalog
    from microfab.cli import app
    from microfab.io.job import read_job
    from microfab.io.runstore import check_run

    runner = CliRunner()
    monkeypatch.chdir(tmp_path)
    shipped = catalog.default_job()
    job = tmp_path / "default.toml"
    job.write_text(
        f'[job]\nkind = "msl-ilc"\nout = "{shipped.out.as_posix()}"\n'
        "[scan]\niterations = 2\nlearning_rates = [400]\n",
        encoding="utf-8",
    )
    monkeypatch.setattr(catalog, "default_job", lambda: catalog.load_job(job))
    simulate = ["droplet", "simulate", "--duration", "30"]
    for argv in (
        simulate,
        ["droplet", "sweep", "--concentrations", "1", "--voltages", "", "--duration", "30"],
        ["run"],
    ):
        res = runner.invoke(app, argv)
        assert res.exit_code == 0, (argv, res.output)
    assert (tmp_path / shipped.out / "report.html").is_file()
    assert (tmp_path / "report" / "droplet" / "simulate" / "droplet.json").is_file()
    for example in sorted((Path(__file__).parent.parent / "examples").glob("*.toml")):
        out = read_job(example).out
        if out != shipped.out:  # (the default job's own file is the same job)
            assert check_run(out, {"any": "settings"}) == "start", example.name
    res = runner.invoke(app, simulate)
    assert res.exit_code == 0, res.output
