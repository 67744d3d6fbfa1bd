"""NNA descriptor layer: kernel == naive reference, accumulators == an independent numpy sum,
and the weight files."""

import dataclasses
import io
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.lib.stride_tricks import sliding_window_view
from numpy.testing import assert_array_equal

from stereosim.core.config import NnaConfig
from stereosim.core.errors import ConfigError, InputError
from stereosim.nna.conv.conv import (
    MAX_KERNEL_SIZE,
    check_layer,
    cnn_accumulators,
    cnn_descriptor,
    cnn_descriptor_ref,
)
from stereosim.nna.conv.weights import load_layer, load_weights, placeholder_weights, save_weights


def _layer(seed, n_channels=32, k_size=9, bias_range=20000):
    """Random int8 weights with both extremes present, random int32 bias."""
    rng = np.random.default_rng(seed)
    weights = rng.integers(-128, 128, size=(n_channels, k_size, k_size), dtype=np.int8)
    weights.flat[0] = -128
    weights.flat[-1] = 127
    bias = rng.integers(-bias_range, bias_range + 1, size=n_channels).astype(np.int32)
    return weights, bias


def _image(shape, seed):
    return np.random.default_rng(seed).integers(0, 256, size=shape, dtype=np.uint8)


def _numpy_accumulators(img, weights, bias, input_offset):
    """Independent int64 computation: pad with edge replication, sum over sliding windows."""
    k_size = weights.shape[1]
    r = k_size // 2
    x_i64 = np.pad(img.astype(np.int64) - input_offset, r, mode="edge")
    windows = sliding_window_view(x_i64, (k_size, k_size))  # (H, W, K, K)
    return np.einsum("hwij,cij->hwc", windows, weights.astype(np.int64)) + bias.astype(np.int64)


def _pack_signs(acc):
    n_channels = acc.shape[-1]
    dtype = np.uint32 if n_channels <= 32 else np.uint64
    out = np.zeros(acc.shape[:2], dtype=dtype)
    for c in range(n_channels):
        out |= (acc[..., c] > 0).astype(dtype) << np.array(c, dtype=dtype)
    return out


@pytest.mark.parametrize("input_offset", [0, 128, 255])
@pytest.mark.parametrize("shape", [(1, 1), (5, 3), (3, 5), (31, 17)])
def test_descriptor_kernel_equals_ref(shape, input_offset):
    weights, bias = _layer(seed=shape[0] * 100 + shape[1] + input_offset)
    img = _image(shape, seed=input_offset)
    got = cnn_descriptor(img, weights, bias, input_offset)
    want = cnn_descriptor_ref(img, weights, bias, input_offset)
    assert got.dtype == np.uint32
    assert_array_equal(got, want)
    # Not a vacuous comparison: both signs occur on the larger images.
    if img.size > 100:
        assert got.any() and (~got).any()


@pytest.mark.parametrize(
    ("n_channels", "k_size"),
    # up to K = 21 the kernel sums in float32 (exact); K = 23 takes the int32 path
    [(1, 1), (7, 3), (32, 5), (33, 5), (64, 9), (3, 11), (3, 21), (2, 23)],
)
def test_other_layer_shapes(n_channels, k_size):
    weights, bias = _layer(seed=n_channels + k_size, n_channels=n_channels, k_size=k_size)
    img = _image((13, 10), seed=k_size)
    got = cnn_descriptor(img, weights, bias, 128)
    assert got.dtype == (np.uint32 if n_channels <= 32 else np.uint64)
    assert_array_equal(got, cnn_descriptor_ref(img, weights, bias, 128))
    acc = cnn_accumulators(img, weights, bias, 128)
    assert_array_equal(acc, _numpy_accumulators(img, weights, bias, 128))
    assert_array_equal(got, _pack_signs(acc))


@pytest.mark.parametrize("input_offset", [0, 128, 255])
@pytest.mark.parametrize("shape", [(1, 1), (5, 3), (31, 17), (40, 70)])
def test_accumulators_equal_numpy(shape, input_offset):
    weights, bias = _layer(seed=7 + input_offset)
    img = _image(shape, seed=11)
    acc = cnn_accumulators(img, weights, bias, input_offset)
    assert acc.dtype == np.int32 and acc.shape == shape + (32,)
    assert_array_equal(acc, _numpy_accumulators(img, weights, bias, input_offset))
    assert_array_equal(cnn_descriptor(img, weights, bias, input_offset), _pack_signs(acc))


def test_largest_accumulator_is_exact():
    # Every tap at its extreme product: -128 * (0 - 255) = 32640, 81 taps, plus the largest
    # bias check_layer accepts for 9x9: the int32 accumulator must reach 2**31 - 1 exactly.
    weights = np.full((2, 9, 9), -128, dtype=np.int8)
    weights[1] = 127  # 127 * -255 * 81, negative
    limit = 2**31 - 1 - 81 * 32640
    bias = np.array([limit, -limit], dtype=np.int32)
    img = np.zeros((3, 4), dtype=np.uint8)
    acc = cnn_accumulators(img, weights, bias, 255)
    assert (acc[..., 0] == 2**31 - 1).all()
    assert (acc[..., 1] == -limit - 127 * 255 * 81).all()
    assert_array_equal(cnn_descriptor(img, weights, bias, 255), np.full((3, 4), 1, np.uint32))
    with pytest.raises(ConfigError, match="overflow"):
        check_layer(weights, np.array([limit + 1, 0], dtype=np.int32), 255)


@pytest.mark.parametrize("k_size", [9, 21, 23])
def test_threshold_at_the_largest_tap_sums(k_size):
    # Tap sums at their extreme, +-K*K*32640 (14.4 million for K = 21, just under 2**24, the
    # limit of exact float32 integers), with the bias set so the accumulator is exactly 0, 1 or
    # -1: the float32 lanes (K <= 21) and the int32 path (K = 23) must both see the sign.
    extreme = k_size * k_size * 32640
    weights = np.full((6, k_size, k_size), -128, dtype=np.int8)
    weights[3:] = 127  # 127 * -255 per tap: -K*K*32385
    low = k_size * k_size * 127 * 255
    bias = np.array([-extreme, 1 - extreme, -1 - extreme, low, low + 1, low - 1], np.int32)
    img = np.zeros((4, 5), dtype=np.uint8)
    acc = cnn_accumulators(img, weights, bias, 255)
    assert_array_equal(acc[0, 0], [0, 1, -1, 0, 1, -1])
    expected = np.full((4, 5), 0b010010, np.uint32)
    assert_array_equal(cnn_descriptor(img, weights, bias, 255), expected)
    assert_array_equal(cnn_descriptor(img, weights, bias, 255),
                       cnn_descriptor_ref(img, weights, bias, 255))


def test_zero_accumulator_gives_zero_bit():
    # Threshold is strict: acc == 0 -> bit 0; acc == 1 -> bit 1.
    weights = np.zeros((2, 3, 3), dtype=np.int8)
    bias = np.array([0, 1], dtype=np.int32)
    desc = cnn_descriptor(_image((4, 4), 0), weights, bias, 0)
    assert_array_equal(desc, np.full((4, 4), 0b10, np.uint32))


def test_non_contiguous_input():
    weights, bias = _layer(seed=3)
    img = _image((12, 30), seed=4)[:, ::3]
    assert_array_equal(
        cnn_descriptor(img, weights, bias, 100),
        cnn_descriptor_ref(np.ascontiguousarray(img), weights, bias, 100),
    )


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    height=st.integers(1, 12),
    width=st.integers(1, 12),
    n_channels=st.integers(1, 64),
    k_size=st.integers(0, 5).map(lambda i: 2 * i + 1),
    input_offset=st.integers(0, 255),
    seed=st.integers(0, 2**32 - 1),
)
def test_kernel_equals_ref_hypothesis(height, width, n_channels, k_size, input_offset, seed):
    weights, bias = _layer(seed, n_channels=n_channels, k_size=k_size)
    img = _image((height, width), seed)
    got = cnn_descriptor(img, weights, bias, input_offset)
    assert_array_equal(got, cnn_descriptor_ref(img, weights, bias, input_offset))
    acc = cnn_accumulators(img, weights, bias, input_offset)
    assert_array_equal(acc, _numpy_accumulators(img, weights, bias, input_offset))


def _good():
    weights, bias = _layer(seed=0, n_channels=4, k_size=3)
    return weights, bias, 128


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"weights": np.zeros((4, 3, 3), np.int16)}, "int8"),
        ({"weights": np.zeros((4, 3, 3), np.float32)}, "int8"),
        ({"weights": np.zeros((4, 3, 5), np.int8)}, "shape"),
        ({"weights": np.zeros((4, 9), np.int8)}, "shape"),
        ({"weights": np.zeros((4, 4, 4), np.int8)}, "odd"),
        ({"weights": np.zeros((65, 3, 3), np.int8)}, "channels"),
        ({"bias": np.zeros(4, np.int64)}, "int32"),
        ({"bias": np.zeros(5, np.int32)}, r"shape \(4,\)"),
        ({"input_offset": 256}, "0..255"),
        ({"input_offset": -1}, "0..255"),
        ({"input_offset": 1.5}, "int"),
    ],
)
def test_bad_layer_raises_config_error(change, message):
    weights, bias, input_offset = _good()
    args = {"weights": weights, "bias": bias, "input_offset": input_offset} | change
    with pytest.raises(ConfigError, match=message):
        cnn_descriptor(np.zeros((4, 4), np.uint8), **args)


@pytest.mark.parametrize(
    "img", [np.zeros((4, 4), np.float64), np.zeros((4, 4, 3), np.uint8), np.zeros((4, 0), np.uint8)]
)
def test_bad_image_raises_input_error(img):
    weights, bias, input_offset = _good()
    for fn in (cnn_descriptor, cnn_accumulators, cnn_descriptor_ref):
        with pytest.raises(InputError):
            fn(img, weights, bias, input_offset)


def test_placeholder_weights_deterministic_and_zero_sum():
    weights, bias, input_offset = placeholder_weights()
    again = placeholder_weights()
    assert_array_equal(weights, again[0])
    assert_array_equal(bias, again[1])
    assert input_offset == again[2] == 128
    assert weights.dtype == np.int8 and weights.shape == (32, 9, 9)
    assert bias.dtype == np.int32 and bias.shape == (32,) and not bias.any()
    assert (weights.astype(np.int64).sum(axis=(1, 2)) == 0).all()
    assert np.abs(weights.astype(np.int64)).max() <= 127
    assert 15 < weights.astype(np.float64).std() < 35  # roughly N(0, 24), not degenerate
    check_layer(weights, bias, input_offset)


def test_placeholder_weights_ignore_brightness_offset():
    weights, bias, input_offset = placeholder_weights()
    img = _image((30, 41), seed=9) // 2  # 0..127
    desc = cnn_descriptor(img, weights, bias, input_offset)
    assert_array_equal(cnn_descriptor(img + np.uint8(100), weights, bias, input_offset), desc)
    assert desc.any()


def test_save_load_round_trip(tmp_path):
    weights, bias = _layer(seed=5, n_channels=40, k_size=7)
    path = tmp_path / "layer.npz"
    save_weights(path, weights, bias, 17)
    got_w, got_b, got_offset = load_weights(path)
    assert got_w.dtype == np.int8 and got_b.dtype == np.int32
    assert_array_equal(got_w, weights)
    assert_array_equal(got_b, bias)
    assert got_offset == 17 and isinstance(got_offset, int)
    # A str path works too, and the defaults survive the trip.
    save_weights(str(path), *placeholder_weights())
    for a, b in zip(load_weights(str(path)), placeholder_weights(), strict=True):
        assert_array_equal(a, b)


def _write(path, **arrays):
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


@pytest.mark.parametrize(
    ("arrays", "message"),
    [
        ({"weights": np.zeros((4, 3, 3), np.int8), "bias": np.zeros(4, np.int32)}, "lacks"),
        (
            {
                "weights": np.zeros((4, 3, 3), np.float32),
                "bias": np.zeros(4, np.int32),
                "input_offset": np.int32(0),
            },
            "int8",
        ),
        (
            {
                "weights": np.zeros((4, 3, 2), np.int8),
                "bias": np.zeros(4, np.int32),
                "input_offset": np.int32(0),
            },
            "shape",
        ),
        (
            {
                "weights": np.zeros((4, 3, 3), np.int8),
                "bias": np.zeros(3, np.int32),
                "input_offset": np.int32(0),
            },
            "bias",
        ),
        (
            {
                "weights": np.zeros((4, 3, 3), np.int8),
                "bias": np.zeros(4, np.int32),
                "input_offset": np.int32(300),
            },
            "0..255",
        ),
        (
            {
                "weights": np.zeros((4, 3, 3), np.int8),
                "bias": np.zeros(4, np.int32),
                "input_offset": np.float32(1),
            },
            "integer scalar",
        ),
    ],
    ids=[
        "missing-key",
        "float-weights",
        "bad-shape",
        "bias-length",
        "offset-range",
        "offset-float",
    ],
)
def test_bad_weight_files_raise_config_error(tmp_path, arrays, message):
    path = _write(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ConfigError, match=message) as info:
        load_weights(path)
    assert "bad.npz" in str(info.value)


def test_missing_or_garbage_weight_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_weights(tmp_path / "nope.npz")
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"this is not an npz archive")
    with pytest.raises(ConfigError, match="not a readable"):
        load_weights(garbage)
    single = tmp_path / "single.npy"
    np.save(single, np.zeros((4, 3, 3), np.int8))
    with pytest.raises(ConfigError, match="single array"):
        load_weights(single)


# ---------------------------------------------------------------- the largest kernel


def test_kernel_size_is_capped_by_the_largest_line_buffer():
    # The window's rows must fit nna.line_buffer_rows, at most 64: the widest odd window is 63.
    (rows,) = [f for f in dataclasses.fields(NnaConfig) if f.name == "line_buffer_rows"]
    assert MAX_KERNEL_SIZE == 63 == rows.metadata["hi"] - 1
    bias = np.zeros(2, np.int32)
    weights, bias, _ = check_layer(np.ones((2, 63, 63), np.int8), bias, 0)
    assert weights.shape == (2, 63, 63)
    for k_size in (65, 99):
        with pytest.raises(ConfigError) as info:
            check_layer(np.ones((2, k_size, k_size), np.int8), bias, 0)
        assert str(info.value) == (
            f"weights kernel size {k_size}x{k_size} is larger than the 63x63 window the largest "
            "NNA line buffer can hold (nna.line_buffer_rows <= 64): use a smaller kernel"
        )


def test_a_99x99_weight_file_is_refused(tmp_path):
    path = _write(tmp_path / "k99.npz", weights=np.ones((32, 99, 99), np.int8),
                  bias=np.zeros(32, np.int32), input_offset=np.int32(128))  # fmt: skip
    for load in (load_weights, load_layer):
        with pytest.raises(ConfigError, match=r"k99.npz'?: weights kernel size 99x99 is larger"):
            load(path)


def test_a_weight_file_is_read_within_bounds(tmp_path):
    # A member whose .npy header claims 10**13 weights: refused from the header, naming the file.
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "|i1", "fortran_order": False, "shape": (10**13,)}
    )
    path = tmp_path / "lying.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("weights.npy", header.getvalue() + bytes(64))
        archive.writestr("bias.npy", b"")
    for load in (load_weights, load_layer):
        claim = r"weight file '.*lying.npz' .*claims \(10000000000000,\)"
        with pytest.raises(ConfigError, match=claim):
            load(path)
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(ConfigError, match=r"empty.npz' is empty; write it with nna.save_weights"):
        load_layer(empty)
