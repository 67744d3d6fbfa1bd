"""LR check: right disparity by diagonal search and the consistency test, kernel == reference."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.sva.lr.lr_check import lr_check, lr_check_ref, right_disparity_ref
from stereosim.sva.wta.wta import INVALID, wta_ref

SHAPES = [(1, 1), (1, 17), (19, 1), (7, 13), (9, 21)]


def run_both(s, max_diff, uniqueness=0):
    q, dint = wta_ref(s, uniqueness=uniqueness, subpixel="parabola", frac_bits=4)
    q_before = q.copy()
    got, dr = lr_check(s, q, dint, max_diff)
    assert_array_equal(q, q_before)  # the input words are not modified
    dr_ref = right_disparity_ref(s)
    assert_array_equal(dr, dr_ref)
    assert_array_equal(got, lr_check_ref(q, dint, dr_ref, max_diff))
    return got, dr, dint


# one row, W = 4, D = 2: S[0, x, d]
S_1X4 = np.array([[[5, 9], [7, 2], [1, 8], [6, 3]]], np.uint16)


def test_right_disparity_by_hand():
    # xr = 0: S(0, 0) = 5, S(1, 1) = 2 -> 1;  xr = 1: S(1, 0) = 7, S(2, 1) = 8 -> 0
    # xr = 2: S(2, 0) = 1, S(3, 1) = 3 -> 0;  xr = 3: only S(3, 0) (x_r + 1 = W) -> 0
    _, dr, dint = run_both(S_1X4, 0)
    assert dr.tolist() == [[1, 0, 0, 0]]
    assert dint.tolist() == [[0, 1, 0, 1]]


def test_pixel_invalid_when_the_right_disparity_disagrees():
    # x0: d* = 0 but dR(0) = 1; x3: d* = 1 but dR(2) = 0 -> both off by one
    got, _, _ = run_both(S_1X4, 0)
    assert got.tolist()[0][0] == INVALID and got.tolist()[0][3] == INVALID
    assert got[0, 1] != INVALID and got[0, 2] != INVALID
    got, _, _ = run_both(S_1X4, 1)  # a difference of one is accepted with max_diff = 1
    assert (got != INVALID).all()


def test_pixel_invalid_when_its_match_falls_outside():
    s = np.array([[[9, 1], [3, 8]]], np.uint16)  # x = 0 wins at d = 1: x - d < 0
    got, _, dint = run_both(s, 255)
    assert dint[0, 0] == 1 and got[0, 0] == INVALID


def test_ties_resolve_to_the_smallest_disparity():
    s = np.full((1, 6, 4), 7, np.uint16)
    _, dr, _ = run_both(s, 0)
    assert (dr == 0).all()


def test_consistent_shift_survives():
    # S has its minimum on the diagonal d = 3 everywhere: left and right agree
    h, w, dn = 5, 16, 8
    s = np.full((h, w, dn), 100, np.uint16)
    s[:, :, 3] = 10
    got, dr, dint = run_both(s, 0)
    assert (dint == 3).all() and (dr[:, : w - 3] == 3).all()
    assert (got[:, 3:] != INVALID).all() and (got[:, :3] == INVALID).all()


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("disparities", [1, 2, 16, 30])
@pytest.mark.parametrize("max_diff", [0, 1, 3])
def test_kernel_equals_ref_random(shape, disparities, max_diff):
    rng = np.random.default_rng(sum(shape) + disparities)
    s = rng.integers(0, 30, size=shape + (disparities,), dtype=np.uint16)
    run_both(s, max_diff, uniqueness=10)


@settings(max_examples=50, deadline=None)
@given(
    h=st.integers(1, 4),
    w=st.integers(1, 30),
    disparities=st.integers(1, 35),
    max_diff=st.integers(0, 4),
    spread=st.sampled_from([2, 40, 65536]),
    seed=st.integers(0, 2**16),
)
def test_kernel_equals_ref_hypothesis(h, w, disparities, max_diff, spread, seed):
    rng = np.random.default_rng(seed)
    s = rng.integers(0, spread, size=(h, w, disparities)).astype(np.uint16)
    run_both(s, max_diff)


@pytest.mark.parametrize("disparities", [16, 256])
def test_largest_costs_tie_to_the_smallest_disparity(disparities):
    # the diagonal search starts every right pixel at (0xFFFF, d = 0): S = 0xFFFF everywhere
    # (sum_bits = 16 saturated) must still give d = 0, and a single smaller cost must win
    h, w = 2, disparities + 3
    s = np.full((h, w, disparities), 0xFFFF, np.uint16)
    _, dr, dint = run_both(s, 1)
    assert (dr == 0).all() and (dint == 0).all()
    s[1, w - 1, disparities - 1] = 0xFFFE  # right pixel w - disparities sees it at d = D - 1
    _, dr, _ = run_both(s, 1)
    assert dr[1, w - disparities] == disparities - 1
