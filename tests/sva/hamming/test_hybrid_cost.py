"""The hybrid descriptor's cost and automatic weights: the kernels against the references that
read like the definitions (sva.cost, sva.noise), and the whole SVA's two implementations."""

import itertools

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from stereosim.core.config import load_config
from stereosim.core.errors import InputError
from stereosim.sva.hamming.cost import cost_parts, cost_row_add, hamming_cost, hamming_cost_ref
from stereosim.sva.hamming.noise import (
    band_rows,
    frame_weights,
    noise_statistic,
    noise_statistic_ref,
)
from stereosim.sva.pipeline.pipeline import frame_cost, sva_ref, sva_stream

from .test_cost import descriptor_pair, reversed_row

WEIGHTS = [w for w in itertools.product(range(4), repeat=2) if any(w)]


@pytest.mark.parametrize("weights", WEIGHTS)
@pytest.mark.parametrize("parts", [(32, 32), (16, 16), (20, 23), (1, 63)])
def test_two_part_cost_equals_ref(parts, weights):
    dl, dr = descriptor_pair(5, 23, sum(parts), seed=sum(parts) + 7 * weights[0] + weights[1])
    spec = cost_parts(parts, weights)
    got = hamming_cost(dl, dr, 9, spec)
    assert_array_equal(got, hamming_cost_ref(dl, dr, 9, spec))
    # the definition, part by part: the low bits are the first part
    v = int(dl[2, 10]) ^ int(dr[2, 6])
    low = bin(v & ((1 << parts[0]) - 1)).count("1")
    high = bin(v >> parts[0]).count("1")
    assert got[2, 10, 4] == weights[0] * low + weights[1] * high
    assert got[2, 3, 8] == spec.top == weights[0] * parts[0] + weights[1] * parts[1]
    # the streaming row sums take the same cost
    sums = np.zeros((23, 9), np.uint16)
    cost_row_add(dl[1], reversed_row(dr[1]), spec.registers(dl.dtype), sums)
    assert_array_equal(sums, got[1].astype(np.uint16))


def test_one_part_of_weight_one_is_the_hamming_distance():
    dl, dr = descriptor_pair(4, 17, 32, seed=3)
    assert_array_equal(hamming_cost(dl, dr, 8, cost_parts((32,))), hamming_cost_ref(dl, dr, 8, 32))


def test_bad_parts_raise():
    with pytest.raises(InputError, match="weight in 0..3"):
        cost_parts((32, 32), (0, 0))
    with pytest.raises(InputError, match="weight in 0..3"):
        cost_parts((32, 32), (4, 1))
    with pytest.raises(InputError, match="1..64 bits"):
        cost_parts((40, 32))


@pytest.mark.parametrize("rows", [1, 2, 3, 6, 40])
@pytest.mark.parametrize("gradient", [0, 16, 1020])
def test_noise_statistic_equals_ref(rows, gradient):
    img = np.random.default_rng(rows + gradient).integers(0, 256, (12, 19), dtype=np.uint8)
    assert noise_statistic(img, rows, gradient) == noise_statistic_ref(img, rows, gradient)


def test_noise_statistic_reads_gaussian_noise():
    """On a flat grey image with Gaussian noise of sigma s the mean |Laplacian| is about
    6 s sqrt(2 / pi) = 4.79 s (the mask's 36 = sum of its squared entries); a linear ramp
    gives 0."""
    rng = np.random.default_rng(0)
    for sigma in (4.0, 8.0):
        img = np.clip(np.rint(128 + rng.normal(0, sigma, (200, 300))), 0, 255).astype(np.uint8)
        s, n = noise_statistic(img, 200, 1020)
        assert abs(s / n - 4.79 * sigma) < 0.05 * 4.79 * sigma
    ramp = np.add.outer(np.arange(50), 2 * np.arange(60)).astype(np.uint8)
    assert noise_statistic(ramp, 50, 1020)[0] == 0


def test_auto_weights_follow_the_first_rows_only():
    cfg = load_config(overrides={"nna.descriptor": "hybrid", "sva.weight_mode": "auto"}).sva
    b = band_rows(cfg, 100)
    assert b == cfg.box_size // 2 + cfg.median // 2 + 1
    rng = np.random.default_rng(1)
    clean = np.tile(np.arange(80, dtype=np.uint8), (100, 1))
    noisy = clean.copy()
    noisy[:b] = np.clip(clean[:b] + rng.normal(0, 12, (b, 80)), 0, 255).astype(np.uint8)
    below = clean.copy()
    below[b:] = np.clip(clean[b:] + rng.normal(0, 12, (100 - b, 80)), 0, 255).astype(np.uint8)
    assert frame_weights(cfg, clean)[0] == cfg.cost_weights
    weights, noise = frame_weights(cfg, noisy)
    assert weights == cfg.noisy_weights and noise["noisy"]
    assert noise["sum"] > cfg.noise_threshold * noise["count"]
    assert frame_weights(cfg, below)[0] == cfg.cost_weights  # noise below the band: unseen


@pytest.mark.parametrize("mode", ["fixed", "auto"])
@pytest.mark.parametrize("weights", [(3, 1), (1, 2), (0, 3)])
def test_hybrid_sva_stream_equals_ref(mode, weights):
    cfg = load_config(overrides={"nna.descriptor": "hybrid", "sva.disparities": 16,
                                 "sva.cost_weights": list(weights), "sva.weight_mode": mode,
                                 "sva.noisy_weights": [1, 0]}).sva
    dl, dr = descriptor_pair(14, 40, 64, seed=5, flip=0.2)
    rng = np.random.default_rng(2)
    img = np.clip(100 + rng.normal(0, 10, (14, 40)), 0, 255).astype(np.uint8)  # noisy
    got = sva_stream(dl, dr, img, cfg, (32, 32))
    assert_array_equal(got, sva_ref(dl, dr, img, cfg, (32, 32)))
    cost, noise = frame_cost((32, 32), cfg, img)
    assert cost.weights == ((1, 0) if mode == "auto" else weights)
    assert (noise is None) == (mode == "fixed")
