"""The quantizer: the searches really minimise, the whole model agrees, the artifact round-trips."""

import dataclasses
import io
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from stereosim.core.errors import ConfigError
from stereosim.nna.conv.conv import cnn_accumulators
from stereosim.nna.conv.weights import load_layer, load_weights
from stereosim.quant.artifact import load_quantized, save_quantized, to_nna_weights
from stereosim.quant.distances import DISTANCES, l1
from stereosim.quant.intconv import int_forward, int_layer, mul_shift_ref, requantize
from stereosim.quant.quantizer import (
    FloatModel,
    QuantizerConfig,
    equalize_channels,
    float_forward,
    float_input,
    float_layer,
    quantize,
    scale_grid,
    search_channel_scale,
    search_mul_shift,
)

INPUT_SCALE = 1 / 64  # a power of two, so float inputs are exact


def _smooth_images(n, shape, seed, even=False):
    """Textured uint8 images (integrated noise); ``even`` keeps every pixel value even."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        a = rng.normal(size=shape).cumsum(0).cumsum(1)
        a += rng.normal(scale=a.std() * 0.3, size=shape)
        a = (a - a.min()) / (a.max() - a.min()) * 255
        img = a.astype(np.uint8)
        out.append(img & 0xFE if even else img)
    return out


def _planted_layer(seed, n_channels=4, k_size=5):
    """int8 weights with max |w| = 127 (reached at +127), odd biases; float = int / scale."""
    rng = np.random.default_rng(seed)
    w_int = rng.integers(-127, 128, size=(n_channels, 1, k_size, k_size)).astype(np.int8)
    w_int[:, 0, 0, 0] = 127
    b_int = (2 * rng.integers(-3000, 3000, size=n_channels) + 1).astype(np.int32)
    s0 = np.array([250.0, 1000.0, 31.75, 4096.0][:n_channels])
    acc_scale0 = s0 / INPUT_SCALE  # a_0 = 1 / input_scale
    w = w_int / s0[:, None, None, None]
    b = b_int / acc_scale0
    return w_int, b_int, s0, w, b


# --- the scale search ---------------------------------------------------------------------------


@pytest.mark.parametrize("distance", ["rms", "l1"])
def test_planted_scale_is_found_exactly(distance):
    """W = W_int / s0: the search returns s0, W_int and B_int, and the integer output equals the
    s0-scaled float output (zero distance, all signs equal; even inputs and odd biases keep every
    accumulator away from 0)."""
    w_int, b_int, s0, w, b = _planted_layer(0)
    images = _smooth_images(2, (40, 50), 1, even=True)
    model = FloatModel(weights=(w,), biases=(b,), input_offset=128, input_scale=INPUT_SCALE)
    config = QuantizerConfig(distance=distance, n_samples=3000, seed=5)
    qm = quantize(model, images, config)
    assert_allclose(qm.weight_scales[0], s0, rtol=1e-9)
    assert_array_equal(qm.weights[0], w_int)
    assert_array_equal(qm.biases[0], b_int)
    assert qm.sign_agreement == 1.0
    assert qm.acc_rms < 1e-6
    acc = int_forward(images[0], qm.weights, qm.biases, [], [], 128)
    scaled = float_forward(model, images[0]) * (s0 / INPUT_SCALE)
    assert_allclose(acc, scaled, atol=1e-6)


def test_planted_scale_hamming_gives_zero_distance():
    w_int, b_int, s0, w, b = _planted_layer(1)
    images = _smooth_images(2, (40, 50), 2, even=True)
    model = FloatModel(weights=(w,), biases=(b,), input_offset=128, input_scale=INPUT_SCALE)
    qm = quantize(model, images, QuantizerConfig(distance="hamming", n_samples=3000))
    assert qm.sign_agreement == 1.0


def _brute_force(w_flat, bias, patches, float_out, act_scale, x_max, distance, n_steps):
    """Every candidate of the grid, written out one at a time with int64 arithmetic."""
    m = np.abs(w_flat).max()
    primary, secondary, candidates = [], [], []
    for k in range(n_steps, 0, -1):
        s = 127 / (k * (m / n_steps))
        wq = np.clip(np.rint(w_flat * s), -128, 127).astype(np.int64)
        limit = 2**31 - 1 - np.abs(wq).sum() * x_max
        bq = int(np.clip(np.rint(bias * s * act_scale), -limit, limit))
        acc = patches.astype(np.int64) @ wq + bq
        target = float_out * (s * act_scale)
        primary.append(float(DISTANCES[distance](target, acc)))
        secondary.append(float(l1(target, acc)))
        candidates.append((s, wq, bq))
    return np.array(primary), np.array(secondary), candidates


@pytest.mark.parametrize("distance", list(DISTANCES))
def test_scale_search_is_the_argmin_over_the_grid(distance):
    rng = np.random.default_rng(7)
    w_flat = rng.normal(0, 0.05, size=9)
    # one large weight on a quiet input: saturating it beats the min/max mapping (paper's example)
    w_flat[3] = 1.0
    patches = rng.integers(-255, 256, size=(400, 9))
    patches[:, 3] //= 32
    x_float = patches / 64.0 + rng.normal(0, 0.01, size=patches.shape)  # float input != X_dot
    float_out = x_float @ w_flat + 0.1
    n_steps = 1000
    scale, w_int, b_int, dist, all_d = search_channel_scale(
        w_flat, 0.1, patches, float_out, 64.0, 255, distance, n_steps, chunk=97
    )
    primary, secondary, candidates = _brute_force(
        w_flat, 0.1, patches, float_out, 64.0, 255, distance, n_steps
    )
    assert_allclose(all_d, primary, rtol=1e-9, atol=1e-12)
    assert dist == pytest.approx(primary.min(), rel=1e-9, abs=1e-12)
    best = np.flatnonzero(np.isclose(primary, primary.min(), rtol=1e-9, atol=1e-12))
    best = best[np.isclose(secondary[best], secondary[best].min(), rtol=1e-9, atol=1e-12)][0]
    assert scale == pytest.approx(candidates[best][0], rel=1e-12)
    assert_array_equal(w_int, candidates[best][1])
    assert b_int == candidates[best][2]
    assert np.isin(scale, scale_grid(1.0, n_steps))
    if distance != "hamming":
        # the naive min/max mapping (first candidate) is beaten, so the argmin is not trivial
        assert dist < primary[0]


@settings(max_examples=25, deadline=None)
@given(
    n_taps=st.integers(1, 60),
    s0=st.floats(0.5, 5000.0),
    act_scale=st.sampled_from([1.0, 64.0, 0.25]),
    distance=st.sampled_from(["rms", "l1"]),
    seed=st.integers(0, 10**6),
)
def test_planted_channel_hypothesis(n_taps, s0, act_scale, distance, seed):
    """Any planted channel (max |W_int| = 127) is recovered exactly by the per-channel search."""
    rng = np.random.default_rng(seed)
    w_int = rng.integers(-127, 128, size=n_taps)
    w_int[rng.integers(n_taps)] = 127 * rng.choice([-1, 1])
    b_int = int(rng.integers(-10000, 10001))
    patches = rng.integers(-255, 256, size=(200, n_taps))
    float_out = (patches / act_scale) @ (w_int / s0) + b_int / (s0 * act_scale)
    scale, found_w, found_b, dist, _ = search_channel_scale(
        w_int / s0, b_int / (s0 * act_scale), patches, float_out, act_scale, 255, distance
    )
    assert scale == pytest.approx(s0, rel=1e-9)
    assert_array_equal(found_w, w_int)
    assert found_b == b_int
    assert dist < 1e-6


def test_grid_covers_zero_to_max_with_fine_step():
    grid = scale_grid(0.5, 1000)
    spans = 127 / grid  # the S values
    assert spans[0] == pytest.approx(0.5) and spans[-1] == pytest.approx(0.5 / 1000)
    assert_allclose(-np.diff(spans), 0.5 / 1000)


# --- the multiply-shift search ------------------------------------------------------------------


@settings(max_examples=20, deadline=None)
@given(m0=st.integers(0, 255), h0=st.integers(0, 40), seed=st.integers(0, 1000))
def test_planted_mul_shift_gives_zero_error(m0, h0, seed):
    acc = np.random.default_rng(seed).integers(-(2**20), 2**20, size=300)
    target = np.clip(mul_shift_ref(acc, m0, h0), 0, 127).astype(np.float64)
    m, h, err = search_mul_shift(acc, target, z_bits=8)
    assert err == 0.0
    assert_array_equal(np.clip(mul_shift_ref(acc, m, h), 0, 127), target)
    assert 0 <= m <= 255 and 0 <= h <= 255


def test_mul_shift_search_is_exhaustive():
    rng = np.random.default_rng(3)
    acc = rng.integers(-2000, 6000, size=200)
    target = acc * 0.0123 + rng.normal(0, 2, size=200)
    z_bits = 5
    errors = np.empty((32, 32))
    for m in range(32):
        for h in range(32):
            out = np.clip(mul_shift_ref(acc, m, h), 0, 127)
            errors[m, h] = np.mean(np.abs(np.clip(target, 0, 127) - out))
    m, h, err = search_mul_shift(acc, target, z_bits)
    assert err == pytest.approx(errors.min(), rel=1e-12)
    assert errors[m, h] == pytest.approx(errors.min(), rel=1e-9)


# --- the whole model ----------------------------------------------------------------------------


def _two_layer_model(seed):
    rng = np.random.default_rng(seed)
    w0 = rng.normal(0, 0.3, size=(4, 1, 3, 3))
    w1 = rng.normal(0, 0.3, size=(8, 4, 3, 3))
    b0 = rng.normal(0, 0.05, size=4)
    b1 = rng.normal(0, 0.05, size=8)
    return FloatModel(weights=(w0, w1), biases=(b0, b1), input_offset=100, input_scale=INPUT_SCALE)


def test_two_layer_model_agrees_and_figures_are_honest():
    model = _two_layer_model(4)
    images = _smooth_images(2, (45, 37), 8)
    qm = quantize(model, images, QuantizerConfig(n_samples=4000), variant="test")
    assert qm.n_layers == 2 and qm.mult[0].shape == (4,) and qm.shift[0].shape == (4,)
    assert qm.distances == ("rms", "hamming")
    bits = []
    for img in images:
        acc = int_forward(img, qm.weights, qm.biases, qm.mult, qm.shift, qm.input_offset)
        bits.append((acc > 0) == (float_forward(model, img) > 0))
    agree = float(np.mean(np.concatenate([b.ravel() for b in bits])))
    assert agree == pytest.approx(qm.sign_agreement, abs=1e-12)
    assert agree > 0.95
    # the hidden activations use the int8 range, neither all zero nor all saturated
    assert np.all(qm.act_scales > 0)


def _hidden_relu(model, images, layer=0):
    """ReLU of ``layer``'s float output, (C, pixels of every image)."""
    maps = []
    for im in images:
        x = float_input(model, im)
        for lay in range(layer + 1):
            x = np.maximum(float_layer(x, model.weights[lay], model.biases[lay]), 0.0)
        maps.append(x.reshape(x.shape[0], -1))
    return np.concatenate(maps, axis=1)


@pytest.mark.parametrize("q", [0.9999, 0.99, 0.9])
def test_the_hidden_activation_scale_maps_the_chosen_quantile_to_127(q):
    """With every pixel sampled, layer 1's input scale is 127 over the q-quantile of ReLU of
    layer 0's float output over all pixels and channels (the module docstring's rule); with
    the channels equalised, the same rule on the equalised model's outputs."""
    model = _two_layer_model(6)
    images = _smooth_images(2, (21, 19), 3)
    relu = _hidden_relu(model, images)
    qm = quantize(model, images, QuantizerConfig(n_samples=10**6, act_quantile=q,
                                                 equalize=False))
    assert qm.act_scales[0] == pytest.approx(1.0 / INPUT_SCALE)
    assert qm.act_scales[1] == pytest.approx(127.0 / np.quantile(relu.T, q), rel=1e-12)
    config = QuantizerConfig(n_samples=10**6, act_quantile=q)
    eq = quantize(model, images, config)
    relu_eq = _hidden_relu(equalize_channels(model, images, config), images)
    assert eq.act_scales[1] == pytest.approx(127.0 / np.quantile(relu_eq.T, q), rel=1e-12)


def _three_layer_model(seed, dead=None):
    """Three layers whose hidden channels span ranges 1000x apart (and one channel of layer 0
    never positive when ``dead`` is given)."""
    rng = np.random.default_rng(seed)
    w0 = rng.normal(0, 0.3, size=(4, 1, 3, 3)) * np.array([1.0, 0.03, 0.3, 0.001])[:, None,
                                                                                   None, None]
    w1 = rng.normal(0, 0.3, size=(6, 4, 3, 3)) * np.array([1.0, 30.0, 3.0, 1000.0])[None, :,
                                                                                    None, None]
    w2 = rng.normal(0, 0.3, size=(8, 6, 3, 3))
    b0 = rng.normal(0, 0.05, size=4) * np.array([1.0, 0.03, 0.3, 0.001])
    if dead is not None:
        w0[dead] = 0.0
        b0[dead] = -1.0
    b1 = rng.normal(0, 0.05, size=6)
    b2 = rng.normal(0, 0.05, size=8)
    return FloatModel(weights=(w0, w1, w2), biases=(b0, b1, b2), input_offset=128,
                      input_scale=INPUT_SCALE)


@pytest.mark.parametrize("dead", [None, 2])
def test_equalised_channels_keep_the_float_function_on_one_range(dead):
    """Every layer's pre-activations are the model's own (ReLU is positively homogeneous);
    every hidden channel that is ever positive has its quantile at the largest one, a channel
    never positive keeps its weights; a one-layer model is returned as it is."""
    model = _three_layer_model(11, dead)
    images = _smooth_images(2, (33, 29), 5)
    config = QuantizerConfig(n_samples=10**6)
    eq = equalize_channels(model, images, config)
    for im in images:
        assert_allclose(float_forward(eq, im), float_forward(model, im), rtol=1e-9, atol=1e-12)
    for layer in range(2):
        q = np.quantile(_hidden_relu(eq, images, layer), config.act_quantile, axis=1)
        live = q > 0
        assert_allclose(q[live], q[live].max(), rtol=1e-9)
        assert q[live].max() == pytest.approx(
            np.quantile(_hidden_relu(model, images, layer), config.act_quantile, axis=1).max())
    if dead is not None:
        assert_array_equal(eq.weights[0][dead], model.weights[0][dead])
        assert eq.biases[0][dead] == model.biases[0][dead]
        row_alpha = eq.biases[1] / model.biases[1]  # layer 1's own outputs' rescaling
        assert_allclose(eq.weights[1][:, dead],
                        model.weights[1][:, dead] * row_alpha[:, None, None], rtol=1e-12)
    one = FloatModel(weights=model.weights[:1], biases=model.biases[:1], input_offset=128,
                     input_scale=INPUT_SCALE)
    assert equalize_channels(one, images, config) is one
    assert quantize(one, images, config).weights[0].tobytes() == quantize(
        one, images, dataclasses.replace(config, equalize=False)).weights[0].tobytes()


def test_equalised_channels_use_the_int8_range_and_agree_more():
    """A hidden channel 1000x below the layer's largest uses at most a couple of int8 levels on
    one range a layer; equalised, every live channel reaches the top of the range, and the
    descriptor bits agree with the float signs more."""
    model = _three_layer_model(12)
    images = _smooth_images(2, (40, 36), 6)
    flat = quantize(model, images, QuantizerConfig(n_samples=6000, equalize=False))
    eq = quantize(model, images, QuantizerConfig(n_samples=6000))
    for qm, top in ((flat, None), (eq, 100)):
        acc = [int_layer(im.astype(np.int32)[None] - 128, qm.weights[0], qm.biases[0])
               for im in images]
        act = np.concatenate([requantize(a, qm.mult[0], qm.shift[0]).reshape(4, -1)
                              for a in acc], axis=1)
        if top is None:
            assert act[3].max() <= 2
        else:
            assert act.max(axis=1).min() >= top
    assert eq.sign_agreement > flat.sign_agreement


def test_quantize_is_deterministic():
    """Same seed, same result; a 1x1 image that receives no samples does not break anything."""
    model = _two_layer_model(5)
    images = _smooth_images(1, (30, 30), 9) + [np.full((1, 1), 7, dtype=np.uint8)]
    config = QuantizerConfig(n_samples=500, seed=0)  # seed 0 draws nothing from the 1x1 image
    a = quantize(model, images, config)
    b = quantize(model, images, config)
    arrays_a = a.weights + a.biases + a.mult + a.shift
    arrays_b = b.weights + b.biases + b.mult + b.shift
    for x, y in zip(arrays_a, arrays_b):
        assert_array_equal(x, y)


def test_config_is_validated():
    with pytest.raises(ConfigError, match="n_steps"):
        QuantizerConfig(n_steps=100)
    with pytest.raises(ConfigError, match="unknown distance"):
        QuantizerConfig(distance="cosine")
    with pytest.raises(ConfigError, match="z_bits"):
        QuantizerConfig(z_bits=0)
    with pytest.raises(ConfigError, match="float weights"):
        FloatModel(weights=(np.zeros((2, 3, 3, 3)),), biases=(np.zeros(2),), input_offset=0,
                   input_scale=1.0)  # fmt: skip


# --- the artifact -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def single():
    w_int, b_int, s0, w, b = _planted_layer(2)
    model = FloatModel(weights=(w,), biases=(b,), input_offset=128, input_scale=INPUT_SCALE)
    return quantize(model, _smooth_images(1, (30, 30), 3), QuantizerConfig(n_samples=800))


@pytest.fixture(scope="module")
def double():
    images = _smooth_images(1, (30, 30), 4)
    return quantize(_two_layer_model(6), images, QuantizerConfig(n_samples=800))


def _same(a, b):
    for field in ("weights", "biases", "mult", "shift", "weight_scales"):
        for x, y in zip(getattr(a, field), getattr(b, field)):
            assert_array_equal(x, y)
    assert_array_equal(a.act_scales, b.act_scales)
    for field in ("input_offset", "input_scale", "z_bits", "distances", "sign_agreement",
                  "acc_rms", "variant", "calibration"):  # fmt: skip
        assert getattr(a, field) == getattr(b, field), field


@pytest.mark.parametrize("which", ["single", "double"])
def test_artifact_round_trip(which, request, tmp_path):
    qm = request.getfixturevalue(which)
    path = tmp_path / "q.npz"
    save_quantized(path, qm)
    _same(qm, load_quantized(path))


def test_single_layer_artifact_is_an_nna_weight_file(single, tmp_path):
    path = tmp_path / "q.npz"
    save_quantized(path, single)
    weights, bias, offset = load_weights(path)
    assert_array_equal(weights, single.weights[0][:, 0])
    assert (weights, bias, offset)[2] == 128
    w2, b2, o2 = to_nna_weights(single)
    assert_array_equal(w2, weights) and o2 == offset
    assert_array_equal(b2, bias)
    img = _smooth_images(1, (21, 19), 9)[0]
    assert_array_equal(
        cnn_accumulators(img, weights, bias, offset),
        int_forward(img, single.weights, single.biases, [], [], offset),
    )


def test_to_nna_weights_refuses_multilayer(double):
    with pytest.raises(ConfigError, match="one layer"):
        to_nna_weights(double)


def _rewrite(path, out, **changes):
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files}
    for key, value in changes.items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    with open(out, "wb") as f:
        np.savez(f, **arrays)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"weights_1": None}, "lacks the field 'weights_1'"),
        ({"mult_0": None}, "lacks the field 'mult_0'"),
        ({"weights_0": np.zeros((4, 1, 3), dtype=np.int8)}, "shape"),
        ({"bias_1": np.zeros(7, dtype=np.int32)}, "shape"),
        ({"weights_0": np.full((4, 1, 3, 3), 200, dtype=np.int16)}, "outside int8"),
        ({"weights_0": np.zeros((4, 1, 3, 3))}, "integers"),
        ({"mult_0": np.full(4, 256, dtype=np.int32)}, "mult"),
        ({"shift_0": np.full(4, -1, dtype=np.int32)}, "shift"),
        ({"input_offset": np.int32(300)}, "input_offset"),
        ({"z_bits": np.int32(40)}, "z_bits"),
        ({"weight_scales_0": np.array([1.0, -1.0, 1.0, 1.0])}, "weight_scales"),
        ({"distances": np.array(["rms", "cosine"])}, "unknown distance"),
        ({"format": np.array("other")}, "format"),
        ({"n_layers": np.int32(3)}, "lacks the field"),
    ],
)
def test_bad_artifacts_are_refused(double, tmp_path, changes, message):
    good = tmp_path / "good.npz"
    save_quantized(good, double)
    bad = tmp_path / "bad.npz"
    _rewrite(good, bad, **changes)
    with pytest.raises(ConfigError, match=message) as info:
        load_quantized(bad)
    assert "\n" not in str(info.value)


def test_missing_and_garbage_files_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_quantized(tmp_path / "none.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(ConfigError, match="not a readable"):
        load_quantized(junk)


def test_nna_keys_must_match(single, tmp_path):
    good = tmp_path / "good.npz"
    save_quantized(good, single)
    bad = tmp_path / "bad.npz"
    _rewrite(good, bad, bias=np.zeros(4, dtype=np.int32))
    with pytest.raises(ConfigError, match="disagree"):
        load_quantized(bad)


def test_artifacts_are_read_within_bounds(single, tmp_path):
    good = tmp_path / "good.npz"
    save_quantized(good, single)
    # A member that would unpickle objects is refused from its header, before anything loads.
    bad = tmp_path / "objects.npz"
    _rewrite(good, bad)
    with zipfile.ZipFile(bad, "a") as archive:
        buf = io.BytesIO()
        np.lib.format.write_array(buf, np.array([print], dtype=object), allow_pickle=True)
        archive.writestr("extra.npy", buf.getvalue())
    with pytest.raises(ConfigError, match=r"objects.npz' member 'extra.npy' holds Python objects"):
        load_quantized(bad)
    # A field of the wrong kind is a ConfigError, not numpy's ValueError.
    _rewrite(good, bad, act_scales=np.array(["a"]))
    with pytest.raises(ConfigError, match=r"act_scales must be numbers, got <U1"):
        load_quantized(bad)


def test_a_single_layer_artifact_with_a_kernel_too_large_for_the_nna(single, tmp_path):
    w = np.zeros((4, 1, 65, 65), np.int8)
    w[:, 0, 32, 32] = 1
    wide = dataclasses.replace(single, weights=(w,))
    path = tmp_path / "wide.npz"
    save_quantized(path, wide)  # a valid integer network ...
    assert load_quantized(path).weights[0].shape == (4, 1, 65, 65)
    with pytest.raises(ConfigError, match=r"wide.npz': weights kernel size 65x65 is larger"):
        load_layer(path)  # ... but not a layer the NNA can run
