"""Integer inference: numba kernels == numpy int64 emulation bit for bit; one layer == the NNA."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.nna.conv import cnn_accumulators
from stereosim.quant.intconv import (
    check_network,
    int_forward,
    int_forward_ref,
    mul_shift,
    mul_shift_ref,
)
from stereosim.sim.errors import ConfigError


def _network(seed, channels, k_sizes, z_bits=8, bias_range=5000):
    """Random int8 weights with -128 and 127 present, random biases and m/h over the full range."""
    rng = np.random.default_rng(seed)
    weights, biases, mult, shift = [], [], [], []
    c_in = 1
    for layer, (c_out, k) in enumerate(zip(channels, k_sizes)):
        w = rng.integers(-128, 128, size=(c_out, c_in, k, k), dtype=np.int8)
        w.flat[0] = -128
        w.flat[-1] = 127
        weights.append(w)
        biases.append(rng.integers(-bias_range, bias_range + 1, size=c_out).astype(np.int32))
        if layer < len(channels) - 1:
            top = 2**z_bits - 1
            mult.append(rng.integers(0, top + 1, size=c_out).astype(np.int32))
            # mostly useful shifts (outputs not all 0 or 127), plus the range's extremes
            h = rng.integers(min(8, top), min(20, top) + 1, size=c_out).astype(np.int32)
            h[0] = top
            if c_out > 1:
                h[1] = 0
            shift.append(h)
        c_in = c_out
    return weights, biases, mult, shift


def _image(shape, seed):
    return np.random.default_rng(seed).integers(0, 256, size=shape, dtype=np.uint8)


@pytest.mark.parametrize(
    "channels, k_sizes",
    [((32,), (9,)), ((4, 32), (3, 3)), ((4, 4, 8, 32), (3, 3, 3, 3)), ((3, 5, 2, 7), (5, 1, 3, 3))],
)
@pytest.mark.parametrize("shape", [(17, 23), (1, 1), (9, 4)])
def test_numba_equals_numpy_emulation(channels, k_sizes, shape):
    weights, biases, mult, shift = _network(len(channels) * 7 + shape[0], channels, k_sizes)
    img = _image(shape, shape[1])
    fast = int_forward(img, weights, biases, mult, shift, 128)
    ref = int_forward_ref(img, weights, biases, mult, shift, 128)
    assert fast.dtype == np.int32 and fast.shape == shape + (channels[-1],)
    assert_array_equal(fast, ref)


def test_intermediate_activations_are_not_trivial():
    """Guards the bit-exact test above: the requantised activations must take many values."""
    weights, biases, mult, shift = _network(3, (4, 32), (3, 3))
    img = _image((31, 29), 5)
    one = int_forward(img, weights[:1], biases[:1], [], [], 128).transpose(2, 0, 1)
    act = np.clip(mul_shift_ref(one, mult[0][:, None, None], shift[0][:, None, None]), 0, 127)
    assert len(np.unique(act[2:])) > 20


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n_layers=st.integers(1, 4),
    height=st.integers(1, 13),
    width=st.integers(1, 13),
    seed=st.integers(0, 2**16),
    offset=st.integers(0, 255),
    z_bits=st.integers(1, 16),
)
def test_numba_equals_numpy_hypothesis(n_layers, height, width, seed, offset, z_bits):
    rng = np.random.default_rng(seed)
    channels = tuple(int(c) for c in rng.integers(1, 6, size=n_layers))
    k_sizes = tuple(int(k) for k in rng.choice([1, 3, 5], size=n_layers))
    weights, biases, mult, shift = _network(seed, channels, k_sizes, z_bits=z_bits)
    img = _image((height, width), seed + 1)
    assert_array_equal(
        int_forward(img, weights, biases, mult, shift, offset, z_bits),
        int_forward_ref(img, weights, biases, mult, shift, offset, z_bits),
    )


@pytest.mark.parametrize("shape", [(25, 31), (9, 9), (3, 40)])
@pytest.mark.parametrize("offset", [0, 128, 255])
def test_single_layer_equals_nna_accumulators(shape, offset):
    weights, biases, _, _ = _network(11, (32,), (9,), bias_range=100000)
    img = _image(shape, 2)
    ours = int_forward(img, weights, biases, [], [], offset)
    assert_array_equal(ours, cnn_accumulators(img, weights[0][:, 0], biases[0], offset))


def test_mul_shift_is_floor_division():
    cases = [(-3, 1, 1, -2), (3, 1, 1, 1), (-1, 1, 5, -1), (7, 3, 2, 5), (-7, 3, 2, -6),
             (2**31 - 1, 65535, 10, (2**31 - 1) * 65535 // 1024), (-5, 255, 63, -1),
             (-5, 255, 255, -1), (5, 255, 200, 0), (12345, 0, 3, 0)]  # fmt: skip
    for acc, m, h, expected in cases:
        assert int(mul_shift(acc, m, h)) == expected, (acc, m, h)
        assert int(mul_shift_ref(acc, m, h)) == expected, (acc, m, h)


def test_check_network_refuses_bad_networks():
    weights, biases, mult, shift = _network(1, (4, 8), (3, 3))
    check_network(weights, biases, mult, shift, 128)
    with pytest.raises(ConfigError, match="mult"):
        check_network(weights, biases, [mult[0] + 256], shift, 128)
    with pytest.raises(ConfigError, match="shift"):
        check_network(weights, biases, mult, [shift[0] - 300], 128)
    with pytest.raises(ConfigError, match="input channels"):
        check_network(weights[::-1], biases[::-1], mult, shift, 128)
    with pytest.raises(ConfigError, match="int32"):
        big = [biases[0], np.full(8, 2**31 - 10, dtype=np.int32)]
        check_network(weights, big, mult, shift, 128)
    with pytest.raises(ConfigError, match="int8"):
        check_network([w.astype(np.int16) for w in weights], biases, mult, shift, 128)
    with pytest.raises(ConfigError, match="z_bits"):
        check_network(weights, biases, mult, shift, 128, z_bits=17)
    with pytest.raises(ConfigError, match="input_offset"):
        check_network(weights, biases, mult, shift, 256)
    with pytest.raises(ConfigError, match="1..4 layers"):
        check_network(weights * 3, biases * 3, mult * 5, shift * 5, 128)
