"""Hamming cost: kernel == naive reference bit for bit, plus the definition checked by hand."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.errors import InputError
from stereosim.sva.hamming.cost import (
    cost_parts,
    cost_row_add,
    cost_row_update,
    hamming_cost,
    hamming_cost_ref,
    reverse_row,
)

SHAPES = [(1, 1), (1, 17), (19, 1), (7, 13), (9, 21)]


def descriptor_pair(h, w, bits, seed, shift=3, flip=0.05):
    """Random ``bits``-wide descriptors; the right view is the left one shifted by ``shift``
    pixels (DR(x - shift) = DL(x)) with a fraction ``flip`` of its bits flipped."""
    rng = np.random.default_rng(seed)
    dtype = np.uint32 if bits <= 32 else np.uint64
    bit_values = rng.integers(0, 2, size=(h, w + shift, bits), dtype=np.uint64)
    scene = (bit_values << np.arange(bits, dtype=np.uint64)).sum(axis=2, dtype=np.uint64)
    left = scene[:, :w].astype(dtype)
    right = scene[:, shift : shift + w].copy()
    noise = rng.random((h, w, bits)) < flip
    right ^= (noise.astype(np.uint64) << np.arange(bits, dtype=np.uint64)).sum(
        axis=2, dtype=np.uint64
    )
    return left, right.astype(dtype)


def test_hamming_of_two_known_words():
    # 0b1011 xor 0b0110 = 0b1101: three bits differ.
    dl = np.array([[0b1011, 0b1011]], np.uint32)
    dr = np.array([[0b0110, 0b1011]], np.uint32)
    cost = hamming_cost(dl, dr, 2, 4)
    # x = 0: d = 0 compares with DR(0) -> 3; d = 1 has no right pixel -> B = 4
    # x = 1: d = 0 compares with DR(1) = DL(1) -> 0; d = 1 compares with DR(0) -> 3
    assert cost.tolist() == [[[3, 4], [0, 3]]]
    assert_array_equal(cost, hamming_cost_ref(dl, dr, 2, 4))


def test_top_bit_of_a_64_bit_word_counts():
    dl = np.array([[1 << 63]], np.uint64)
    dr = np.array([[(1 << 64) - 1]], np.uint64)
    assert hamming_cost(dl, dr, 1, 64)[0, 0, 0] == 63
    assert hamming_cost_ref(dl, dr, 1, 64)[0, 0, 0] == 63


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("disparities", [1, 2, 16, 25])
@pytest.mark.parametrize("bits", [1, 31, 32, 64])
def test_kernel_equals_ref_textured(shape, disparities, bits):
    dl, dr = descriptor_pair(*shape, bits, seed=shape[0] * 100 + shape[1] + disparities)
    got = hamming_cost(dl, dr, disparities, bits)
    assert got.dtype == np.uint8 and got.shape == shape + (disparities,)
    assert_array_equal(got, hamming_cost_ref(dl, dr, disparities, bits))


@pytest.mark.parametrize("shape", SHAPES)
def test_flat_descriptors(shape):
    h, w = shape
    d = np.full((h, w), 0x5A5A5A5A, np.uint32)
    got = hamming_cost(d, d, 16, 32)
    # no differing bit wherever a right pixel exists, B where none does
    x = np.arange(w)[:, None]
    expected = np.where(x - np.arange(16)[None, :] >= 0, 0, 32).astype(np.uint8)
    assert_array_equal(got, np.broadcast_to(expected, (h, w, 16)))
    assert_array_equal(got, hamming_cost_ref(d, d, 16, 32))


def test_shifted_copy_matches_at_its_disparity():
    dl, dr = descriptor_pair(5, 30, 31, seed=1, shift=4, flip=0.0)
    cost = hamming_cost(dl, dr, 8, 31)
    assert (cost[:, 4:, 4] == 0).all()


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(1, 6),
    w=st.integers(1, 30),
    disparities=st.integers(1, 40),
    bits=st.integers(1, 64),
    shift=st.integers(0, 8),
    seed=st.integers(0, 2**16),
)
def test_kernel_equals_ref_hypothesis(h, w, disparities, bits, shift, seed):
    dl, dr = descriptor_pair(h, w, bits, seed, shift=shift, flip=0.1)
    assert_array_equal(
        hamming_cost(dl, dr, disparities, bits), hamming_cost_ref(dl, dr, disparities, bits)
    )


def reversed_row(row):
    out = np.empty_like(row)
    reverse_row(row, out)
    assert_array_equal(out, row[::-1])
    return out


@pytest.mark.parametrize(("w", "disparities"), [(1, 1), (7, 3), (13, 16), (9, 21)])
@pytest.mark.parametrize("bits", [31, 64])
def test_row_sums_of_costs_equal_ref(w, disparities, bits):
    # the streaming vertical box sum: rows added (cost_row_add) and slid (cost_row_update)
    dl, dr = descriptor_pair(4, w, bits, seed=w + disparities)
    cost = hamming_cost_ref(dl, dr, disparities, bits).astype(np.uint16)
    sums = np.zeros((w, disparities), np.uint16)
    for y in (0, 1, 1):
        cost_row_add(dl[y], reversed_row(dr[y]), cost_parts(bits).registers(dl.dtype), sums)
    assert_array_equal(sums, cost[0] + 2 * cost[1])
    # replace row 0 by row 3: only d <= x changes, the B entries cancel
    cost_row_update(dl[3], reversed_row(dr[3]), dl[0], reversed_row(dr[0]),
                    cost_parts(bits).registers(dl.dtype), sums)
    assert_array_equal(sums, cost[3] + 2 * cost[1])


def test_bad_inputs_raise():
    d = np.zeros((3, 4), np.uint32)
    with pytest.raises(InputError, match="differ"):
        hamming_cost(d, np.zeros((3, 5), np.uint32), 2, 8)
    with pytest.raises(InputError, match="uint32 or uint64"):
        hamming_cost(d.astype(np.int32), d.astype(np.int32), 2, 8)
    with pytest.raises(InputError, match="1..64 bits"):
        hamming_cost(d, d, 2, 65)
    with pytest.raises(InputError, match="at least 1"):
        hamming_cost(d, d, 0, 8)


def test_cosine_cost_of_sign_vectors_is_hamming():
    from stereosim.sva.hamming.cost import cosine_cost, hamming_cost

    rng = np.random.default_rng(11)
    for bits, h, w, dn in ((32, 7, 29, 16), (8, 5, 13, 12)):
        signs = rng.integers(0, 2, size=(2, h, w, bits))
        feats = np.where(signs > 0, 1.0, -1.0) * rng.uniform(0.5, 3.0, size=(2, h, w, 1))
        weights = np.uint64(1) << np.arange(bits, dtype=np.uint64)
        desc = (signs.astype(np.uint64) * weights).sum(axis=3, dtype=np.uint64).astype(np.uint32)
        want = hamming_cost(desc[0], desc[1], dn, bits)
        assert_array_equal(cosine_cost(feats[0], feats[1], dn, bits), want)


def test_cosine_cost_by_hand():
    from stereosim.sva.hamming.cost import cosine_cost

    left = np.array([[[1.0, 0.0], [0.0, 2.0], [3.0, 3.0]]])  # (1, 3, 2)
    right = np.array([[[0.0, 1.0], [1.0, 0.0], [-1.0, -1.0]]])
    got = cosine_cost(left, right, 2, 8)
    # d = 0: cos = 0, 0, -1 -> 4, 4, 8; d = 1: x=0 outside -> 8, cos(L1, R0) = 1 -> 0,
    # cos(L2, R1) = 1/sqrt2 -> rint(4 * 0.2929) = 1
    assert_array_equal(got[0, :, 0], [4, 4, 8])
    assert_array_equal(got[0, :, 1], [8, 0, 1])
