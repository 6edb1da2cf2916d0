"""The seed 000 report in a real headless browser: it loads, every figure renders, a table
puts the seed beside ours, and the console stays silent. Skipped where no Chromium is
installed (Debian: `apt install chromium`; `.ci/run` installs it). The other kinds' pages
are opened the same way by tests/cli/test_run_store.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from microfab.experiments.seed000_msl.job import tables_from_runs
from microfab.experiments.seed000_msl.report import FIGURE_FILES, write_report
from microfab.machines.galvo.ilc import beam_exposure, run_msl_ilc
from microfab.machines.galvo.machine import calibrated_axes, open_loop


def test_report_renders_in_headless_chromium(tmp_path: Path, page_check) -> None:
    if page_check is None:
        pytest.skip("no Chromium on this machine (apt install chromium)")
    run = run_msl_ilc(400, 3)
    axes = calibrated_axes()
    page = write_report(
        tmp_path,
        {400: run},
        main_rate=400,
        tables=tables_from_runs({400: run}, axes),
        exposure=beam_exposure(run),
        open_loops={n: open_loop(a) for n, a in axes.items()},
    )
    assert page.read_text(encoding="utf-8").count("<img") == len(FIGURE_FILES)
    page_check(page)
