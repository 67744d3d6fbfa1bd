"""Quantisation-aware training (nna.trainqat): its forward pass is the chip's integer network.

With the fake-quant parameters frozen, the QAT network's accumulators (float64 convolutions, the
chip's replicate border) must equal :func:`quant.intconv.int_forward_ref` exactly, and the
artifact ``stereosim train --qat`` writes must be that integer network.
"""

import numpy as np
import pytest
import torch
from numpy.testing import assert_array_equal

from stereosim.core.datasets import find_scene, load_scene, shared_data_dir
from stereosim.core.io import to_grey
from stereosim.nna.training.floatmodel import load_float_model, save_float_model
from stereosim.nna.training.train import train
from stereosim.nna.training.trainconfig import TrainConfig
from stereosim.nna.training.traindata import training_scene_dirs
from stereosim.nna.training.trainqat import build_qat_net, export_quantized, integer_network
from stereosim.quant.artifact import load_quantized
from stereosim.quant.intconv import int_forward, int_forward_ref
from stereosim.quant.quantizer import FloatModel, QuantizerConfig, quantize_twin
from stereosim.sim.cli import main

DATA = shared_data_dir()
SHAPES = ((1, 4, 5), (4, 6, 3), (6, 8, 3))  # (C_in, C_out, K): a small mixed network


def _model(seed: int, shapes=SHAPES) -> FloatModel:
    rng = np.random.default_rng(seed)
    weights = [rng.normal(0.0, 1.0 / np.sqrt(c_in * k * k), (c_out, c_in, k, k))
               for c_in, c_out, k in shapes]
    biases = [rng.normal(0.0, 0.1, c_out) for _, c_out, _ in shapes]
    return FloatModel(weights=tuple(weights), biases=tuple(biases), input_offset=128,
                      input_scale=1 / 64)


def _images(seed: int, n: int = 2, shape=(29, 37)):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, shape, dtype=np.uint8) for _ in range(n)]


def _quantized(model: FloatModel):
    """The quantiser's float twin of ``model`` (equalised: the same function, rescaled hidden
    channels) and its integer network."""
    return quantize_twin(model, _images(1), QuantizerConfig(n_samples=800), progress=False)


def _accumulators(net, img):
    x = torch.from_numpy(img.astype(np.float64) - 128.0)[None, None]
    with torch.no_grad():
        acc = net.accumulators(x, same=True)
    return acc[0].permute(1, 2, 0).numpy()


@pytest.mark.parametrize("shapes", [SHAPES, ((1, 8, 3),), ((1, 3, 3), (3, 5, 1), (5, 4, 3),
                                                            (4, 6, 3))])
def test_qat_forward_equals_the_integer_reference(shapes):
    model = _model(2, shapes)
    model, qm = _quantized(model)
    net = build_qat_net(model, qm, torch.float64)
    # the QAT starts from the quantiser's integer network
    weights, biases = integer_network(net)
    for w, b, wq, bq in zip(weights, biases, qm.weights, qm.biases):
        assert_array_equal(w, wq)
        assert_array_equal(b, bq)
    # move the float weights, as training does, and freeze them: the forward pass is the chip's
    with torch.no_grad():
        for w in net.weights:
            w.add_(0.05 * torch.randn(w.shape, generator=torch.Generator().manual_seed(3)))
    weights, biases = integer_network(net)
    assert any(not np.array_equal(w, wq) for w, wq in zip(weights, qm.weights))
    args = (weights, biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    for img in _images(4, 3, (17, 23)) + [np.zeros((5, 9), np.uint8),
                                          np.full((6, 7), 255, np.uint8)]:
        ref = int_forward_ref(img, *args)
        assert_array_equal(_accumulators(net, img), ref)
        assert_array_equal(int_forward(img, *args), ref)


def test_qat_forward_is_the_accumulators_over_their_scale_and_passes_gradients():
    model = _model(5)
    model, qm = _quantized(model)
    net = build_qat_net(model, qm)  # float32, as in training
    img = _images(6, 1, (21, 25))[0]
    x = torch.from_numpy((img.astype(np.float32) - 128.0) / 64.0)[None, None]
    out = net(x)
    weights, biases = integer_network(net)
    ref = int_forward_ref(img, weights, biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    reach = sum(w.shape[2] // 2 for w in weights)  # 'valid' output: the interior of 'same'
    acc_scale = qm.weight_scales[-1] * qm.act_scales[-1]
    inner = ref[reach:-reach, reach:-reach] / acc_scale
    assert_array_equal(out[0].permute(1, 2, 0).detach().numpy(), inner.astype(np.float32))
    out.sum().backward()
    assert all(float(w.grad.abs().sum()) > 0 for w in net.weights)  # straight-through
    assert all(float(b.grad.abs().sum()) > 0 for b in net.biases)


def test_export_writes_the_qat_integer_network():
    model = _model(7)
    model, qm = _quantized(model)
    images = _images(8)
    out = export_quantized(model, qm, images, "test")
    weights, biases = integer_network(build_qat_net(model, qm))
    for a, b in zip(out.weights + out.biases, weights + biases):
        assert_array_equal(a, b)
    assert out.mult == qm.mult and out.shift == qm.shift
    args = (out.weights, out.biases, out.mult, out.shift, out.input_offset, out.z_bits)
    from stereosim.quant.quantizer import float_forward

    agree = np.mean([(int_forward(im, *args) > 0) == (float_forward(model, im) > 0)
                     for im in images])
    assert out.sign_agreement == pytest.approx(agree)


def test_train_qat_command(tmp_path, scene_writer, capsys):
    root = tmp_path / "data"
    for year, name, seed in (("2005", "Books", 2), ("2006", "Aloe", 3)):
        scene_writer(root / f"middlebury{year}_third" / name, seed, 6)
    base = tmp_path / "base.npz"
    cfg = TrainConfig(variant="mccnn4-slim", epochs=1, steps_per_epoch=3, strips=8, threads=1)
    save_float_model(base, train(cfg, training_scene_dirs(root), progress=False))
    out, flt = tmp_path / "q.int8.npz", tmp_path / "q.float.npz"
    code = main(["train", "--qat", str(base), "--data", str(root), "--epochs", "1", "--steps",
                 "3", "--strips", "8", "--threads", "1", "--out", str(out), "--float-out",
                 str(flt), "--quiet"])
    assert code == 0
    assert capsys.readouterr().err == ""  # --quiet: neither the thread nor the quantiser note
    qm = load_quantized(out)
    latent, variant, info = load_float_model(flt)
    assert variant == "mccnn4-slim" and info["config"]["qat"] == "base.npz"
    assert info["config"]["sign_fraction"] == 1.0 and "QAT" in qm.calibration
    weights, biases = integer_network(build_qat_net(latent, qm))
    for a, b in zip(qm.weights + qm.biases, weights + biases):
        assert_array_equal(a, b)
    code = main(["train", "--qat", str(base), "--variant", "single9x9", "--data", str(root),
                 "--out", str(tmp_path / "x.npz")])
    assert code == 2 and "mccnn4-slim" in capsys.readouterr().err


@pytest.mark.skipif(DATA is None, reason="shared Middlebury data not found (../shared/data)")
def test_qat_forward_equals_the_integer_reference_on_a_real_scene():
    """A QAT network moved off the quantiser's point, on both views of a training scene
    (2006 Aloe, cropped to keep the int64 reference fast)."""
    scene = load_scene(find_scene(DATA / "middlebury2006_third" / "Aloe"))
    views = [to_grey(scene[v])[100:180, 150:270].copy() for v in ("left", "right")]
    model = _model(9, ((1, 8, 5), (8, 16, 3), (16, 32, 3)))
    model, qm = quantize_twin(model, views, QuantizerConfig(n_samples=2000), progress=False)
    net = build_qat_net(model, qm, torch.float64)
    with torch.no_grad():
        for b in net.biases:
            b.add_(0.02)
    weights, biases = integer_network(net)
    args = (weights, biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    for img in views:
        assert_array_equal(_accumulators(net, img), int_forward_ref(img, *args))


def test_the_frozen_arithmetic_moves_with_the_network_and_stays_out_of_checkpoints():
    """The scales and multiply-shift pairs are buffers: ``.to()`` moves them with the weights
    (a GPU run), and a checkpoint (the state dict) holds the trained weights and biases alone."""
    import torch

    model = _model(5)
    model, qm = _quantized(model)
    net = build_qat_net(model, qm)
    assert set(net.state_dict()) == {f"{k}.{i}" for k in ("weights", "biases")
                                     for i in range(len(model.weights))}
    assert len(net.scale) == len(model.weights) and len(net.mult) == len(qm.mult)
    moved = net.to(torch.float64)  # floating buffers follow the module like its parameters
    assert all(s.dtype == torch.float64 for s in moved.scale + moved.mult + moved.pow)
    x = torch.zeros(1, 1, 12, 12, dtype=torch.float32)
    assert torch.isfinite(build_qat_net(model, qm)(x)).all()
