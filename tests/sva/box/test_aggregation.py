"""Box-filter aggregation: row kernels == naive reference bit for bit, saturation, borders."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.errors import InputError
from stereosim.sva.box.aggregation import box_filter, box_filter_ref

SHAPES = [(1, 1), (1, 17), (19, 1), (7, 13), (9, 21)]


def random_costs(shape, seed, high=65):
    return np.random.default_rng(seed).integers(0, high, size=shape, dtype=np.uint8)


@pytest.mark.parametrize("k", [1, 3, 5, 15])
@pytest.mark.parametrize("value", [0, 7, 64])
def test_constant_volume_sums_k_squared_values(k, value):
    cost = np.full((6, 9, 4), value, np.uint8)
    got = box_filter(cost, k, 15)
    # replicate borders: every pixel sums exactly k*k costs, also at the corners
    assert (got == k * k * value).all()
    assert_array_equal(got, box_filter_ref(cost, k, 15))


def test_hand_worked_border_clamp():
    # one row, one disparity: costs 1, 2, 3; k = 3 sums rows clamp(-1..1) = row 0 three times
    cost = np.array([[[1], [2], [3]]], np.uint8)
    # x = 0: columns (0, 0, 1) -> 3 * (1 + 1 + 2) = 12; x = 1: 3 * 6 = 18; x = 2: 3 * (2+3+3) = 24
    assert box_filter(cost, 3, 15)[0, :, 0].tolist() == [12, 18, 24]


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("k", [1, 3, 5, 7])
@pytest.mark.parametrize("disparities", [1, 16, 45])  # 45: a vector chunk and a scalar tail
def test_kernel_equals_ref_textured(shape, k, disparities):
    cost = random_costs(shape + (disparities,), seed=sum(shape) * k + disparities)
    got = box_filter(cost, k, 11)
    assert got.dtype == np.uint16
    assert_array_equal(got, box_filter_ref(cost, k, 11))


@pytest.mark.parametrize("k", [3, 5, 15])
def test_saturation_hits_the_cap(k):
    cost_bits = 8
    cap = (1 << cost_bits) - 1
    cost = random_costs((7, 13, 5), seed=k, high=256)
    got = box_filter(cost, k, cost_bits)
    assert (got == cap).any()
    assert_array_equal(got, box_filter_ref(cost, k, cost_bits))


def test_largest_window_of_largest_costs_is_exact():
    # 15 * 15 * 255 = 57375: the widest sum the uint16 running sums have to carry
    cost = np.full((3, 4, 2), 255, np.uint8)
    assert (box_filter(cost, 15, 16) == 57375).all()
    assert (box_filter(cost, 15, 15) == 32767).all()


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(1, 9),
    w=st.integers(1, 21),
    disparities=st.integers(1, 70),
    k=st.sampled_from([1, 3, 5, 7, 9, 15]),
    cost_bits=st.integers(6, 15),
    high=st.sampled_from([2, 65, 256]),
    seed=st.integers(0, 2**16),
)
def test_kernel_equals_ref_hypothesis(h, w, disparities, k, cost_bits, high, seed):
    cost = random_costs((h, w, disparities), seed, high)
    assert_array_equal(box_filter(cost, k, cost_bits), box_filter_ref(cost, k, cost_bits))


def test_bad_inputs_raise():
    cost = np.zeros((3, 4, 2), np.uint8)
    with pytest.raises(InputError, match="uint8"):
        box_filter(cost.astype(np.uint16), 3, 11)
    with pytest.raises(InputError, match="odd"):
        box_filter(cost, 4, 11)
    with pytest.raises(InputError, match="too large"):
        box_filter(cost, 17, 11)
    with pytest.raises(InputError, match="cost width"):
        box_filter(cost, 3, 17)
