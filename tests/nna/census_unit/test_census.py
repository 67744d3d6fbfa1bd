"""Census: kernel == naive reference bit for bit, plus the definition checked by hand."""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.errors import ConfigError, InputError
from stereosim.nna.census_unit.census import census, census_bits, census_offsets, census_ref

# (window, kind, stride) covering both kinds, the 32/64-bit boundaries and the sparse census.
CONFIGS = [
    ((5, 5), "plain", 1),  # 24 bits
    ((5, 5), "symmetric", 1),  # 12 bits
    ((7, 7), "plain", 1),  # 48 bits -> uint64
    ((7, 7), "symmetric", 1),
    ((9, 7), "plain", 1),  # 62 bits
    ((9, 7), "symmetric", 1),  # 31 bits, the chip default
    ((9, 9), "symmetric", 1),  # 40 bits
    ((13, 5), "plain", 1),  # exactly 64 bits: bit 63 in use
    ((13, 5), "symmetric", 1),  # 32 bits: bit 31 in use
    ((9, 9), "plain", 2),  # sparse: 24 bits
    ((9, 9), "symmetric", 2),
    ((7, 5), "plain", 2),  # stride 2 on a grid without the centre
    ((9, 9), "symmetric", 3),  # stride 3: grid not symmetric about the centre
]
SHAPES = [(1, 1), (1, 17), (19, 1), (7, 13), (37, 23)]


def _id(config):
    (w, h), kind, stride = config
    return f"{w}x{h}-{kind}-s{stride}"


def _textured(shape, seed, levels=256):
    rng = np.random.default_rng(seed)
    return rng.integers(0, levels, size=shape, dtype=np.uint8)


@pytest.mark.parametrize(
    ("window", "kind", "stride", "bits"),
    [
        ((5, 5), "plain", 1, 24),
        ((7, 7), "plain", 1, 48),
        ((9, 7), "plain", 1, 62),
        ((9, 7), "symmetric", 1, 31),
        ((9, 9), "symmetric", 1, 40),
        ((13, 5), "symmetric", 1, 32),
        ((5, 13), "symmetric", 1, 32),
        ((9, 9), "plain", 2, 24),
        ((13, 5), "plain", 1, 64),
        ((7, 7), "plain", 2, 16),  # grid -3, -1, 1, 3: no centre to drop
        ((3, 1), "symmetric", 1, 1),
    ],
)
def test_bit_counts(window, kind, stride, bits):
    assert census_bits(window, kind, stride) == bits
    assert len(census_offsets(window, kind, stride)) == bits


def test_plain_9x9_is_too_wide():
    with pytest.raises(ConfigError, match="9x9 plain.*80 bits.*symmetric.*stride=2"):
        census_bits((9, 9), "plain", 1)
    with pytest.raises(ConfigError, match="80 bits"):
        census(np.zeros((4, 4), np.uint8), (9, 9), "plain")


@pytest.mark.parametrize(
    ("window", "kind", "stride"),
    [
        ((8, 7), "symmetric", 1),  # even
        ((17, 3), "plain", 1),  # too wide
        ((9,), "plain", 1),  # not a pair
        ((9, 7), "mirror", 1),  # unknown kind
        ((9, 7), "plain", 0),
        ((9, 7), "plain", 5),
        ((1, 1), "plain", 1),  # nothing to compare
        ((9.0, 7), "plain", 1),
    ],
)
def test_bad_parameters_raise_config_error(window, kind, stride):
    with pytest.raises(ConfigError):
        census(np.zeros((3, 3), np.uint8), window, kind, stride)


def test_offsets_order_and_mirror_rule():
    # Row-major, dy outer, dx inner; symmetric keeps the offsets before the centre.
    assert census_offsets((3, 3), "plain") == [
        (-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1),
    ]  # fmt: skip
    assert census_offsets((3, 3), "symmetric") == [(-1, -1), (0, -1), (1, -1), (-1, 0)]
    # Sparse: dx, dy in -4, -2, 0, 2, 4.
    assert census_offsets((9, 9), "plain", 2)[:6] == [
        (-4, -4), (-2, -4), (0, -4), (2, -4), (4, -4), (-4, -2),
    ]  # fmt: skip
    # Stride 3 on width 9: dx = -4, -1, 2 (stops before passing +4).
    assert census_offsets((9, 1), "plain", 3) == [(-4, 0), (-1, 0), (2, 0)]


def test_hand_worked_3x3():
    img = np.array(
        [
            [10, 50, 20],
            [60, 30, 30],
            [5, 40, 90],
        ],
        dtype=np.uint8,
    )
    # Plain 3x3 at the centre (y=1, x=1), I(p) = 30; offsets in bit order:
    expected = 0
    expected |= 0 << 0  # (-1,-1): 10 > 30? no
    expected |= 1 << 1  # ( 0,-1): 50 > 30? yes
    expected |= 0 << 2  # ( 1,-1): 20 > 30? no
    expected |= 1 << 3  # (-1, 0): 60 > 30? yes
    expected |= 0 << 4  # ( 1, 0): 30 > 30? no (strict)
    expected |= 0 << 5  # (-1, 1):  5 > 30? no
    expected |= 1 << 6  # ( 0, 1): 40 > 30? yes
    expected |= 1 << 7  # ( 1, 1): 90 > 30? yes
    assert expected == 202
    assert census(img, (3, 3), "plain")[1, 1] == expected
    assert census_ref(img, (3, 3), "plain")[1, 1] == expected

    # Plain 3x3 at the corner (y=0, x=0), I(p) = 10; replicate border clamps the coordinates:
    expected = 0
    expected |= 0 << 0  # (-1,-1) -> (0,0): 10 > 10? no
    expected |= 0 << 1  # ( 0,-1) -> (0,0): 10 > 10? no
    expected |= 1 << 2  # ( 1,-1) -> (x=1,y=0): 50 > 10? yes
    expected |= 0 << 3  # (-1, 0) -> (0,0): 10 > 10? no
    expected |= 1 << 4  # ( 1, 0): 50 > 10? yes
    expected |= 1 << 5  # (-1, 1) -> (x=0,y=1): 60 > 10? yes
    expected |= 1 << 6  # ( 0, 1): 60 > 10? yes
    expected |= 1 << 7  # ( 1, 1): 30 > 10? yes
    assert expected == 244
    assert census(img, (3, 3), "plain")[0, 0] == expected

    # Symmetric 3x3 at the centre: I(p + o) > I(p - o) for the four offsets before the centre.
    expected = 0
    expected |= 0 << 0  # (-1,-1) vs ( 1, 1): 10 > 90? no
    expected |= 1 << 1  # ( 0,-1) vs ( 0, 1): 50 > 40? yes
    expected |= 1 << 2  # ( 1,-1) vs (-1, 1): 20 >  5? yes
    expected |= 1 << 3  # (-1, 0) vs ( 1, 0): 60 > 30? yes
    assert expected == 14
    assert census(img, (3, 3), "symmetric")[1, 1] == expected
    assert census_ref(img, (3, 3), "symmetric")[1, 1] == expected


@pytest.mark.parametrize("config", CONFIGS, ids=_id)
def test_kernel_equals_ref(config):
    window, kind, stride = config
    for i, shape in enumerate(SHAPES):
        for img in (_textured(shape, seed=i), _textured(shape, seed=100 + i, levels=3)):
            got = census(img, window, kind, stride)
            want = census_ref(img, window, kind, stride)
            assert got.dtype == want.dtype
            assert_array_equal(got, want)


@pytest.mark.parametrize("config", CONFIGS, ids=_id)
def test_flat_image_gives_zero(config):
    window, kind, stride = config
    img = np.full((9, 11), 77, dtype=np.uint8)
    assert not census(img, window, kind, stride).any()
    assert not census_ref(img, window, kind, stride).any()


@pytest.mark.parametrize("config", CONFIGS, ids=_id)
def test_top_bit_is_used(config):
    # The highest comparison is reachable, so no bit is lost to a narrow dtype.
    window, kind, stride = config
    bits = census_bits(window, kind, stride)
    desc = census(_textured((37, 23), seed=7), window, kind, stride)
    assert desc.dtype == (np.uint32 if bits <= 32 else np.uint64)
    assert (desc >> np.array(bits - 1, dtype=desc.dtype)).any()
    if bits < 64:
        assert not (desc >> np.array(bits, dtype=desc.dtype)).any()


@pytest.mark.parametrize("config", CONFIGS, ids=_id)
def test_brightness_offset_invariance(config):
    window, kind, stride = config
    img = _textured((31, 29), seed=3, levels=200)
    brighter = img + np.uint8(55)  # max 254: no clipping
    assert_array_equal(census(brighter, window, kind, stride), census(img, window, kind, stride))


def test_non_contiguous_input():
    img = _textured((21, 40), seed=5)
    view = img[:, ::2]
    assert not view.flags.c_contiguous
    assert_array_equal(census(view), census_ref(np.ascontiguousarray(view)))


@pytest.mark.parametrize(
    "img",
    [
        np.zeros((4, 4), np.float32),
        np.zeros((4, 4), np.uint16),
        np.zeros((4, 4, 3), np.uint8),
        np.zeros(4, np.uint8),
        np.zeros((0, 4), np.uint8),
        [[1, 2], [3, 4]],
    ],
    ids=["float32", "uint16", "colour", "1-D", "empty", "list"],
)
def test_bad_images_raise_input_error(img):
    with pytest.raises(InputError):
        census(img)
    with pytest.raises(InputError):
        census_ref(img)


odd = st.integers(0, 7).map(lambda i: 2 * i + 1)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    height=st.integers(1, 16),
    width=st.integers(1, 16),
    win_w=odd,
    win_h=odd,
    kind=st.sampled_from(["plain", "symmetric"]),
    stride=st.integers(1, 4),
    levels=st.sampled_from([2, 5, 256]),
    seed=st.integers(0, 2**32 - 1),
)
def test_kernel_equals_ref_hypothesis(height, width, win_w, win_h, kind, stride, levels, seed):
    window = (win_w, win_h)
    try:
        census_bits(window, kind, stride)
    except ConfigError:
        assume(False)
    img = _textured((height, width), seed, levels)
    assert_array_equal(census(img, window, kind, stride), census_ref(img, window, kind, stride))
