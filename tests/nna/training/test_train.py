"""Training (nna.train), ``stereosim train`` / ``stereosim quantize`` and the shipped weights.

The training tests run on a tiny synthetic Middlebury-2006-layout folder, so they need neither
the shared data nor more than a few seconds; the full training is never run here.
"""

import errno
import io
import os
import shutil
import struct
import zipfile
import zlib
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import torch  # in the test extra: the smoke epoch must run in CI
from numpy.testing import assert_array_equal

from stereosim.core.config import DESCRIPTOR_DEFAULTS, load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.nna.conv.conv import cnn_descriptor
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS, default_weights, load_layer
from stereosim.nna.training.floatmodel import load_float_model, save_float_model
from stereosim.nna.training.train import train
from stereosim.nna.training.trainconfig import VARIANTS, TrainConfig, receptive_field
from stereosim.nna.training.traindata import (
    calibration_scene_dirs,
    cv_folds,
    leave_fold_out,
    load_strip_set,
    load_training_set,
    patch_size,
    sample_batch,
    sample_strips,
    strip_reach,
    training_scene_dirs,
)
from stereosim.nna.training.trainloss import (
    bit_regularisers,
    build_network,
    cost_curves,
    curve_loss,
    relaxed_bits,
)
from stereosim.quant.artifact import load_quantized, to_nna_weights
from stereosim.quant.intconv import int_forward
from stereosim.quant.quantizer import FloatModel, float_forward
from stereosim.sim.cli import main
from stereosim.sva.box.aggregation import box_filter
from stereosim.sva.hamming.cost import hamming_cost

SHIFT = 5  # disparity of the synthetic scenes


@pytest.fixture(scope="module")
def data_root(tmp_path_factory, scene_writer):
    root = tmp_path_factory.mktemp("data")
    # Art must be left out (= MiddEval3 ArtL)
    for year, name, seed in (("2005", "Art", 1), ("2005", "Books", 2), ("2006", "Aloe", 3)):
        scene_writer(root / f"middlebury{year}_third" / name, seed, SHIFT)
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


def test_a_left_out_fold_is_the_tuning_cross_validation_fold(data_root):
    """Scene i of the sorted names is in fold i mod k -- worked by hand for seven names in
    three folds -- and leaving a fold out trains on the other folds' scenes only."""
    names = ["g", "a", "e", "b", "f", "c", "d"]  # sorted: a b c d e f g -> folds 0 1 2 0 1 2 0
    assert cv_folds(names, 3) == [0, 0, 1, 1, 2, 2, 0]
    assert cv_folds([*names, "a"], 3)[-1] == 0  # a degraded copy's name falls in its scene's fold
    dirs = training_scene_dirs(data_root)  # Books, Aloe: sorted Aloe (fold 0), Books (fold 1)
    assert [p.name for p in leave_fold_out(dirs, 0, 2)] == ["Books"]
    assert [p.name for p in leave_fold_out(dirs, 1, 2)] == ["Aloe"]


def test_positive_patch_is_the_left_patch_without_augmentation(data_root):
    cfg = TrainConfig(pos_offset=0.0, neg_low=3.0, neg_high=3.0, gain=0.0, offset=0.0,
                      noise_max=0.0, batch=64)  # fmt: skip
    ts = load_training_set(training_scene_dirs(data_root), cfg)
    assert np.all(ts.disp == SHIFT) and ts.scene.size > 0
    batch = sample_batch(ts, cfg, np.random.default_rng(0))
    assert batch.shape == (3, 64, 9, 9)  # single9x9's window
    assert_array_equal(batch[1], batch[0])  # right(x - d) == left(x) in this scene
    assert not np.array_equal(batch[2], batch[0])  # the negative is 3 px off


def test_augmentation_changes_each_view_independently(data_root):
    cfg = TrainConfig(pos_offset=0.0, batch=64)
    ts = load_training_set(training_scene_dirs(data_root), cfg)
    batch = sample_batch(ts, cfg, np.random.default_rng(0))
    assert not np.array_equal(batch[1], batch[0])
    assert batch.min() >= 0 and batch.max() <= 255 and np.all(batch == np.rint(batch))


def _train(data_root, **kw):
    cfg = TrainConfig(
        **{"epochs": 2, "steps_per_epoch": 3, "batch": 16, "strips": 8, "threads": 1, **kw}
    )
    return train(cfg, training_scene_dirs(data_root), progress=False)


@pytest.mark.parametrize(
    "variant, objective", [(v, "curve") for v in VARIANTS] + [("single9x9", "triplet")]
)
def test_smoke_epoch_is_deterministic(data_root, variant, objective):
    a = _train(data_root, variant=variant, objective=objective, seed=3)
    b = _train(data_root, variant=variant, objective=objective, seed=3)
    c = _train(data_root, variant=variant, objective=objective, seed=4)
    assert len(a["weights"]) == len(VARIANTS[variant])
    for (c_in, c_out, k), w in zip(VARIANTS[variant], a["weights"]):
        assert w.shape == (c_out, c_in, k, k)
    for x, y in zip(a["weights"], b["weights"]):
        assert_array_equal(x, y)
    assert not np.array_equal(a["weights"][0], c["weights"][0])
    assert all(np.isfinite(v) for v in a["loss_per_epoch"])


@pytest.mark.parametrize("objective", ["curve", "triplet"])
def test_training_lowers_the_loss(data_root, objective):
    res = _train(data_root, objective=objective, epochs=4, steps_per_epoch=25, batch=64,
                 noise_max=4.0)  # fmt: skip
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
                 f"nna.cnn.weights={weights}", "--disparities", "16", "--out", str(out)])
    assert code == 0 and (out / "disparity.pfm").is_file()


def test_quantize_takes_the_hidden_layer_settings_of_a_multi_layer_model(data_root, tmp_path,
                                                                          capsys):
    model = tmp_path / "slim.npz"
    save_float_model(model, _train(data_root, variant="mccnn4-slim"))
    scales = {}
    for q in ("0.9999", "0.9"):
        out = tmp_path / f"w{q}.npz"
        args = ["quantize", str(model), "--calib", str(data_root), "--out", str(out),
                "--samples", "300", "--act-quantile", q, "--hidden-distance", "l1"]
        assert main(args) == 0, capsys.readouterr().err
        qm = load_quantized(out)
        assert qm.distances == ("l1", "l1", "l1", "hamming")
        assert f"activation quantile {q}" in qm.calibration
        scales[q] = qm.act_scales[1]
    # a lower quantile of the same ReLU outputs maps a smaller value to 127
    assert scales["0.9"] > scales["0.9999"]
    # --no-equalize: the paper's one range a layer, as the channels come, and the record says so
    flat = tmp_path / "flat.npz"
    args = ["quantize", str(model), "--calib", str(data_root), "--out", str(flat), "--samples",
            "300", "--hidden-distance", "l1", "--no-equalize"]
    assert main(args) == 0, capsys.readouterr().err
    qm_flat = load_quantized(flat)
    assert "one activation range a layer (not equalised)" in qm_flat.calibration
    assert "hidden channels equalised to one activation range" in qm.calibration
    assert qm_flat.act_scales[1] != scales["0.9999"]  # the same quantile, another range
    bad = ["quantize", str(model), "--calib", str(data_root), "--out", str(tmp_path / "x.npz"),
           "--act-quantile", "0"]
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: ") and "act_quantile" in err and err.count("\n") == 1
    assert not (tmp_path / "x.npz").exists()


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
        (["train", "--data", str(data_root), "--leave-out-fold", "2/2", "--out", str(out)],
         "fold 2 of 2: need 2 <= folds <= 2 (the scenes) and 0 <= fold < folds"),
        (["train", "--data", str(data_root), "--leave-out-fold", "0/3", "--out", str(out)],
         "fold 0 of 3: need 2 <= folds <= 2"),
        (["train", "--data", str(data_root), "--leave-out-fold", "1", "--out", str(out)],
         "'1' is not K/N"),
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
    assert batch.shape == (3, 8, 9 + 2, 9 + 2)
    assert_array_equal(batch[1], batch[0])
    res = _train(data_root, objective="triplet", aggregate=3)
    assert res["weights"][0].shape == (32, 1, 9, 9)
    with pytest.raises(ConfigError, match="aggregate"):
        TrainConfig(aggregate=2)


# --- the cost-curve objective -------------------------------------------------------------------


def test_strips_cover_both_views_with_their_own_ground_truth(data_root):
    cfg = TrainConfig(strips=64, strip_width=16, disparities=12, gain=0.0, offset=0.0,
                      noise_max=0.0)  # fmt: skip
    ss = load_strip_set(training_scene_dirs(data_root), cfg)
    assert ss.names == ("middlebury2005_third/Books", "middlebury2006_third/Aloe")
    assert len(ss.views) == 4 and set(np.unique(ss.image)) == {0, 1, 2, 3}
    # left GT is unknown in the first SHIFT columns, right GT in the last SHIFT columns; every
    # other pixel is visible in the other view (the right view's check is mirrored)
    left, right = ss.x[ss.image % 2 == 0], ss.x[ss.image % 2 == 1]
    assert left.min() == SHIFT and left.max() == 399
    assert right.min() == 0 and right.max() == 399 - SHIFT
    batch = sample_strips(ss, cfg, np.random.default_rng(0))
    r = strip_reach(cfg)
    assert batch["ref"].shape == (64, 2 * r + 1, 16 + 2 * r)
    assert batch["other"].shape == (64, 2 * r + 1, 16 + 2 * r + 11)
    assert batch["mirror"].any() and not batch["mirror"].all()
    known = np.isfinite(batch["target"])
    assert known.any() and np.all(batch["target"][known] == SHIFT)
    # without augmentation the other view's crop, at the match, is the reference crop
    for k in range(64):
        ref, other, x0 = batch["ref"][k], batch["other"][k], batch["x0"][k]
        cols = x0 - r + np.arange(ref.shape[1])  # image columns of the reference crop
        if batch["mirror"][k]:  # right reference: match at x + d, other crop starts at x0 - r
            k_other, matched = cols - (x0 - r) + SHIFT, cols + SHIFT
        else:  # left reference: match at x - d, other crop starts D - 1 further left
            k_other, matched = cols - (x0 - r - 11) - SHIFT, cols - SHIFT
        ok = (cols >= 0) & (cols < 400) & (matched >= 0) & (matched < 400)
        assert ok.sum() >= 10
        assert_array_equal(other[:, k_other[ok]], ref[:, ok])


def _float_bits(model, img):
    return float_forward(model, img) > 0


def test_receptive_fields_are_the_sum_of_the_kernels():
    assert receptive_field("single9x9") == receptive_field("mccnn4") == 9
    assert receptive_field("mixed5x5-wide") == receptive_field("double5x5") == 9
    assert receptive_field("mixed5x5-rf11") == 11
    cfg = TrainConfig(variant="mixed5x5-rf11", box=7)
    assert strip_reach(cfg) == 5 + 3 and patch_size(cfg) == 11


@pytest.mark.parametrize("variant", ["single9x9", "mixed5x5-rf11"])
def test_cost_curves_are_the_chips_box_filtered_hamming_costs(data_root, variant):
    """With sign bits, the training cost of every strip pixel equals the SVA's Hamming cost
    box-filtered over 5 x 5 (divided by 25) at that pixel, for both reference views. The crops
    clamp their coordinates into the image, which is the chip's replicate border for one layer;
    for several layers the check keeps to pixels whose window lies inside the image."""
    cfg = TrainConfig(variant=variant, strips=24, strip_width=20, disparities=10, gain=0.0,
                      offset=0.0, noise_max=0.0)  # fmt: skip
    dirs = training_scene_dirs(data_root)
    ss = load_strip_set(dirs, cfg)
    torch.manual_seed(0)
    net = build_network(variant).double()
    convs = [m for m in net if isinstance(m, torch.nn.Conv2d)]
    with torch.no_grad():
        for conv in convs:
            conv.bias.uniform_(-0.2, 0.2)
    model = FloatModel(
        weights=tuple(c.weight.detach().numpy().astype(np.float64) for c in convs),
        biases=tuple(c.bias.detach().numpy().astype(np.float64) for c in convs),
        input_offset=cfg.input_offset,
        input_scale=cfg.input_scale,
    )
    margin = cfg.box // 2 if len(convs) == 1 else strip_reach(cfg)
    batch = sample_strips(ss, cfg, np.random.default_rng(2))
    with torch.no_grad():
        feats = [
            net((torch.from_numpy(batch[k]).double() - 128.0)[:, None] / 64.0)
            for k in ("ref", "other")
        ]
        mirror = torch.from_numpy(batch["mirror"])[:, None, None, None]
        feats = [torch.where(mirror, f.flip(3), f) for f in feats]
        bits = [relaxed_bits(f, 1.0, sign=True) for f in feats]
        cost = cost_curves(bits[0], bits[1], cfg.disparities, cfg.box).numpy()
    # the chip's volumes: left reference directly; right reference on mirrored images with
    # the mirrored network (conv of a mirrored image by a mirrored kernel = mirrored output)
    mirrored = FloatModel(weights=tuple(w[..., ::-1] for w in model.weights),
                          biases=model.biases, input_offset=model.input_offset,
                          input_scale=model.input_scale)
    volumes = {}
    for i in range(len(ss.views)):
        view, partner = ss.views[i].astype(np.uint8), ss.views[i ^ 1].astype(np.uint8)
        m = model
        if i % 2:
            view, partner, m = view[:, ::-1], partner[:, ::-1], mirrored
        words = [
            (_float_bits(m, v).astype(np.uint64) << np.arange(32, dtype=np.uint64)).sum(axis=2)
            for v in (view, partner)
        ]
        c = hamming_cost(words[0].astype(np.uint32), words[1].astype(np.uint32),
                         cfg.disparities, 32)  # fmt: skip
        volumes[i] = box_filter(c, cfg.box, 10).astype(np.float64) / cfg.box**2
    checked = 0
    for k in range(cfg.strips):
        i, y = int(batch["image"][k]), int(batch["y"][k])
        height, width = ss.views[i].shape
        if not margin <= y < height - margin:
            continue
        for j in np.flatnonzero(np.isfinite(batch["target"][k])):
            # max_disp is the pixel's column in the chip's (for a right reference: mirrored)
            # geometry, where the match of column x at disparity d is column x - d
            xc = int(batch["max_disp"][k, j])
            if xc - margin - (cfg.disparities - 1) < 0 or xc + margin >= width:
                continue
            np.testing.assert_allclose(cost[k, j], volumes[i][y, xc], atol=1e-9)
            checked += 1
    assert checked > 100


def test_curve_loss_prefers_the_ground_truth_and_ignores_unusable_pixels():
    cost = torch.full((1, 3, 8), 10.0, dtype=torch.float64)
    cost[0, 0, 3] = 0.0  # pixel 0: clear minimum at 3
    cost[0, 1, 5] = 0.0  # pixel 1: minimum at 5, but its GT is unknown
    target = torch.tensor([[3.0, float("nan"), 2.5]], dtype=torch.float64)
    max_disp = torch.full((1, 3), 7.0, dtype=torch.float64)
    log_t = torch.tensor(0.0, dtype=torch.float64)
    right = curve_loss(cost, target, max_disp, log_t)
    wrong = curve_loss(cost, torch.tensor([[6.0, float("nan"), 2.5]], dtype=torch.float64),
                       max_disp, log_t)  # fmt: skip
    assert right < wrong
    # pixel 2 is flat: its loss is log(8), whatever the split of its target; pixel 0's is tiny
    expected = (np.log(1 + 7 * np.exp(-10.0)) + np.log(8)) / 2
    assert abs(float(right) - expected) < 1e-9
    # candidates beyond max_disp are left out of the softmax
    max_disp[0, 2] = 3.0
    assert abs(float(curve_loss(cost, target, max_disp, log_t))
               - (np.log(1 + 7 * np.exp(-10.0)) + np.log(4)) / 2) < 1e-9  # fmt: skip


def test_bit_regularisers_are_zero_for_balanced_independent_bits():
    gen = torch.Generator().manual_seed(0)
    bits = torch.randint(0, 2, (64, 4, 16, 16), generator=gen).double() * 2 - 1
    bal, dec = bit_regularisers(bits)
    assert bal < 1e-3 and dec < 1e-3
    same = bits[:, :1].repeat(1, 4, 1, 1)  # four copies of one bit: fully correlated
    assert bit_regularisers(same)[1] > 0.99
    assert bit_regularisers(torch.ones(8, 4, 3, 3, dtype=torch.float64))[0] == 1.0


def test_straight_through_bits_are_signs_with_the_tanh_gradient():
    f = torch.tensor([-2.0, -0.1, 0.3, 1.5], dtype=torch.float64, requires_grad=True)
    b = relaxed_bits(f, 2.0, sign=True)
    assert_array_equal(b.detach().numpy(), [-1.0, -1.0, 1.0, 1.0])
    b.sum().backward()
    np.testing.assert_allclose(f.grad.numpy(), 2.0 / np.cosh(2.0 * f.detach().numpy()) ** 2)


# --- files read safely ----------------------------------------------------------------------------


def _float_model_file(path: Path, **changes) -> Path:
    """A valid single9x9 float model file, with some of its arrays replaced (None removes)."""
    cfg = TrainConfig()
    rng = np.random.default_rng(0)
    save_float_model(path, {
        "weights": [rng.normal(size=(32, 1, 9, 9)).astype(np.float32)],
        "biases": [np.zeros(32, np.float32)],
        "config": asdict(cfg), "scenes": [], "loss_per_epoch": [], "samples": 0,
    })  # fmt: skip
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files}
    for key, value in changes.items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    np.savez(path, **arrays)  # np.savez keeps a name that ends in .npz
    return path


@pytest.mark.parametrize(
    "changes, message",
    [
        ({}, None),
        ({"training": np.array("{not json")}, "its training record is not JSON"),
        ({"training": np.array('{"config": ' + "1" * 5000 + "}")},
         "its training record is not JSON"),
        ({"training": None}, "lacks the field 'training'"),
        ({"input_offset": np.zeros(3, np.int32)},
         r"input_offset must be a scalar, got int32 \(3,\)"),
        ({"input_scale": np.array("big")}, "input_scale must be a scalar, got <U3"),
        ({"format": np.zeros(2)}, "format must be a scalar"),
        ({"weights_0": np.full((32, 1, 9, 9), "w")}, r"layer 0 of single9x9 must be float"),
        ({"weights_0": np.full((32, 1, 9, 9), np.inf)}, "non-finite weights"),
        ({"input_offset": np.int32(300)}, "input_offset must be in 0..255"),
    ],
    ids=[
        "good", "json", "json-long-number", "no-training", "offset-array", "scale-text",
        "format-array", "text-weights", "inf-weights", "offset-range",
    ],
)
def test_float_model_fields_are_checked(tmp_path, changes, message):
    path = _float_model_file(tmp_path / "m.npz", **changes)
    if message is None:
        model, variant, training = load_float_model(path)
        assert variant == "single9x9" and model.weights[0].shape == (32, 1, 9, 9)
        assert training["samples"] == 0
        return
    with pytest.raises(ConfigError, match=message) as info:
        load_float_model(path)
    assert f"float model '{path}'" in str(info.value) and "\n" not in str(info.value)


def test_a_float_model_is_read_within_bounds(tmp_path):
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        buf = io.BytesIO()
        np.save(buf, np.zeros(1 << 18))  # 2 MiB of zeros: about 2 KB deflated
        archive.writestr("weights_0.npy", buf.getvalue())
    with pytest.raises(ConfigError, match=r"float model '.*bomb.npz' member .* a zip bomb"):
        load_float_model(path)


def test_training_scenes_go_through_the_bounded_readers(data_root, tmp_path, monkeypatch):
    # A training view that claims 9000x8000 pixels is refused from its header.
    root = tmp_path / "data"
    shutil.copytree(data_root, root)
    view = root / "middlebury2006_third" / "Aloe" / "view5.png"
    ihdr = struct.pack(">IIBBBBB", 9000, 8000, 8, 0, 0, 0, 0)
    view.write_bytes(b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr
                     + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)))  # fmt: skip
    dirs = training_scene_dirs(root)
    cfg = TrainConfig()
    for load in (load_training_set, load_strip_set):
        with pytest.raises(InputError, match=r"view5.png is 9000x8000 \(72.0 M pixels\)"):
            load(dirs, cfg)
    # A collection that cannot be listed, a path too long: one line, not an OSError.
    real_scandir = os.scandir

    def denied(path):
        if Path(path).name == "middlebury2005_third":
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real_scandir(path)

    monkeypatch.setattr(os, "scandir", denied)
    with pytest.raises(InputError, match=r"middlebury2005_third \(Permission denied\)"):
        training_scene_dirs(root)
    with pytest.raises(InputError, match=r"middlebury2005_third \(Permission denied\)"):
        calibration_scene_dirs(root)
    long = tmp_path / ("d" * 5000)
    for find in (training_scene_dirs, calibration_scene_dirs):
        with pytest.raises(InputError, match=r"File name too long"):
            find(long)


def test_the_training_device_is_checked_and_a_missing_gpu_is_one_line(data_root, tmp_path,
                                                                      capsys):
    """``--device``: cpu or cuda, nothing else; cuda where torch sees no GPU is one line and
    writes nothing (where it sees one, a smoke run on it writes a model of the same shapes,
    recorded as trained there)."""
    with pytest.raises(ConfigError, match="device must be one of cpu, cuda"):
        TrainConfig(device="tpu")
    out = tmp_path / "g.npz"
    args = ["train", "--data", str(data_root), "--device", "cuda", "--epochs", "1", "--steps",
            "2", "--strips", "4", "--threads", "1", "--quiet", "--out", str(out)]
    code = main(args)
    err = capsys.readouterr().err
    if torch.cuda.is_available():
        assert code == 0, err
        model, _, info = load_float_model(out)
        assert info["config"]["device"] == "cuda"
        assert [w.shape for w in model.weights] == [(32, 1, 9, 9)]
    else:
        assert code == 2 and err.count("\n") == 1
        assert "--device cuda: this torch sees no CUDA GPU; train with --device cpu" in err
        assert not out.exists()


def test_a_run_records_its_device(data_root):
    cfg = TrainConfig(epochs=1, steps_per_epoch=2, strips=4, threads=1)
    assert train(cfg, training_scene_dirs(data_root), progress=False)["config"]["device"] == "cpu"
