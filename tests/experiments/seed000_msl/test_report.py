from __future__ import annotations

import html

import pytest

from microfab.experiments.seed000_msl import figures
from microfab.experiments.seed000_msl import paper as seed000
from microfab.experiments.seed000_msl.report import FIGURE_FILES, fmt_mm_s, fmt_mv, write_report
from microfab.machines.galvo.ilc import beam_exposure, run_msl_ilc
from microfab.machines.galvo.machine import calibrated_axes, open_loop
from microfab.report import galvo_ilc

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def result():
    return run_msl_ilc(400, 4)


@pytest.fixture(scope="module")
def tables(result):
    return {
        "table1": {a: {"400": result.table1_row(a)} for a in result.axes},
        "table2": {"400": result.velocity_stats()},
        "margins": {"x": {"gm_db": 20.0, "pm_deg": 47.0}, "y": {"gm_db": 17.0, "pm_deg": 46.0}},
    }


@pytest.fixture(scope="module")
def drawn(result, tables):
    """What the job computes for the page besides the runs (the report only draws)."""
    return {
        "tables": tables,
        "exposure": beam_exposure(result),
        "open_loops": {n: open_loop(a) for n, a in calibrated_axes().items()},
    }


@pytest.fixture(scope="module")
def report(result, drawn, tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "out"
    path = write_report(
        out,
        {400.0: result},
        main_rate=400,
        **drawn,
        title="Seed <000> report",
        notes=["first note", "a <b>bold</b> & raw note"],
    )
    return path, path.read_text(encoding="utf-8")


def test_report_written_with_all_pngs(report):
    path, text = report
    assert path.name == "report.html" and path.is_file()
    assert text.startswith("<!DOCTYPE html>")
    for name in FIGURE_FILES:
        assert f'src="{name}"' in text
        data = (path.parent / name).read_bytes()
        assert data.startswith(PNG_SIGNATURE)
        assert len(data) > 5000
        svg = name.replace(".png", ".svg")
        assert f'href="{svg}"' in text
        assert (path.parent / svg).read_bytes().lstrip().startswith(b"<?xml")
    assert "http://" not in text and "https://" not in text  # no external resources
    assert "Why the gain margins differ" in text or "margins" not in text


def test_captions_name_seed_figures(report):
    _, text = report
    for fig in ("Fig. 4a", "Fig. 4b", "Fig. 5", "Fig. 6", "Fig. 7", "Fig. 8"):
        assert f"seed 000 {fig}" in text


def test_table1_and_table2_numbers(report, result):
    _, text = report
    for axis in result.axes:
        for value in result.table1_row(axis).values():
            assert f">{fmt_mv(value)}<" in text
    for value in result.velocity_stats().values():
        assert f">{fmt_mm_s(value)}<" in text


def test_seed_values_and_ratios(report, result):
    _, text = report
    ours = result.table1_row("x")["fb_rms"]
    seed = seed000.TABLE1_MV["x"][400]["fb_rms"]
    assert f">{fmt_mv(seed)}<" in text
    assert f">{ours / seed:.2f}<" in text
    assert f">{fmt_mm_s(seed000.TABLE2_MM_S[400]['ilc_std'])}<" in text
    assert ">68.5<" in text  # seed gain margin, x
    assert "ours/seed" in text


def test_text_is_escaped(report):
    _, text = report
    assert "<title>Seed &lt;000&gt; report</title>" in text
    assert "<li>a &lt;b&gt;bold&lt;/b&gt; &amp; raw note</li>" in text
    assert "<li>first note</li>" in text
    assert "<b>bold</b>" not in text
    assert html.escape("<000>") in text


def test_without_notes_no_notes_section(result, drawn, tmp_path, monkeypatch):
    # Figures are not under test here: substitute a cheap one to keep this fast.
    from matplotlib.figure import Figure

    def tiny(*args, **kwargs):
        fig = Figure(figsize=(1, 1))
        fig.add_subplot().plot([0, 1])
        return fig

    for module, name in (
        (galvo_ilc, "fig_xy"),
        (galvo_ilc, "fig_time"),
        (galvo_ilc, "fig_psd"),
        (galvo_ilc, "fig_learning"),
        (figures, "fig_velocity"),
        (figures, "fig_line_width"),
    ):
        monkeypatch.setattr(module, name, tiny)
    path = write_report(tmp_path, {400: result}, main_rate=400.0, **drawn)
    text = path.read_text(encoding="utf-8")
    assert "<h2>Notes</h2>" not in text
    assert f">{fmt_mv(result.table1_row('y')['ilc_pp'])}<" in text


def test_figure_failure_leaves_no_report(result, drawn, tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("simulated figure failure")

    monkeypatch.setattr(galvo_ilc, "fig_psd", boom)
    out = tmp_path / "fresh"
    with pytest.raises(RuntimeError, match="simulated figure failure"):
        write_report(out, {400.0: result}, main_rate=400, **drawn)
    assert not (out / "report.html").exists()
    assert not out.exists() or list(out.iterdir()) == []  # nothing half-written


def test_figure_failure_keeps_previous_report(result, drawn, tmp_path, monkeypatch):
    old = tmp_path / "report.html"
    old.write_text("old report", encoding="utf-8")

    def boom(*args, **kwargs):
        raise RuntimeError("simulated figure failure")

    monkeypatch.setattr(galvo_ilc, "fig_xy", boom)
    with pytest.raises(RuntimeError):
        write_report(tmp_path, {400.0: result}, main_rate=400, **drawn)
    assert old.read_text(encoding="utf-8") == "old report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]


def test_bad_main_rate(result, drawn, tmp_path):
    with pytest.raises(ValueError, match="main_rate"):
        write_report(tmp_path, {400.0: result}, main_rate=200, **drawn)
    with pytest.raises(ValueError):
        write_report(tmp_path, {}, main_rate=400, **drawn)
    assert not (tmp_path / "report.html").exists()
