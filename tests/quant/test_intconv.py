"""Integer inference: the fast form (row bands, exact float lanes) == the numpy int64 definition
bit for bit, accumulators and descriptor signs, on random networks, odd sizes, band edges and the
worst-case sums that float32 lanes still hold."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.errors import ConfigError
from stereosim.nna.conv.conv import cnn_accumulators
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS, load_network
from stereosim.quant import vnni
from stereosim.quant.intconv import (
    F32_EXACT,
    _layer_rows,
    _pad_taps,
    _padded,
    check_network,
    int_forward,
    int_forward_ref,
    int_signs,
    lane_dtype,
    mul_shift,
    mul_shift_ref,
    signs_ref,
    tap_bound,
)


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
    """The network definition of one layer equals the NNA's fast one-layer accumulators."""
    weights, biases, _, _ = _network(11, (32,), (9,), bias_range=100000)
    img = _image(shape, 2)
    ours = int_forward_ref(img, weights, biases, [], [], offset)
    assert_array_equal(ours, cnn_accumulators(img, weights[0][:, 0], biases[0], offset))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n_layers=st.integers(1, 4),
    height=st.integers(1, 40),
    width=st.integers(1, 40),
    seed=st.integers(0, 2**16),
    offset=st.integers(0, 255),
    band_rows=st.sampled_from([1, 2, 3, 7, 32]),
)
def test_random_networks_descriptors_equal_the_definition(n_layers, height, width, seed, offset,
                                                          band_rows):
    """Networks of 1-4 layers, K in 1/3/5/7/9, 1-32 channels, on odd sizes (the replicate border
    at every layer's input) and bands of any height (each layer's halo across band edges): the
    fast descriptor and accumulators equal the int64 definition's."""
    rng = np.random.default_rng(seed)
    channels = tuple(int(c) for c in rng.integers(1, 33, size=n_layers))
    k_sizes = tuple(int(k) for k in rng.choice([1, 3, 5, 7, 9], size=n_layers))
    weights, biases, mult, shift = _network(seed, channels, k_sizes)
    img = _image((height, width), seed + 1)
    args = (weights, biases, mult, shift, offset)
    ref = int_forward_ref(img, *args)
    assert_array_equal(int_forward(img, *args, band_rows=band_rows), ref)
    assert_array_equal(int_signs(img, *args, band_rows=band_rows), signs_ref(ref))


@pytest.mark.parametrize("height", [31, 32, 33, 65])
def test_shipped_networks_on_band_edges(height):
    """The trained networks the repo ships, on frames a band longer or shorter than a band."""
    models = Path(__file__).resolve().parents[2] / "benchmarks" / "models"
    img = _image((height, 45), height)
    for path in (SHIPPED_WEIGHTS, models / "mccnn4.int8.npz", models / "mccnn4-slim.int8.npz"):
        net = load_network(path)
        assert_array_equal(int_signs(img, *net.args), signs_ref(int_forward_ref(img, *net.args)))


@pytest.mark.parametrize("lo, n, a, b, r", [(0, 5, 0, 5, 2), (3, 6, 3, 9, 4), (2, 7, 4, 6, 1),
                                             (0, 1, 0, 1, 3), (5, 4, 6, 8, 0)])
def test_padded_input_is_the_replicate_border(lo, n, a, b, r):
    """A layer's padded input (the helper every fast path uses): rows [a - r, b + r) and
    columns [-r, W - r + Kp - 1) of the rows given, coordinates clamped into them."""
    x = np.random.default_rng(r).integers(-255, 256, size=(3, n, 7)).astype(np.float32)
    k_cols = 3 * -(-(2 * r + 1) // 3)
    got = _padded(x, lo, a, b, r, k_cols, np.float64)
    rows = np.clip(np.arange(a - r, b + r), lo, lo + n - 1) - lo
    cols = np.clip(np.arange(-r, 7 - r + k_cols - 1), 0, 6)
    assert got.dtype == np.float64
    assert_array_equal(got, x[:, rows][:, :, cols])


def test_float32_lanes_hold_the_worst_case_sums():
    """Why the fast form may use float32: float32 holds every integer below 2**24, and a layer
    whose worst-case |tap sum| (sum |w| x max|x|) stays below that gets float32 lanes -- every
    product and partial sum is such an integer, in any order. At the bound's edge (all weights
    -128, inputs at their extreme) the result is exact; past it a layer gets float64 lanes, and
    float32 lanes would indeed round (the kernel run in float32 on such a layer is wrong)."""
    # layer 1: 3 channels x 9 x 9 taps x 128 x 127 = 3,950,208 < 2**24 -> float32, exact
    w = np.full((2, 3, 9, 9), -128, np.int8)
    assert tap_bound(w, 127) < F32_EXACT and lane_dtype(w, 127) == np.float32
    weights = [np.full((3, 1, 1, 1), 1, np.int8), w]
    biases = [np.zeros(3, np.int32), np.zeros(2, np.int32)]
    mult, shift = [np.full(3, 1, np.int32)], [np.zeros(3, np.int32)]
    img = np.full((12, 12), 255, np.uint8)  # x = 255 - 0, requantised to 127
    ref = int_forward_ref(img, weights, biases, mult, shift, 0)
    assert int(ref.min()) == -128 * 127 * 3 * 81
    assert_array_equal(int_forward(img, weights, biases, mult, shift, 0), ref)
    # 7 channels x 81 taps x 128 x 255 > 2**24; the last tap's product is odd
    big = np.full((1, 7, 9, 9), -128, np.int8)
    big[0, -1, -1, -1] = -127
    assert tap_bound(big, 255) >= F32_EXACT and lane_dtype(big, 255) == np.float64
    exact = (7 * 81 - 1) * 128 * 255 + 127 * 255  # x = -255 everywhere
    got = {}
    for dtype in (np.float32, np.float64):
        xp = np.full((7, 9, 9), -255, dtype)
        acc = np.zeros((1, 1, 1), np.int32)  # (C, rows, W): the accumulators
        _layer_rows(xp, _pad_taps(big, dtype), np.zeros(1, np.int32), None, None, acc)
        got[dtype] = int(acc[0, 0, 0])
    assert got[np.float64] == exact
    assert got[np.float32] != exact  # what float32 lanes would do: the reason for the rule


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


# ---- byte dot products (AVX512-VNNI) ----------------------------------------------------------


@pytest.mark.skipif(not vnni.HAS_VNNI, reason="the byte dot products need AVX512-VNNI")
@given(seed=st.integers(0, 2**16), k=st.sampled_from([9, 11]),
       channels=st.sampled_from([1, 5, 32, 40]), height=st.integers(1, 40),
       width=st.integers(1, 70), offset=st.integers(0, 255), band_rows=st.integers(1, 40))
@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
def test_byte_dot_products_equal_the_definition(seed, k, channels, height, width, offset,
                                                  band_rows):
    """One layer of 9 or 11 taps a row (every odd K the three groups of four hold), 1 to 40
    channels (uint64 descriptors past 32), frames narrower than a block of 16 and not whole
    blocks, any offset, bands of any height (the replicate border at every band's edge): the
    VNNI descriptor equals the int64 definition's signs."""
    weights, biases, mult, shift = _network(seed, (channels,), (k,), bias_range=60000)
    img = _image((height, width), seed + 1)
    args = (weights, biases, mult, shift, offset)
    ref = signs_ref(int_forward_ref(img, *args))
    out = np.empty_like(ref)
    vnni.vnni_signs(img, weights[0], biases[0], offset, out, band_rows)
    assert_array_equal(out, ref)


def test_the_byte_dot_products_serve_one_wide_layer_only(monkeypatch):
    """int_signs takes the dot products for a single layer of 9 or 11 taps on a CPU with the
    instruction, unless STEREOSIM_VNNI=0; otherwise the float lanes, which still equal the
    definition for such a layer."""
    wide, _, _, _ = _network(1, (32,), (9,))
    assert vnni.vnni_applies(tuple(wide)) == vnni.HAS_VNNI
    assert not vnni.vnni_applies(tuple(_network(2, (32,), (7,))[0]))
    assert not vnni.vnni_applies(tuple(_network(3, (8, 32), (9, 3))[0]))
    monkeypatch.setenv("STEREOSIM_VNNI", "0")
    assert not vnni.vnni_applies(tuple(wide))
    weights, biases, mult, shift = _network(4, (32,), (9,))
    img = _image((37, 53), 5)
    args = (weights, biases, mult, shift, 77)
    assert_array_equal(int_signs(img, *args), signs_ref(int_forward_ref(img, *args)))


def test_a_generic_numba_target_keeps_the_float_lanes():
    """NUMBA_CPU_NAME / NUMBA_CPU_FEATURES (a cache for other machines) decide, not the host:
    the instruction only where the named features include it."""
    assert not vnni.numba_targets_vnni("generic", None, {"avx512vnni": True})
    assert not vnni.numba_targets_vnni("znver4", "+avx2,-avx512vnni", {"avx512vnni": True})
    assert vnni.numba_targets_vnni("generic", "+avx512f,+avx512vnni", {})
    assert vnni.numba_targets_vnni(None, None, {"avx512vnni": True})
    assert not vnni.numba_targets_vnni(None, None, {"avx512vnni": False})
