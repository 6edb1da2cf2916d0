"""Per-axis neural networks of seed 002 (eq. 7, Fig. 5; issue 17 "Neural networks")."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys

import numpy as np
import pytest
import scipy.signal

torch = pytest.importorskip("torch")

from microfab.identify.ann import (  # noqa: E402
    FORMAT_VERSION,
    HIDDEN,
    AnnConfig,
    AnnModel,
    build_network,
    n_weights,
)
from microfab.identify.ann_data import (  # noqa: E402
    Scaling,
    WindowSet,
    WindowSpec,
    check_run,
    windows,
)
from microfab.identify.ann_train import CheckpointMismatchError, train_ann  # noqa: E402

FS = 10_000.0
TAU_S = 0.01  # time constant of the synthetic linear "stage" (assumed, short so h=20 covers it)


def synthetic_run(n: int, seed: int, *, amplitude_m: float = 2e-3):
    """A smooth random command from rest (x, y) and a first-order lag's response to it."""
    rng = np.random.default_rng(seed)
    b, a = scipy.signal.butter(2, 3.0 / (FS / 2))
    u = scipy.signal.lfilter(b, a, rng.standard_normal((n, 2)), axis=0)
    u = np.cumsum(u, axis=0)
    u -= u[0]
    u *= amplitude_m / np.abs(u).max()
    ramp = np.clip(np.arange(n) / 2000.0, 0.0, 1.0)  # leave rest smoothly
    u *= (ramp**2 * (3 - 2 * ramp))[:, None]
    k = 1.0 / (TAU_S * FS)
    y = scipy.signal.lfilter([k], [1.0, k - 1.0], u, axis=0)
    y[:, 1] = 0.7 * y[:, 1] + 0.3 * u[:, 1]  # y axis: a different linear map
    return u, y


SPEC = WindowSpec(h=20)
TRAIN = [synthetic_run(12_000, s) for s in range(3)]
VAL = [synthetic_run(8_000, 10)]


def small_config(**kw) -> AnnConfig:
    base = dict(
        window=SPEC,
        batch_size=512,
        offsets=(0, 7, 13),
        learning_rate=2e-3,
        max_epochs=3,
        device="cpu",
        threads=1,
    )
    base.update(kw)
    return AnnConfig(**base)


# --- network ---------------------------------------------------------------------------


def test_position_features_of_a_window():
    """sin/cos of 2π r_{i-k} / λ for each lag and wavelength, appended after the window."""
    from microfab.identify.ann_data import (
        FEATURE_LAGS,
        FEATURE_WAVELENGTHS_M,
        position_features,
    )

    spec = WindowSpec(features="position")
    assert spec.n_features == 2 * len(FEATURE_LAGS) * len(FEATURE_WAVELENGTHS_M) == 208
    assert spec.n_inputs == 200 + 208
    assert WindowSpec(features="position", inputs="both").n_inputs == 2 * 408
    assert n_weights(spec.n_inputs) == 117_322 + 208 * 200
    rng = np.random.default_rng(3)
    cmd = np.cumsum(rng.normal(size=(20_000, 2)) * 1e-5, axis=0)
    x, _, _ = windows(cmd, None, spec, axis=1, offset=4)
    plain, _, _ = windows(cmd, None, WindowSpec(), axis=1, offset=4)
    assert np.array_equal(x[:, :200], plain)
    i, k, j = 777, FEATURE_LAGS[3], 5
    r = cmd[4::25, 1][i - k]  # the window of target i ends at sample i - 1
    feats = x[i, 200:]
    assert np.array_equal(position_features(np.array([cmd[4::25, 1][i - 200 : i]]))[0], feats)
    n = len(FEATURE_WAVELENGTHS_M)
    lam = FEATURE_WAVELENGTHS_M[j]
    assert feats[3 * 2 * n + j] == pytest.approx(np.sin(2 * np.pi * r / lam), abs=1e-12)
    assert feats[3 * 2 * n + n + j] == pytest.approx(np.cos(2 * np.pi * r / lam), abs=1e-12)
    with pytest.raises(ValueError, match="features must be one of"):
        WindowSpec(features="fourier")
    with pytest.raises(ValueError, match="need a history h >= 16"):
        WindowSpec(features="position", h=8)


def test_weight_count_fig5():
    assert n_weights(200) == 117_322  # seed 002 Fig. 5
    net = build_network(200, seed=0)
    assert sum(p.numel() for p in net.parameters()) == 117_322
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    assert [m.out_features for m in linears] == [*HIDDEN, 1]
    assert all(m.bias is not None for m in linears)
    acts = [m for m in net if isinstance(m, torch.nn.LeakyReLU)]
    assert len(acts) == 8 and all(m.negative_slope == 0.01 for m in acts)
    assert WindowSpec(inputs="both").n_inputs == 400
    assert n_weights(400) == 117_322 + 200 * 200


def test_network_seeded_and_global_rng_untouched():
    state = torch.get_rng_state()
    a, b = build_network(20, seed=3), build_network(20, seed=3)
    assert torch.equal(torch.get_rng_state(), state)
    for p, q in zip(a.parameters(), b.parameters(), strict=True):
        assert torch.equal(p, q)
    c = build_network(20, seed=4)
    assert not torch.equal(next(a.parameters()), next(c.parameters()))


def test_data_module_does_not_import_torch():
    code = (
        "import sys, microfab.identify.ann_data, microfab.identify; print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# --- windows ---------------------------------------------------------------------------


@pytest.mark.parametrize("pad", [True, False])
@pytest.mark.parametrize("offset", [0, 11, 24])
def test_windows_shape_and_offset(pad, offset):
    spec = WindowSpec(h=20, encoding="absolute", pad=pad)
    u, y = TRAIN[0]
    x, t, base = windows(u, y, spec, axis=1, offset=offset)
    r = u[offset::25, 1]
    m = r.size
    assert m == len(range(offset, u.shape[0], 25))
    n_win = m if pad else m - 20
    assert x.shape == (n_win, 20) and t.shape == (n_win,) and np.all(base == 0.0)
    first = 0 if pad else 20
    for j in (0, 1, 5, 19, 20, 21, n_win - 1):
        i = j + first  # target model sample
        hist = [r[k] if k >= 0 else u[0, 1] for k in range(i - 20, i)]
        np.testing.assert_array_equal(x[j], hist)
        assert t[j] == y[offset + 25 * i, 1]  # eq. (7): φ_i after r_{i-1}


def test_relative_encoding_decodes_and_both_inputs():
    u, y = TRAIN[1]
    spec_a = WindowSpec(h=20, encoding="absolute")
    xa, ta, _ = windows(u, y, spec_a, axis=0, offset=3)
    xr, tr, base = windows(u, y, WindowSpec(h=20, encoding="relative"), axis=0, offset=3)
    np.testing.assert_array_equal(base, xa[:, -1])
    np.testing.assert_array_equal(xr[:, -1], xa[:, -1])
    np.testing.assert_allclose(xr[:, :-1] + base[:, None], xa[:, :-1], rtol=0, atol=1e-18)
    np.testing.assert_allclose(tr + base, ta, rtol=0, atol=1e-18)
    xe, te, base_e = windows(u, y, SPEC, axis=0, offset=3)
    np.testing.assert_array_equal(xe, xr)
    np.testing.assert_array_equal(base_e, 2 * xa[:, -1] - xa[:, -2])
    np.testing.assert_allclose(te + base_e, ta, rtol=0, atol=1e-18)
    both = WindowSpec(h=20, inputs="both", encoding="relative")
    xb, tb, _ = windows(u, y, both, axis=1, offset=3)
    xy, ty, _ = windows(u, y, WindowSpec(h=20, encoding="relative"), axis=1, offset=3)
    assert xb.shape == (xr.shape[0], 40)
    np.testing.assert_array_equal(xb[:, 20:], xy)
    np.testing.assert_array_equal(xb[:, :20], xr)
    np.testing.assert_array_equal(tb, ty)


@pytest.mark.parametrize("inputs", ["own", "both"])
def test_window_set_gathers_the_strided_windows(inputs):
    spec = WindowSpec(h=20, inputs=inputs)
    ws = WindowSet(TRAIN[:2], spec, offsets=(2, 9))
    parts = [windows(u, y, spec, axis=1, offset=o) for u, y in TRAIN[:2] for o in (2, 9)]
    x_ref = np.concatenate([p[0] for p in parts])
    t_ref = np.concatenate([p[1] for p in parts])
    assert len(ws) == x_ref.shape[0]
    idx = np.random.default_rng(0).permutation(len(ws))[:3000]
    x, t = ws.batch(idx, 1)
    np.testing.assert_array_equal(x, x_ref[idx])
    np.testing.assert_array_equal(t, t_ref[idx])
    ref = Scaling.fit(x_ref, t_ref)
    # one chunk, and chunks of 997 windows (the one-pass moments about a shift)
    for scal in (ws.fit_scaling(1), ws.fit_scaling(1, chunk=997)):
        np.testing.assert_allclose(scal.in_offset, ref.in_offset, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(scal.in_scale, ref.in_scale, rtol=1e-9)
        assert scal.out_offset == pytest.approx(ref.out_offset, rel=1e-9, abs=1e-15)
        assert scal.out_scale == pytest.approx(ref.out_scale, rel=1e-9)


def test_scaling_round_trip():
    x, t, _ = windows(*TRAIN[2], SPEC, axis=0, offset=0)
    s = Scaling.fit(x, t)
    xs = s.scale_inputs(x)
    assert xs.dtype == np.float32
    np.testing.assert_allclose(xs.mean(axis=0), 0.0, atol=1e-4)
    np.testing.assert_allclose(xs.std(axis=0), 1.0, atol=1e-3)
    z = (t - s.out_offset) / s.out_scale
    np.testing.assert_allclose(s.unscale_target(z), t, rtol=0, atol=1e-18)
    back = Scaling.from_dict(json.loads(json.dumps(s.as_dict())))
    for a, b in ((back.in_offset, s.in_offset), (back.in_scale, s.in_scale)):
        np.testing.assert_array_equal(a, b)
    assert (back.out_offset, back.out_scale) == (s.out_offset, s.out_scale)
    const = Scaling.fit(np.ones((10, 3)), np.arange(10.0))
    np.testing.assert_array_equal(const.in_scale, 1.0)


# --- training, resume, files -------------------------------------------------------------


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    d = tmp_path_factory.mktemp("ck")
    records = []
    model = train_ann(
        TRAIN,
        VAL,
        small_config(max_epochs=12, patience=12),
        checkpoint_dir=d,
        progress=records.append,
    )
    return model, records, d


def test_training_reduces_validation_error(trained):
    model, records, _ = trained
    for axis in ("x", "y"):
        val = [r.val_loss for r in records if r.axis == axis]
        assert len(val) == 12
        assert min(val) < 0.05 * val[0]  # scaled MSE; the first epoch is already trained once
    # untrained network with the same scaling, on the validation run (x)
    fresh = AnnModel(
        model.config, {a: build_network(20, seed=5) for a in model.axes}, model.scalings
    )
    err_fresh = fresh.metrics(VAL)["x"].sigma
    err = model.metrics(VAL)["x"].sigma
    assert err < 0.05 * err_fresh
    assert model.info["axes"]["x"]["epochs"] == 12
    lrs = [r.learning_rate for r in records if r.axis == "x"]
    assert all(b < a for a, b in itertools.pairwise(lrs))  # decaying learning rate


def test_training_threads_default_one_unless_asked():
    assert AnnConfig().threads == 1
    before = torch.get_num_threads()
    cfg = dict(vars(small_config(max_epochs=1, axes=("x",))))
    del cfg["threads"]
    try:
        torch.set_num_threads(2)
        train_ann(TRAIN[:1], VAL, AnnConfig(**cfg))
        assert torch.get_num_threads() == 1
        train_ann(TRAIN[:1], VAL, AnnConfig(**{**cfg, "threads": 2}))
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    with pytest.raises(ValueError, match="threads"):
        AnnConfig(threads=0)


def test_resume_is_bit_identical(tmp_path):
    whole = train_ann(TRAIN, VAL, small_config(max_epochs=4))
    d = tmp_path / "ck"
    part = train_ann(TRAIN, VAL, small_config(max_epochs=2), checkpoint_dir=d)
    assert part.info["axes"]["y"]["epochs"] == 2
    resumed = train_ann(TRAIN, VAL, small_config(max_epochs=4), checkpoint_dir=d)
    assert resumed.info["axes"]["x"]["history"] == whole.info["axes"]["x"]["history"]
    differ = []
    for a in ("x", "y"):
        sw, sr = whole.networks[a].state_dict(), resumed.networks[a].state_dict()
        assert all(torch.equal(sw[k], sr[k]) for k in sw)
        sp = part.networks[a].state_dict()
        differ.append(not all(torch.equal(sw[k], sp[k]) for k in sw))
    # the resumed epochs did work: an axis whose best epoch came after the interruption
    # (an axis may keep its early best epoch)
    assert any(differ)


def test_checkpoint_of_another_training_refused(trained, tmp_path):
    _, _, d = trained
    with pytest.raises(
        CheckpointMismatchError, match=r"other settings: config\.learning_rate 0\.002 -> 0\.001, "
    ):
        train_ann(TRAIN, VAL, small_config(max_epochs=12, learning_rate=1e-3), checkpoint_dir=d)
    with pytest.raises(CheckpointMismatchError, match="train_digest"):
        train_ann(TRAIN[:2], VAL, small_config(max_epochs=12), checkpoint_dir=d)
    with pytest.raises(CheckpointMismatchError, match=r"config\.window\.h 20 -> 24"):
        train_ann(TRAIN, VAL, small_config(window=WindowSpec(h=24)), checkpoint_dir=d)
    # another format version
    ck = tmp_path / "ck"
    train_ann(TRAIN, VAL, small_config(max_epochs=1, axes=("x",)), checkpoint_dir=ck)
    path = ck / "ann_x.ckpt.npz"
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("meta")))
    meta["version"] = FORMAT_VERSION + 1
    np.savez(path, meta=np.array(json.dumps(meta)), **arrays)
    with pytest.raises(CheckpointMismatchError, match=f"format {FORMAT_VERSION + 1}; this"):
        train_ann(TRAIN, VAL, small_config(max_epochs=2, axes=("x",)), checkpoint_dir=ck)
    again = train_ann(
        TRAIN, VAL, small_config(max_epochs=1, axes=("x",)), checkpoint_dir=ck, restart=True
    )
    assert again.info["axes"]["x"]["epochs"] == 1


def test_predict_at_10khz_interleaves_offsets(trained):
    model, _, _ = trained
    u, _ = VAL[0]
    fine = model.predict(u, at="10khz")
    assert fine.shape == (u.shape[0], 2)
    for o in (0, 5, 24):
        coarse = model.predict(u, offset=o)
        assert coarse.shape == (len(range(o, u.shape[0], 25)), 2)
        np.testing.assert_array_equal(fine[o::25], coarse)


def test_save_load_round_trip(trained, tmp_path):
    model, _, _ = trained
    model.save(tmp_path / "m")
    meta = json.loads((tmp_path / "m" / "model.json").read_text())
    assert meta["layers"] == [20, *HIDDEN, 1] and meta["window"]["rate_hz"] == 400.0
    back = AnnModel.load(tmp_path / "m", run_rate_hz=10_000, rate_hz=400, h=20)
    u, _ = VAL[0]
    np.testing.assert_array_equal(back.predict(u, at="10khz"), model.predict(u, at="10khz"))
    assert back.scalings["y"].as_dict() == model.scalings["y"].as_dict()
    assert back.config.fingerprint() == model.config.fingerprint()


def test_model_refusals(trained, tmp_path):
    model, _, _ = trained
    d = model.save(tmp_path / "m")
    with pytest.raises(ValueError, match="history h is 20, expected 200"):
        AnnModel.load(d, h=200)
    with pytest.raises(ValueError, match="run rate is 10000, expected 20000"):
        AnnModel.load(d, run_rate_hz=20_000)
    with pytest.raises(ValueError, match="model rate is 400, expected 500"):
        AnnModel.load(d, rate_hz=500)
    meta = json.loads((d / "model.json").read_text())
    meta["format_version"] = FORMAT_VERSION + 1
    (d / "model.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=f"format version {FORMAT_VERSION + 1}"):
        AnnModel.load(d)
    u, _ = VAL[0]
    with pytest.raises(ValueError, match="trained on runs at 10000 Hz, got a command at 20000"):
        model.predict(u, rate_hz=20_000)


def test_bad_runs_refused():
    u, y = TRAIN[0]
    with pytest.raises(ValueError, match="at least the history h = 20 samples at 400 Hz"):
        check_run(u[:499], y[:499], SPEC)
    bad = u.copy()
    bad[77, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite value nan at sample 77 of axis y"):
        check_run(bad, y, SPEC)
    with pytest.raises(ValueError, match=r"shape \(n_samples, 2\)"):
        check_run(u[:, :1], None, SPEC)
    with pytest.raises(ValueError, match="differ in length"):
        check_run(u, y[:-1], SPEC)
    with pytest.raises(ValueError, match="whole multiple of rate_hz"):
        WindowSpec(run_rate_hz=10_100.0)
    with pytest.raises(ValueError, match="inputs must be one of"):
        WindowSpec(inputs="all")
    with pytest.raises(ValueError, match="offsets must be distinct and lie in"):
        AnnConfig(offsets=(25,))
    with pytest.raises(ValueError, match="axes must be distinct"):
        AnnConfig(axes=("x", "z"))
    with pytest.raises(ValueError, match="lr_decay must lie in"):
        AnnConfig(lr_decay=1.5)


def test_epoch_windows_draws_a_subset_each_epoch_and_is_fingerprinted(tmp_path):
    full = small_config(max_epochs=1, axes=("x",))
    part = small_config(max_epochs=1, axes=("x",), epoch_windows=1024, val_windows=512)
    t_full = train_ann(TRAIN, VAL, full)
    t_part = train_ann(TRAIN, VAL, part)
    h_full = t_full.info["axes"]["x"]["history"][0]
    h_part = t_part.info["axes"]["x"]["history"][0]
    assert h_full != h_part
    d = tmp_path / "ck"
    train_ann(TRAIN, VAL, part, checkpoint_dir=d)
    with pytest.raises(CheckpointMismatchError, match="epoch_windows"):
        train_ann(TRAIN, VAL, small_config(max_epochs=2, axes=("x",)), checkpoint_dir=d)
    with pytest.raises(ValueError, match="epoch_windows"):
        AnnConfig(epoch_windows=0)
    with pytest.raises(ValueError, match="val_windows"):
        AnnConfig(val_windows=-3)


def test_axes_in_worker_processes_give_the_same_networks(tmp_path):
    seen = []
    one = train_ann(TRAIN, VAL, small_config(max_epochs=2))
    two = train_ann(
        TRAIN, VAL, small_config(max_epochs=2, workers=2), checkpoint_dir=tmp_path / "ck",
        progress=seen.append,
    )  # fmt: skip
    for a in ("x", "y"):
        s1, s2 = one.networks[a].state_dict(), two.networks[a].state_dict()
        assert all(torch.equal(s1[k], s2[k]) for k in s1)
        assert one.info["axes"][a]["history"] == two.info["axes"][a]["history"]
    assert sorted((r.axis, r.epoch) for r in seen) == [("x", 1), ("x", 2), ("y", 1), ("y", 2)]
    # a worker's refusal reaches the caller
    with pytest.raises(CheckpointMismatchError, match="learning_rate"):
        train_ann(
            TRAIN, VAL, small_config(max_epochs=3, workers=2, learning_rate=1e-3),
            checkpoint_dir=tmp_path / "ck",
        )  # fmt: skip
    with pytest.raises(ValueError, match="workers"):
        AnnConfig(workers=0)
