"""Quantisation distances on hand-computed arrays."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from stereosim.core.errors import ConfigError
from stereosim.quant.distances import (
    DISTANCES,
    get_distance,
    hamming,
    hist_rms,
    histograms,
    kl,
    l1,
    rms,
)

F = np.array([1.0, -2.0, 0.5, 3.0])
Q = np.array([2, -1, -1, 0])


def test_sample_wise_by_hand():
    # signs (>0): F T,F,T,T; Q T,F,F,F -> two flips
    assert hamming(F, Q) == 2
    assert l1(F, Q) == pytest.approx((1 + 1 + 1.5 + 3) / 4)
    assert rms(F, Q) == pytest.approx(math.sqrt((1 + 1 + 2.25 + 9) / 4))


def test_hamming_counts_sign_flips_and_zero_is_bit_zero():
    assert hamming(np.array([0.0]), np.array([0])) == 0
    assert hamming(np.array([1e-9]), np.array([0])) == 1
    assert hamming(np.array([-1e-9]), np.array([0])) == 0
    f = np.arange(-5.0, 5.0)
    for n_flips in range(0, 10):
        q = f.copy()
        q[:n_flips] = np.where(f[:n_flips] > 0, -1, 1)
        assert hamming(f, q) == n_flips


def test_histograms_by_hand():
    f = np.array([0.0, 0.0, 0.0, 1.0])
    q = np.array([0, 1, 1, 1])
    h_f, h_q = histograms(f, q, bins=2)
    assert_allclose(h_f, [0.75, 0.25])
    assert_allclose(h_q, [0.25, 0.75])
    assert kl(f, q, bins=2) == pytest.approx(0.75 * math.log2(3) + 0.25 * math.log2(1 / 3))
    assert hist_rms(f, q, bins=2) == pytest.approx(0.5)


def test_common_range_and_empty_bins():
    # values 0..3 on 4 bins; top edge (3.0) goes to the last bin
    h_f, h_q = histograms(np.array([0.0, 3.0]), np.array([1, 2]), bins=4)
    assert_allclose(h_f, [0.5, 0, 0, 0.5])
    assert_allclose(h_q, [0, 0.5, 0.5, 0])
    # disjoint support: finite thanks to eps, and large
    value = kl(np.array([0.0, 3.0]), np.array([1, 2]), bins=4)
    assert np.isfinite(value) and value > 10


def test_identical_histograms_give_zero():
    f = np.random.default_rng(0).normal(size=1000)
    assert kl(f, f.copy()) == 0.0
    assert hist_rms(f, f.copy()) == 0.0
    # same histogram, different order: histogram distances cannot see the permutation
    perm = np.random.default_rng(1).permutation(f)
    assert kl(f, perm) == 0.0
    assert rms(f, perm) > 0.5


def test_constant_columns():
    f = np.full(5, 2.0)
    assert kl(f, f) == 0.0
    assert hist_rms(f, f) == 0.0


@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 40), cols=st.integers(1, 5), seed=st.integers(0, 1000))
def test_columns_are_independent(n, cols, seed):
    rng = np.random.default_rng(seed)
    f = rng.normal(size=(n, cols)) * 10
    q = np.rint(f + rng.normal(size=(n, cols)))
    for name, fn in DISTANCES.items():
        together = fn(f, q)
        assert together.shape == (cols,)
        for c in range(cols):
            assert together[c] == pytest.approx(float(fn(f[:, c], q[:, c])), abs=1e-12), name


def test_unknown_distance_and_shape_mismatch():
    with pytest.raises(ConfigError, match="unknown distance"):
        get_distance("cosine")
    with pytest.raises(ValueError, match="same shape"):
        rms(np.zeros(3), np.zeros(4))
