"""SGM: row kernel == naive reference bit for bit; the path recurrence checked by hand."""

import inspect

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.config import SvaConfig
from stereosim.core.errors import InputError
from stereosim.sva.sgm.sgm import effective_p2, path_step, sgm, sgm_ref

# (19, 1), (23, 2), (40, 3): taller than W + 2, so the top paths' row rings wrap many times
SHAPES = [(1, 1), (1, 17), (19, 1), (23, 2), (40, 3), (7, 13), (9, 21)]

# 1 x 3 image, D = 3: agg[0, x, d]
AGG_1X3 = np.array([[[5, 1, 7], [2, 6, 3], [4, 4, 0]]], np.uint16)


def run_both(agg, **kw):
    got = sgm(agg, **kw)
    assert got.dtype == np.uint16 and got.shape == agg.shape
    assert_array_equal(got, sgm_ref(agg, **kw))
    return got


def random_agg(shape, seed, high=2048):
    return np.random.default_rng(seed).integers(0, high, size=shape, dtype=np.uint16)


def smooth_agg(shape, seed):
    """Costs with a clear minimum per pixel along a slanted disparity surface, so the paths
    carry real structure (not just noise) through the penalties."""
    h, w, dn = shape
    rng = np.random.default_rng(seed)
    truth = (np.arange(w)[None, :] // 4 + np.arange(h)[:, None] // 3) % dn
    d = np.arange(dn)[None, None, :]
    agg = 40 * np.abs(d - truth[:, :, None]) + rng.integers(0, 30, size=shape)
    return agg.astype(np.uint16)


def test_zero_penalties_give_the_cost_itself():
    # P1 = P2 = 0: best = min_k L(p - r, k), so L(p, d) = A(p, d) + m - m = A(p, d)
    got = run_both(AGG_1X3, p1=0, p2=0, paths=1, path_bits=13, sum_bits=16)
    assert_array_equal(got, AGG_1X3)


def test_huge_penalties_give_the_running_sum_minus_min():
    # P1, P2 larger than any cost step: best = L(p - r, d), L = A + L(p - r, d) - min L(p - r)
    # x0 = [5, 1, 7] (path start), min 1
    # x1 = [2 + 5 - 1, 6 + 1 - 1, 3 + 7 - 1] = [6, 6, 9], min 6
    # x2 = [4 + 6 - 6, 4 + 6 - 6, 0 + 9 - 6] = [4, 4, 3]
    got = run_both(AGG_1X3, p1=1000, p2=1000, paths=1, path_bits=13, sum_bits=16)
    assert got[0].tolist() == [[5, 1, 7], [6, 6, 9], [4, 4, 3]]


def test_small_penalties_by_hand():
    # P1 = 1, P2 = 3. x1 from L0 = [5, 1, 7], m = 1:
    #   d0: min(5, 1+1, 1+3) = 2 -> 2 + 2 - 1 = 3
    #   d1: min(1, 5+1, 7+1, 4) = 1 -> 6 + 1 - 1 = 6
    #   d2: min(7, 1+1, 4) = 2 -> 3 + 2 - 1 = 4
    # x2 from L1 = [3, 6, 4], m = 3:
    #   d0: min(3, 6+1, 3+3) = 3 -> 4 + 0 = 4
    #   d1: min(6, 3+1, 4+1, 6) = 4 -> 4 + 1 = 5
    #   d2: min(4, 6+1, 6) = 4 -> 0 + 1 = 1
    got = run_both(AGG_1X3, p1=1, p2=3, paths=1, path_bits=13, sum_bits=16)
    assert got[0].tolist() == [[5, 1, 7], [3, 6, 4], [4, 5, 1]]


def test_top_path_starts_at_the_first_row_and_borders():
    # one column: the diagonal paths always start (their predecessor is outside the image),
    # the top path runs down the column like the left path runs along a row
    agg = AGG_1X3.transpose(1, 0, 2).copy()  # 3 x 1
    top = run_both(agg, p1=1, p2=3, paths=2, path_bits=13, sum_bits=16)
    left_only = agg  # left path starts at every pixel of a one-column image
    assert_array_equal(top - left_only, [[[5, 1, 7]], [[3, 6, 4]], [[4, 5, 1]]])
    four = run_both(agg, p1=1, p2=3, paths=4, path_bits=13, sum_bits=16)
    assert_array_equal(four, top + 2 * agg)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("paths", [1, 2, 3, 4])
@pytest.mark.parametrize("adaptive", [False, True])
def test_kernel_equals_ref_textured(shape, paths, adaptive):
    agg = smooth_agg(shape + (16,), seed=sum(shape) + paths)
    img = np.random.default_rng(paths).integers(0, 256, size=shape, dtype=np.uint8)
    run_both(
        agg,
        p1=12,
        p2=96,
        paths=paths,
        path_bits=13,
        sum_bits=16,
        img=img,
        p2_adaptive=adaptive,
        p2_slope=24,
    )


@pytest.mark.parametrize("disparities", [1, 2, 16, 33, 256])
@pytest.mark.parametrize("paths", [1, 2, 3, 4])
def test_disparity_limits(disparities, paths):
    agg = random_agg((5, 11, disparities), seed=disparities)
    run_both(agg, p1=7, p2=50, paths=paths, path_bits=13, sum_bits=16)


@pytest.mark.parametrize("paths", [1, 2, 3, 4])
def test_flat_costs(paths):
    agg = np.full((7, 13, 16), 100, np.uint16)
    got = run_both(agg, p1=10, p2=120, paths=paths, path_bits=13, sum_bits=16)
    # every path: A + L(prev, d) - min = A, so S = paths * A
    assert (got == paths * 100).all()


@pytest.mark.parametrize("paths", [1, 2, 3, 4])
def test_path_saturation_hits_the_cap(paths):
    path_bits = 8
    agg = random_agg((7, 13, 16), seed=paths, high=400)
    got = run_both(agg, p1=30, p2=200, paths=paths, path_bits=path_bits, sum_bits=16)
    assert (got == paths * 255).any()  # a pixel where every path saturated


@pytest.mark.parametrize("paths", [2, 4])
def test_sum_saturation_hits_the_cap(paths):
    agg = random_agg((7, 13, 16), seed=paths, high=300)
    got = run_both(agg, p1=30, p2=200, paths=paths, path_bits=13, sum_bits=9)
    assert (got == 511).any() and (got < 511).any()


def test_widest_registers_do_not_wrap():
    # path_bits = 14 with costs at 2^15 - 1 and the largest penalties: four paths of 16383
    agg = np.full((3, 5, 4), 32767, np.uint16)
    agg[1, 2] = [0, 32767, 0, 32767]
    got = run_both(agg, p1=32767, p2=32767, paths=4, path_bits=14, sum_bits=16)
    assert (got == 4 * 16383).any()


def test_inputs_above_the_path_cap_saturate():
    agg = random_agg((4, 6, 5), seed=3, high=65536)
    got = run_both(agg, p1=100, p2=2000, paths=4, path_bits=14, sum_bits=16)
    assert (got == 65532).any()


def test_adaptive_p2_formula():
    assert effective_p2(10, 100, False, 16, 0, 255) == 100
    assert effective_p2(10, 100, True, 16, 50, 40) == 90  # 100 - (16 * 10 >> 4)
    assert effective_p2(10, 100, True, 24, 40, 50) == 85  # 100 - (240 >> 4)
    assert effective_p2(10, 100, True, 16, 0, 255) == 10  # floored at P1


def test_path_step_by_hand():
    # the step of test_small_penalties_by_hand's x1 (P1 = 1, P2 = 3, from [5, 1, 7]); a path
    # start (zero predecessor) is the cost clamped to the cap
    assert path_step([2, 6, 3], [5, 1, 7], 1, 3, 100) == [3, 6, 4]
    assert path_step([2, 6, 3], [5, 1, 7], 1, 3, 5) == [3, 5, 4]
    assert path_step([9, 0, 4], [0, 0, 0], 7, 9, 8) == [8, 0, 4]


@settings(max_examples=60, deadline=None)
@given(
    w=st.integers(1, 9),
    disparities=st.sampled_from([1, 2, 15, 16, 17, 31, 32, 33, 63, 64, 65, 97]),
    p1=st.integers(0, 32767),
    p2=st.integers(0, 32767),
    path_bits=st.integers(1, 14),
    adaptive=st.booleans(),
    slope=st.integers(0, 16384),
    high=st.sampled_from([4, 600, 65535]),
    seed=st.integers(0, 2**16),
)
def test_the_kernels_step_is_path_step(w, disparities, p1, p2, path_bits, adaptive, slope,
                                       high, seed):
    """The kernel's vector step (uint16 lanes, masked tail, ABSENT borders) against the plain
    :func:`path_step` on its own: a two-row image with the left and top paths, each path
    iterated here from its start, S their sum (16 bits never saturate two 14-bit paths)."""
    rng = np.random.default_rng(seed)
    agg = rng.integers(0, high, size=(2, w, disparities), dtype=np.uint16)
    img = rng.integers(0, 256, size=(2, w), dtype=np.uint8)
    cap = (1 << path_bits) - 1
    zero = [0] * disparities

    def pen(y, x, py, px):
        return effective_p2(p1, p2, adaptive, slope, img[y, x], img[py, px])

    left = [[path_step(agg[y, 0], zero, p1, p2, cap)] for y in range(2)]
    for y in range(2):
        for x in range(1, w):
            left[y].append(path_step(agg[y, x], left[y][x - 1], p1, pen(y, x, y, x - 1), cap))
    top = [path_step(agg[0, x], zero, p1, p2, cap) for x in range(w)]
    top = [top, [path_step(agg[1, x], top[x], p1, pen(1, x, 0, x), cap) for x in range(w)]]
    want = np.array(left, np.int64) + np.array(top, np.int64)
    got = sgm(agg, p1=p1, p2=p2, paths=2, path_bits=path_bits, sum_bits=16, img=img,
              p2_adaptive=adaptive, p2_slope=slope)
    assert_array_equal(got, want)


def test_the_default_slope_is_the_configurations():
    for fn in (sgm, sgm_ref):
        assert inspect.signature(fn).parameters["p2_slope"].default == SvaConfig().p2_slope


def test_adaptive_p2_changes_the_result():
    agg = smooth_agg((7, 13, 16), seed=5)
    img = np.random.default_rng(5).integers(0, 256, size=(7, 13), dtype=np.uint8)
    kw = {
        "p1": 8,
        "p2": 200,
        "paths": 4,
        "path_bits": 13,
        "sum_bits": 16,
        "img": img,
        "p2_slope": 64,
    }
    on = run_both(agg, p2_adaptive=True, **kw)
    off = run_both(agg, p2_adaptive=False, **kw)
    assert (on != off).any()


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(1, 8),
    w=st.integers(1, 16),
    disparities=st.integers(1, 80),
    paths=st.integers(1, 4),
    p1=st.integers(0, 60),
    p2=st.integers(0, 400),
    path_bits=st.integers(6, 14),
    sum_bits=st.integers(8, 16),
    adaptive=st.booleans(),
    slope=st.integers(0, 64),
    high=st.sampled_from([50, 600, 32768]),
    seed=st.integers(0, 2**16),
)
def test_kernel_equals_ref_hypothesis(
    h, w, disparities, paths, p1, p2, path_bits, sum_bits, adaptive, slope, high, seed
):
    rng = np.random.default_rng(seed)
    agg = rng.integers(0, high, size=(h, w, disparities), dtype=np.uint16)
    img = rng.integers(0, 256, size=(h, w), dtype=np.uint8)
    run_both(
        agg,
        p1=p1,
        p2=p2,
        paths=paths,
        path_bits=path_bits,
        sum_bits=sum_bits,
        img=img,
        p2_adaptive=adaptive,
        p2_slope=slope,
    )


def test_bad_inputs_raise():
    agg = np.zeros((2, 3, 4), np.uint16)
    kw = {"p1": 1, "p2": 2, "paths": 4, "path_bits": 13, "sum_bits": 16}
    with pytest.raises(InputError, match="uint8 or uint16"):
        sgm(agg.astype(np.int32), **kw)
    with pytest.raises(InputError, match="paths"):
        sgm(agg, **{**kw, "paths": 5})
    with pytest.raises(InputError, match="path cost width"):
        sgm(agg, **{**kw, "path_bits": 15})
    with pytest.raises(InputError, match="summed cost width"):
        sgm(agg, **{**kw, "sum_bits": 17})
    with pytest.raises(InputError, match="P2"):
        sgm(agg, **{**kw, "p2": 40000})
    with pytest.raises(InputError, match="grey image"):
        sgm(agg, img=np.zeros((2, 4), np.uint8), **kw)
