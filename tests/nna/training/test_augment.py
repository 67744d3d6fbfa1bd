"""Training's augmentation (nna.augment): the original recipe unchanged, each new change as its
definition says, and every draw reproducible from the seed."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from stereosim.core.errors import ConfigError
from stereosim.nna.training.augment import RECIPES, photometric, rows_at, vertical_offsets
from stereosim.nna.training.trainconfig import TrainConfig


def _old_recipe(patches, cfg, rng, shared_axis=False):
    """The recipe before nna.augment, as it was written: gain, offset, Gaussian noise."""
    n = patches.shape[1] if shared_axis else patches.shape[0]
    gain = rng.uniform(1.0 - cfg.gain, 1.0 + cfg.gain, n).astype(np.float32)[:, None, None]
    offset = rng.uniform(-cfg.offset, cfg.offset, n).astype(np.float32)[:, None, None]
    sigma = rng.uniform(0.0, cfg.noise_max, n).astype(np.float32)[:, None, None]
    noise = rng.standard_normal(patches.shape).astype(np.float32) * sigma
    v = gain * (patches - 128.0) + 128.0 + offset + noise
    return np.clip(np.rint(v), 0.0, 255.0)


def _patches(shape, seed=0):
    return np.random.default_rng(seed).integers(0, 256, shape).astype(np.float32)


@pytest.mark.parametrize("shared", [False, True])
def test_the_basic_recipe_is_the_original_bit_for_bit(shared):
    cfg = TrainConfig()
    p = _patches((2, 5, 9, 20) if shared else (5, 9, 20))
    got = photometric(p, cfg, np.random.default_rng(7), shared_axis=shared)
    want = _old_recipe(p, cfg, np.random.default_rng(7), shared_axis=shared)
    np.testing.assert_array_equal(got, want)


def test_each_change_by_its_definition():
    p = np.full((1, 9, 9), 100.0, np.float32)
    p[0, 4, 4] = 200.0
    none = TrainConfig(gain=0.0, offset=0.0, noise_max=0.0)
    np.testing.assert_array_equal(photometric(p, none, np.random.default_rng(0)), p)
    # gamma alone: 255 (v / 255) ** g with log g drawn from U(-0.3, 0.3)
    rng = np.random.default_rng(1)
    for _ in range(3):  # the draws photometric makes before gamma's
        rng.uniform(size=1)
    g = np.exp(rng.uniform(-0.3, 0.3, 1))[0]
    got = photometric(p, replace(none, gamma=0.3), np.random.default_rng(1))
    np.testing.assert_array_equal(got, np.rint(255.0 * (p / 255.0) ** np.float32(g)))
    # defocus alone: the crop through cv2's Gaussian of the drawn sigma
    for seed in range(20):  # a seed whose sigma is large enough to move the bright pixel
        rng = np.random.default_rng(seed)
        for _ in range(3):
            rng.uniform(size=1)
        s = rng.uniform(0.0, 1.5, 1)[0]
        if s > 0.5:
            break
    got = photometric(p, replace(none, blur_max=1.5), np.random.default_rng(seed))
    blurred = cv2.GaussianBlur(p[0], (0, 0), float(s), borderType=cv2.BORDER_REPLICATE)
    np.testing.assert_array_equal(got[0], np.clip(np.rint(blurred), 0, 255))
    assert got[0, 4, 4] < 200 and got[0, 4, 3] > 100  # the bright pixel spread


def test_shot_noise_grows_with_the_signal():
    cfg = TrainConfig(gain=0.0, offset=0.0, noise_max=0.0, shot_noise=4.0)
    dark = photometric(np.full((400, 8, 8), 20.0, np.float32), cfg, np.random.default_rng(3))
    bright = photometric(np.full((400, 8, 8), 220.0, np.float32), cfg, np.random.default_rng(3))
    # variance k v with k ~ U(0, 4): mean k = 2, so about 40 and 440 grey levels squared
    assert 25 < np.var(dark - 20.0) < 60 and 330 < np.var(bright - 220.0) < 560


def test_vertical_misalignment_interpolates_between_rows():
    img = np.arange(5 * 4, dtype=np.float64).reshape(5, 4) * 10  # row r holds 40 r .. 40 r + 30
    rows, cols = np.array([1, 2, 3]), np.array([0, 1, 5, -1])
    np.testing.assert_array_equal(rows_at(img, rows, cols, 0.0), img[[[1], [2], [3]], [0, 1, 3, 0]])
    np.testing.assert_allclose(rows_at(img, rows, cols, 0.25),
                               img[[[1], [2], [3]], [0, 1, 3, 0]] + 0.25 * 40)
    np.testing.assert_allclose(rows_at(img, rows, cols, -0.5)[0], img[1, [0, 1, 3, 0]] - 20)
    np.testing.assert_array_equal(rows_at(img, np.array([4]), cols, 0.5),
                                  img[[[4]], [0, 1, 3, 0]])  # clamped at the last row
    assert not vertical_offsets(TrainConfig(), np.random.default_rng(0), 4).any()
    dy = vertical_offsets(TrainConfig(vshift_max=0.5), np.random.default_rng(0), 1000)
    assert dy.min() >= -0.5 and dy.max() <= 0.5 and dy.std() > 0.25


def test_the_robust_recipe_is_a_valid_config_and_negative_ranges_are_refused():
    TrainConfig(**RECIPES["robust"])
    for key in ("gamma", "shot_noise", "blur_max", "vshift_max"):
        with pytest.raises(ConfigError, match=key):
            TrainConfig(**{key: -0.1})
