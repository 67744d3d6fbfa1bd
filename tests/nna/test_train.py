"""Training (nna.train), ``stereosim train`` / ``stereosim quantize`` and the shipped weights.

The training tests run on a tiny synthetic Middlebury-2006-layout folder, so they need neither
the shared data nor more than a few seconds; the full training is never run here.
"""

from pathlib import Path

import numpy as np
import pytest
import torch  # noqa: F401  (in the test extra: the smoke epoch must run in CI)
from numpy.testing import assert_array_equal

from nna.conv import cnn_descriptor
from nna.train import (
    PATCH,
    VARIANTS,
    TrainConfig,
    calibration_scene_dirs,
    load_float_model,
    load_training_set,
    sample_batch,
    train,
    training_scene_dirs,
)
from nna.weights import SHIPPED_WEIGHTS, default_weights, load_layer
from quant.intconv import int_forward
from quant.quantizer import load_quantized, to_nna_weights
from sim.cli import main
from sim.config import DESCRIPTOR_DEFAULTS, load_config
from sim.errors import ConfigError, InputError
from sim.io import encode_png

SHIFT = 5  # disparity of the synthetic scenes


def _scene(folder: Path, seed: int, h=30, w=400) -> None:
    """A 2006-layout scene: a smooth random texture, the right view shifted by SHIFT pixels,
    GT x3 as Middlebury stores it (the first SHIFT columns unknown); ThirdSize width, so the
    loader applies the x3 scale."""
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + SHIFT)).astype(np.float64)
    base = (base + np.roll(base, 1, 0) + np.roll(base, 1, 1) + np.roll(base, (1, 1), (0, 1))) / 4
    base = base.astype(np.uint8)
    folder.mkdir(parents=True)
    (folder / "view1.png").write_bytes(encode_png(base[:, :w].copy()))
    (folder / "view5.png").write_bytes(encode_png(base[:, SHIFT:].copy()))
    gt = np.full((h, w), 3 * SHIFT, np.uint8)
    gt[:, :SHIFT] = 0
    gt_right = np.full((h, w), 3 * SHIFT, np.uint8)
    gt_right[:, w - SHIFT :] = 0
    (folder / "disp1.png").write_bytes(encode_png(gt))
    (folder / "disp5.png").write_bytes(encode_png(gt_right))


@pytest.fixture(scope="module")
def data_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    _scene(root / "middlebury2005_third" / "Art", 1)  # must be left out (= MiddEval3 ArtL)
    _scene(root / "middlebury2005_third" / "Books", 2)
    _scene(root / "middlebury2006_third" / "Aloe", 3)
    return root


def test_training_scenes_leave_out_art_and_refuse_middeval3(data_root, tmp_path):
    names = [p.name for p in training_scene_dirs(data_root)]
    assert names == ["Books", "Aloe"]
    eval_dir = tmp_path / "middlebury2014_trainingQ"
    eval_dir.mkdir()
    with pytest.raises(InputError, match="evaluation set"):
        training_scene_dirs(eval_dir)
    with pytest.raises(InputError, match="evaluation set"):
        calibration_scene_dirs(eval_dir)
    with pytest.raises(InputError, match="no training scenes"):
        training_scene_dirs(tmp_path)


def test_positive_patch_is_the_left_patch_without_augmentation(data_root):
    cfg = TrainConfig(pos_offset=0.0, neg_low=3.0, neg_high=3.0, gain=0.0, offset=0.0,
                      noise_max=0.0, batch=64)  # fmt: skip
    ts = load_training_set(training_scene_dirs(data_root), cfg)
    assert np.all(ts.disp == SHIFT) and ts.scene.size > 0
    batch = sample_batch(ts, cfg, np.random.default_rng(0))
    assert batch.shape == (3, 64, PATCH, PATCH)
    assert_array_equal(batch[1], batch[0])  # right(x - d) == left(x) in this scene
    assert not np.array_equal(batch[2], batch[0])  # the negative is 3 px off


def test_augmentation_changes_each_view_independently(data_root):
    cfg = TrainConfig(pos_offset=0.0, batch=64)
    ts = load_training_set(training_scene_dirs(data_root), cfg)
    batch = sample_batch(ts, cfg, np.random.default_rng(0))
    assert not np.array_equal(batch[1], batch[0])
    assert batch.min() >= 0 and batch.max() <= 255 and np.all(batch == np.rint(batch))


def _train(data_root, **kw):
    cfg = TrainConfig(**{"epochs": 2, "steps_per_epoch": 3, "batch": 16, "threads": 1, **kw})
    return train(cfg, training_scene_dirs(data_root), progress=False)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_smoke_epoch_is_deterministic(data_root, variant):
    a = _train(data_root, variant=variant, seed=3)
    b = _train(data_root, variant=variant, seed=3)
    c = _train(data_root, variant=variant, seed=4)
    assert len(a["weights"]) == len(VARIANTS[variant])
    for (c_in, c_out, k), w in zip(VARIANTS[variant], a["weights"]):
        assert w.shape == (c_out, c_in, k, k)
    for x, y in zip(a["weights"], b["weights"]):
        assert_array_equal(x, y)
    assert not np.array_equal(a["weights"][0], c["weights"][0])
    assert all(np.isfinite(v) for v in a["loss_per_epoch"])


def test_training_lowers_the_loss(data_root):
    res = _train(data_root, epochs=4, steps_per_epoch=25, batch=64, noise_max=4.0)
    first, last = res["loss_per_epoch"][0], res["loss_per_epoch"][-1]
    assert last < 0.8 * first


def test_train_and_quantize_commands(data_root, tmp_path, capsys):
    model = tmp_path / "m.npz"
    code = main(["train", "--data", str(data_root), "--epochs", "1", "--steps", "3", "--batch",
                 "16", "--threads", "1", "--out", str(model), "--quiet"])  # fmt: skip
    assert code == 0 and model.is_file()
    fmodel, variant, info = load_float_model(model)
    assert variant == "single9x9" and info["scenes"] == ["middlebury2005_third/Books",
                                                        "middlebury2006_third/Aloe"]
    weights = tmp_path / "w.npz"
    code = main(["quantize", str(model), "--calib", str(data_root), "--out", str(weights),
                 "--samples", "500"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    qm = load_quantized(weights)
    assert qm.variant == "single9x9" and "Books" in qm.calibration
    assert 0.9 <= qm.sign_agreement <= 1.0
    # the NNA loads the artifact and its descriptor is the sign of the integer network
    w_nna, b_nna, off = load_layer(weights)
    img = np.random.default_rng(5).integers(0, 256, (23, 31), dtype=np.uint8)
    acc = int_forward(img, qm.weights, qm.biases, [], [], qm.input_offset)
    bits = ((acc > 0).astype(np.uint64) << np.arange(32, dtype=np.uint64)).sum(axis=2)
    assert_array_equal(cnn_descriptor(img, w_nna, b_nna, off), bits.astype(np.uint32))
    # and the run command takes it as nna.cnn.weights
    out = tmp_path / "out"
    left = data_root / "middlebury2006_third" / "Aloe"
    code = main(["run", str(left), "--mode", "functional", "--descriptor", "cnn", "--set",
                 f"nna.cnn.weights={weights}", "--disparities", "16", "--out", str(out)])  # fmt: skip
    assert code == 0 and (out / "disparity.pfm").is_file()


def test_bad_inputs_are_one_line_errors(data_root, tmp_path, capsys):
    model = tmp_path / "m.npz"
    model.write_bytes(b"junk")
    out = tmp_path / "w.npz"
    cases = [
        (["quantize", str(model), "--calib", str(data_root), "--out", str(out)], "not a readable"),
        (["quantize", str(tmp_path / "none.npz"), "--calib", str(data_root), "--out", str(out)],
         "not found"),
        (["train", "--data", str(tmp_path / "nowhere"), "--out", str(out)], "not found"),
        (["train", "--data", str(data_root), "--epochs", "0", "--out", str(out)], "epochs"),
        (["train", "--data", str(data_root), "--out", str(tmp_path / "no" / "m.npz")],
         "does not exist"),
        (["run", "--descriptor", "cnn", "--set", f"nna.cnn.weights={model}", "--mode",
          "functional", "--out", str(tmp_path / "o")], "not a readable"),
    ]
    for args, message in cases:
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.startswith("stereosim: error: ") and message in err
        assert err.count("\n") == 1
    assert not out.exists()


def test_shipped_weights_are_the_quantized_single9x9():
    qm = load_quantized(SHIPPED_WEIGHTS)
    assert qm.variant == "single9x9" and qm.n_layers == 1
    assert qm.sign_agreement >= 0.995
    for a, b in zip(default_weights(), to_nna_weights(qm)):
        assert_array_equal(a, b)
    weights, bias, _ = default_weights()
    assert weights.shape == (32, 9, 9) and weights.dtype == np.int8
    assert len({w.tobytes() for w in weights}) == 32  # 32 distinct kernels, none degenerate
    # the searched scales use the int8 range
    assert np.all(np.abs(weights.astype(int)).max(axis=(1, 2)) >= 64)


def test_each_descriptor_gets_its_own_penalties(tmp_path):
    for descriptor, tuned in DESCRIPTOR_DEFAULTS.items():
        cfg = load_config(None, {"nna.descriptor": descriptor})
        assert (cfg.sva.p1, cfg.sva.p2) == (tuned["p1"], tuned["p2"])
        cfg = load_config(None, {"nna.descriptor": descriptor, "sva.p1": 7})
        assert (cfg.sva.p1, cfg.sva.p2) == (7, tuned["p2"])
        toml = tmp_path / f"{descriptor}.toml"
        toml.write_text(f'[nna]\ndescriptor = "{descriptor}"\n[sva]\np2 = 300\n')
        cfg = load_config(toml)
        assert (cfg.sva.p1, cfg.sva.p2) == (tuned["p1"], 300)
    with pytest.raises(ConfigError, match="nna.descriptor"):
        load_config(None, {"nna.descriptor": "sift"})


def test_aggregated_training_sees_larger_patches(data_root):
    cfg = TrainConfig(aggregate=3, pos_offset=0.0, gain=0.0, offset=0.0, noise_max=0.0, batch=8)
    ts = load_training_set(training_scene_dirs(data_root), cfg)
    batch = sample_batch(ts, cfg, np.random.default_rng(1))
    assert batch.shape == (3, 8, PATCH + 2, PATCH + 2)
    assert_array_equal(batch[1], batch[0])
    res = _train(data_root, aggregate=3)
    assert res["weights"][0].shape == (32, 1, 9, 9)
    with pytest.raises(ConfigError, match="aggregate"):
        TrainConfig(aggregate=2)
