"""Shared fixtures: a tiny stage model for the optimisation tests (optimize, cli, experiments).

The "stage" is a per-axis second-order lag (70 and 60 rad/s) with a feedthrough, simulated
at 10 kHz; the networks (Fig. 5, h = 200) train for a few epochs on
its response to smooth random commands. They are poor models; the tests check the
optimisation's mechanics, not the seed's numbers.
"""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

FS = 10_000.0


def axis_model(wn: float, zeta: float, wz: float, d: float):
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[wn**2 - d * wn**2, wz - d * 2 * zeta * wn]])
    return a, b, c, np.array([[d]])


def stage_matrices(d: float = 0.9):
    mx, my = axis_model(70.0, 0.5, 40.0, d), axis_model(60.0, 0.6, 30.0, d)
    z2, z1 = np.zeros((2, 2)), np.zeros((2, 1))
    a = np.block([[mx[0], z2], [z2, my[0]]])
    b = np.block([[mx[1], z1], [z1, my[1]]])
    c = np.block([[mx[2], np.zeros((1, 2))], [np.zeros((1, 2)), my[2]]])
    return a, b, c, np.diag([d, d])


def smooth_run(n: int, seed: int, amplitude_m: float = 3e-3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    bb, aa = scipy.signal.butter(2, 4.0 / (FS / 2))
    u = np.cumsum(scipy.signal.lfilter(bb, aa, rng.standard_normal((n, 2)), axis=0), axis=0)
    u -= u[0]
    u *= amplitude_m / np.abs(u).max()
    ramp = np.clip(np.arange(n) / 2000.0, 0.0, 1.0)
    u *= (ramp**2 * (3 - 2 * ramp))[:, None]
    a, b, c, d = stage_matrices()
    sys = scipy.signal.StateSpace(a, b, c, d).to_discrete(1 / FS)
    _, y, _ = scipy.signal.dlsim(sys, u)
    return u, np.asarray(y)


@pytest.fixture(scope="session")
def tiny_models(tmp_path_factory):
    """A folder like a stage-identify output: linear_model.json and ann/model."""
    pytest.importorskip("torch")
    from microfab.identify.ann import AnnConfig
    from microfab.identify.ann_data import WindowSpec
    from microfab.identify.ann_train import train_ann
    from microfab.identify.stage_ann import save_ann_model
    from microfab.identify.stage_data import StageLinearModel, write_stage_model
    from microfab.identify.subspace_model import SubspaceModel

    d = tmp_path_factory.mktemp("models")
    train = [smooth_run(12_000, s) for s in range(3)]
    val = [smooth_run(8_000, 10)]
    # unwhitened (the training before issue 46): the optimiser tests were written on these
    # networks. Measured with the default whitening (1e-3) instead: as accurate (validation
    # σ 9.7 / 23.3 against 10.6 / 22.1 µm), but stage 2 on the easy circle of
    # tests/optimize/test_stage2.py stops after 14 iterations "not converged" with every
    # hard constraint holding (its score not improving); converged at 1e-2 and unwhitened.
    cfg = AnnConfig(window=WindowSpec(), batch_size=512, offsets=(0, 7, 13),
                    learning_rate=2e-3, max_epochs=4, device="cpu", threads=1,
                    whiten=None)  # fmt: skip
    model = train_ann(train, val, cfg)
    save_ann_model(model, d / "ann" / "model")
    a, b, c, dd = stage_matrices()
    dsys = scipy.signal.StateSpace(a, b, c, dd).to_discrete(1e-3)
    sub = SubspaceModel(a=dsys.A, b=dsys.B, c=dsys.C, d=dsys.D, dt=1e-3, x0=np.zeros((1, 4)),
                        singular_values=np.ones(4), block_rows=10, weighting="n4sid",
                        fit_mean=np.zeros(4), fit_std=np.ones(4))  # fmt: skip
    write_stage_model(d / "linear_model.json",
                      StageLinearModel(model=sub, input_dt=1e-4, decimate=10))  # fmt: skip
    return d, model


@pytest.fixture(scope="session")
def tiny_feature_model():
    """Tiny networks with the position features (`microfab.identify.ann_data`)."""
    pytest.importorskip("torch")
    from microfab.identify.ann import AnnConfig
    from microfab.identify.ann_data import WindowSpec
    from microfab.identify.ann_train import train_ann

    train = [smooth_run(12_000, s) for s in range(3)]
    val = [smooth_run(8_000, 10)]
    cfg = AnnConfig(window=WindowSpec(features="position"), batch_size=512, offsets=(0, 7),
                    learning_rate=2e-3, max_epochs=2, device="cpu", threads=1)  # fmt: skip
    return train_ann(train, val, cfg)


# --- report pages in a real browser (issue 32) -------------------------------------------

BROWSER = next(
    (b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None
)

# Added to a copy of the page only: counts the images that decoded.
_PROBE = """<script>
window.addEventListener("load", () => {
  const imgs = [...document.images];
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
  document.body.setAttribute("data-images", ok + "/" + imgs.length);
});
</script>"""


def check_page_in_browser(page: Path) -> None:
    """Open a written report page in headless Chromium and check what a reader sees.

    Every image decodes, the console stays silent, and a table puts the seed's numbers
    beside ours (a table that mentions the seed).
    """
    html = page.read_text(encoding="utf-8")
    tables = re.findall(r"<table.*?</table>", html, flags=re.S | re.I)
    assert any("seed" in t.lower() for t in tables), f"{page}: no table with the seed's numbers"
    probe = page.with_name(f".probe-{page.name}")
    probe.write_text(html + _PROBE, encoding="utf-8")
    try:
        res = subprocess.run(
            [str(BROWSER), "--headless=new", "--no-sandbox", "--disable-gpu",
             "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", "--dump-dom",
             probe.as_uri()],
            capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
    finally:
        probe.unlink()
    assert res.returncode == 0, res.stderr[-2000:]
    found = re.findall(r'data-images="(\d+)/(\d+)"', res.stdout)
    assert found and found[0][0] == found[0][1] and int(found[0][1]) > 0, (page, found)
    console = [ln for ln in res.stderr.splitlines() if ":CONSOLE" in ln]
    assert console == [], console


@pytest.fixture
def page_check():
    """`check_page_in_browser`, or ``None`` where no browser is installed."""
    return None if BROWSER is None else check_page_in_browser


@pytest.fixture(autouse=True)
def _python_sigint_handler():
    """Every test starts with Python's own SIGINT handler.

    A command interrupted in-process (CliRunner) leaves `print_interrupted`'s do-nothing
    handler behind on purpose (a second Ctrl-C must not cut its shutdown); in a test
    process that would swallow the next test's SIGINT.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
