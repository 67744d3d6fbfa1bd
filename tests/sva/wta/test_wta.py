"""WTA, uniqueness and sub-pixel: row kernel == naive reference; the formulas by hand."""

from fractions import Fraction
from math import floor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.sva.wta.wta import INVALID, subpixel_offset, to_float, wta, wta_ref

SHAPES = [(1, 1), (1, 17), (19, 1), (7, 13), (9, 21)]
MODES = ["off", "parabola", "equiangular"]


def run_both(s, **kw):
    q, dint = wta(s, **kw)
    q_ref, dint_ref = wta_ref(s, **kw)
    assert q.dtype == np.int32 and dint.dtype == np.int32
    assert_array_equal(q, q_ref)
    assert_array_equal(dint, dint_ref)
    return q, dint


def one_pixel(costs):
    return np.array(costs, np.uint16).reshape(1, 1, -1)


def round_half_up(x: Fraction) -> int:
    return floor(x + Fraction(1, 2))


@pytest.mark.parametrize(
    ("a", "c", "b", "frac_bits"),
    [(10, 4, 6, 4), (7, 4, 5, 1), (5, 4, 7, 1), (9, 4, 6, 2), (100, 0, 1, 8)],
)
def test_parabola_by_hand(a, c, b, frac_bits):
    # o = round(2^F (a - b) / (2 (a + b - 2c))), half up; (7, 4, 5) is exactly +0.5 -> 1 and
    # (5, 4, 7) exactly -0.5 -> 0
    expected = round_half_up(Fraction((a - b) * 2**frac_bits, 2 * (a + b - 2 * c)))
    if (a, c, b, frac_bits) == (10, 4, 6, 4):
        assert expected == 4  # 16 * 4 / 16
    assert subpixel_offset(a, c, b, "parabola", frac_bits) == expected
    # the same through the kernel, with the winner at d* = 2 of D = 5
    q, dint = run_both(
        one_pixel([999, a, c, b, 999]), uniqueness=0, subpixel="parabola", frac_bits=frac_bits
    )
    assert dint[0, 0] == 2
    assert q[0, 0] == (2 << frac_bits) + expected


@pytest.mark.parametrize(
    ("a", "c", "b", "frac_bits", "offset"),
    # 64/12 = 5.33, -5.33, 32/12 = 2.67, exactly +0.5 and -0.5 (half up)
    [(10, 4, 6, 4, 5), (6, 4, 10, 4, -5), (9, 3, 5, 3, 3), (6, 4, 5, 1, 1), (5, 4, 6, 1, 0)],
)
def test_equiangular_by_hand(a, c, b, frac_bits, offset):
    # o = round(2^F (a - b) / (2 max(a - c, b - c))), half up
    expected = round_half_up(Fraction((a - b) * 2**frac_bits, 2 * max(a - c, b - c)))
    assert expected == offset
    assert subpixel_offset(a, c, b, "equiangular", frac_bits) == expected
    q, _ = run_both(
        one_pixel([999, a, c, b, 999]), uniqueness=0, subpixel="equiangular", frac_bits=frac_bits
    )
    assert q[0, 0] == (2 << frac_bits) + expected


def test_no_offset_without_curvature():
    # a + b - 2c = 0 (parabola) or max(a - c, b - c) = 0 (equiangular): o = 0. WTA never meets
    # it (the winner is the first minimum, so a > c), the definition still says 0.
    assert subpixel_offset(8, 8, 8, "parabola", 4) == 0
    assert subpixel_offset(8, 8, 8, "equiangular", 4) == 0
    assert subpixel_offset(10, 4, 6, "off", 4) == 0


def test_no_offset_at_the_range_ends_or_without_fraction_bits():
    for costs, d in (([1, 5, 9, 9], 0), ([9, 9, 5, 1], 3)):
        q, dint = run_both(one_pixel(costs), uniqueness=0, subpixel="parabola", frac_bits=4)
        assert dint[0, 0] == d and q[0, 0] == d << 4
    q, _ = run_both(one_pixel([10, 4, 6]), uniqueness=0, subpixel="parabola", frac_bits=0)
    assert q[0, 0] == 1


def test_ties_go_to_the_smallest_disparity():
    q, dint = run_both(one_pixel([9, 3, 7, 3, 3]), uniqueness=0, subpixel="off", frac_bits=0)
    assert dint[0, 0] == 1 and q[0, 0] == 1


def test_uniqueness_by_hand():
    # S1 = 100 at d = 1; S2 over |d - 1| >= 2 is 104 at d = 4 (d = 2's 101 is too close)
    s = one_pixel([150, 100, 101, 200, 104])
    kw = {"subpixel": "off", "frac_bits": 0}
    # 104 * 100 < 100 * 105 -> invalid with a 5 % margin, valid with 4 % (10400 < 10400 false)
    assert run_both(s, uniqueness=5, **kw)[0][0, 0] == INVALID
    assert run_both(s, uniqueness=4, **kw)[0][0, 0] == 1
    assert run_both(s, uniqueness=0, **kw)[0][0, 0] == 1
    # the winner's d_int is kept even when the word is invalid (the LR check reads it)
    assert run_both(s, uniqueness=5, **kw)[1][0, 0] == 1


@pytest.mark.parametrize("costs", [[65000, 65535], [65535, 65000], [65535, 65000, 65535]])
def test_no_runner_up_at_the_largest_costs(costs):
    # with D <= 3 a winner can have no d with |d - d*| >= 2: never invalid, even where S is
    # near 0xFFFF (the kernel's "no value" marker is also a legal cost)
    q, dint = run_both(one_pixel(costs), uniqueness=99, subpixel="off", frac_bits=0)
    assert q[0, 0] == dint[0, 0] == costs.index(min(costs))


def test_flat_costs():
    s = np.full((7, 13, 16), 500, np.uint16)
    q, dint = run_both(s, uniqueness=0, subpixel="parabola", frac_bits=4)
    assert (dint == 0).all() and (q == 0).all()
    q, _ = run_both(s, uniqueness=10, subpixel="parabola", frac_bits=4)
    assert (q == INVALID).all()  # a tie with a far disparity is never unique
    zeros = np.zeros((3, 5, 16), np.uint16)
    q, _ = run_both(zeros, uniqueness=10, subpixel="off", frac_bits=0)
    assert (q == 0).all()  # 0 * 100 < 0 * 110 is false: all-zero costs stay valid


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("disparities", [1, 2, 3, 16])
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize(("uniqueness", "frac_bits"), [(0, 0), (0, 4), (15, 4), (99, 8)])
def test_kernel_equals_ref_random(shape, disparities, mode, uniqueness, frac_bits):
    rng = np.random.default_rng(sum(shape) * disparities + uniqueness)
    # a narrow range of values makes ties and equal neighbours common
    s = rng.integers(1000, 1040, size=shape + (disparities,), dtype=np.uint16)
    run_both(s, uniqueness=uniqueness, subpixel=mode, frac_bits=frac_bits)


@pytest.mark.parametrize("mode", MODES)
def test_largest_costs(mode):
    rng = np.random.default_rng(1)
    s = rng.integers(60000, 65536, size=(5, 7, 16), dtype=np.uint16)
    s[:, :, 5] = 65535
    run_both(s, uniqueness=1, subpixel=mode, frac_bits=8)


@settings(max_examples=60, deadline=None)
@given(
    h=st.integers(1, 5),
    w=st.integers(1, 12),
    disparities=st.integers(1, 24),
    uniqueness=st.sampled_from([0, 0, 1, 5, 30, 99]),
    mode=st.sampled_from(MODES),
    frac_bits=st.integers(0, 8),
    spread=st.sampled_from([2, 20, 65536]),
    seed=st.integers(0, 2**16),
)
def test_kernel_equals_ref_hypothesis(h, w, disparities, uniqueness, mode, frac_bits, spread, seed):
    rng = np.random.default_rng(seed)
    lo = rng.integers(0, 65536 - min(spread, 65535))
    s = (lo + rng.integers(0, spread, size=(h, w, disparities))).astype(np.uint16)
    run_both(s, uniqueness=uniqueness, subpixel=mode, frac_bits=frac_bits)


def test_to_float():
    q = np.array([[-1, 0, 24]], np.int32)
    assert to_float(q, 4).tolist() == [[np.inf, 0.0, 1.5]]
