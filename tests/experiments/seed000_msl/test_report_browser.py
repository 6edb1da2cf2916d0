"""The seed 000 report in a real headless browser: it loads, every figure renders, and the
console stays silent. Skipped where no Chromium is installed (Debian: `apt install
chromium`)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from microfab.experiments.seed000_msl.job import tables_from_runs
from microfab.experiments.seed000_msl.report import FIGURE_FILES, write_report
from microfab.machines.galvo import calibrated_axes, open_loop
from microfab.machines.galvo_ilc import beam_exposure, run_msl_ilc

BROWSER = next(
    (b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None
)

# Added to a copy of the page only: counts the images that decoded, and keeps errors.
PROBE = """<script>
window.addEventListener("load", () => {
  const imgs = [...document.images];
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
  document.body.setAttribute("data-images", ok + "/" + imgs.length);
});
</script>"""


@pytest.mark.skipif(BROWSER is None, reason="no Chromium on this machine (apt install chromium)")
def test_report_renders_in_headless_chromium(tmp_path: Path) -> None:
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
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text(encoding="utf-8") + PROBE, encoding="utf-8")
    res = subprocess.run(
        [
            str(BROWSER),
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
            "--dump-dom",
            probe.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    n = len(FIGURE_FILES)
    assert f'data-images="{n}/{n}"' in res.stdout, re.findall(r'data-images="[^"]*"', res.stdout)
    console = [ln for ln in res.stderr.splitlines() if ":CONSOLE" in ln]
    assert console == [], console
