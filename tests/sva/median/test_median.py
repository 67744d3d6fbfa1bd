"""Median post-filter: kernel == naive reference, invalid words, borders."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.errors import InputError
from stereosim.sva.median.median import (
    NARROW_MAX,
    column_networks,
    median,
    median_holds,
    median_ref,
    selection_network,
    sorted_column_windows,
)

SHAPES = [(1, 1), (1, 17), (19, 1), (7, 13), (9, 21)]


def random_words(shape, seed, invalid=0.2, high=2048):
    rng = np.random.default_rng(seed)
    q = rng.integers(0, high, size=shape).astype(np.int32)
    q[rng.random(shape) < invalid] = -1
    return q


def test_hand_worked_3x3():
    q = np.array([[1, 2, 3], [4, 50, 6], [7, 8, 9]], np.int32)
    # centre: sorted 1 2 3 4 6 7 8 9 50 -> element 4 = 6
    assert median(q, 3)[1, 1] == 6
    # corner (0, 0) with replicate borders: 1 1 2 / 1 1 2 / 4 4 50 -> 1 1 1 1 2 2 4 4 50 -> 2
    assert median(q, 3)[0, 0] == 2
    assert_array_equal(median(q, 3), median_ref(q, 3))


def test_mostly_invalid_window_becomes_invalid():
    q = np.full((3, 3), -1, np.int32)
    q[0, :] = 40  # 3 valid words of 9 (centre window)
    assert median(q, 3)[1, 1] == -1
    q[1, :2] = 40  # 5 valid of 9: the median is valid
    assert median(q, 3)[1, 1] == 40


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("k", [3, 5, 7])
def test_kernel_equals_ref(shape, k):
    q = random_words(shape, seed=sum(shape) + k)
    got = median(q, k)
    assert got.dtype == np.int32
    assert_array_equal(got, median_ref(q, k))


@pytest.mark.parametrize("k", [3, 5, 7])
def test_wider_than_a_block(k):
    # the network runs over blocks of 128 pixels (32 for the 5 x 5 median in uint16): a row of
    # 300 has a partial last block
    q = random_words((4, 300), seed=k, high=9)
    assert_array_equal(median(q, k), median_ref(q, k))


@pytest.mark.parametrize("width", [31, 32, 33, 65])
def test_the_16_bit_median_at_the_ends_of_its_range(width):
    """The 5 x 5 median of words in -1 .. NARROW_MAX runs in uint16 (word + 1), 32 pixels a
    step, the last step under a mask: the extreme words and every width around a step."""
    rng = np.random.default_rng(width)
    q = rng.choice(np.array([-1, 0, 1, NARROW_MAX - 1, NARROW_MAX], np.int32), size=(6, width))
    assert_array_equal(median(q, 5), median_ref(q, 5))


def test_words_beyond_16_bits_take_the_32_bit_network():
    """A word above NARROW_MAX (not a word the SVA makes, but median() takes any int32):
    the 32-bit network, still the reference's result."""
    q = random_words((7, 40), seed=1, high=2**31 - 1)
    assert q.max() > NARROW_MAX
    assert_array_equal(median(q, 5), median_ref(q, 5))


@pytest.mark.parametrize("k", [3, 5, 7])
def test_selection_network_puts_the_median_in_the_middle(k):
    rng = np.random.default_rng(k)
    network = selection_network(k)
    for _ in range(300):
        v = list(rng.integers(-1, 6, size=k * k))
        for a, b in network:
            if v[a] > v[b]:
                v[a], v[b] = v[b], v[a]
        assert v[k * k // 2] == sorted(v)[k * k // 2]


@pytest.mark.parametrize("k", [3, 5])
def test_the_column_networks_sort_and_select(k):
    """The column network sorts every 0-1 column (all 2^k), the window network leaves the
    median of every 0-1 window with sorted columns in the middle (all (k + 1)^k: by the 0-1
    principle, of every such window), with fewer pairs than the selection network; and it is
    not vacuous: without the column sort it fails."""
    column, network = column_networks(k)
    for v in range(1 << k):
        col = [(v >> i) & 1 for i in range(k)]
        for a, b in column:
            col[a], col[b] = min(col[a], col[b]), max(col[a], col[b])
        assert col == sorted(col)
    assert median_holds([tuple(p) for p in network], sorted_column_windows(k))
    assert len(network) < len(selection_network(k))
    rng = np.random.default_rng(k)
    unsorted_fails = False
    for _ in range(2000):
        v = list(rng.integers(-1, 6, size=k * k))
        for a, b in network:
            if v[a] > v[b]:
                v[a], v[b] = v[b], v[a]
        unsorted_fails |= v[k * k // 2] != sorted(v)[k * k // 2]
    assert unsorted_fails


@pytest.mark.parametrize("k", [3, 5])
def test_flat(k):
    q = np.full((7, 13), 37, np.int32)
    assert (median(q, k) == 37).all()
    assert (median(np.full((4, 5), -1, np.int32), k) == -1).all()


@pytest.mark.parametrize("k", [0, 1])
def test_off_returns_a_copy(k):
    q = random_words((5, 6), seed=k)
    got = median(q, k)
    assert got is not q
    assert_array_equal(got, q)
    assert_array_equal(got, median_ref(q, 1))


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(1, 10),
    w=st.integers(1, 14),
    k=st.sampled_from([3, 5, 7]),
    invalid=st.sampled_from([0.0, 0.3, 0.9]),
    high=st.sampled_from([3, 4096]),
    seed=st.integers(0, 2**16),
)
def test_kernel_equals_ref_hypothesis(h, w, k, invalid, high, seed):
    q = random_words((h, w), seed, invalid, high)
    assert_array_equal(median(q, k), median_ref(q, k))


def test_even_window_raises():
    with pytest.raises(InputError, match="odd"):
        median(np.zeros((3, 3), np.int32), 4)
