"""The public Python interface: validation, determinism, and the functional model's output."""

import numpy as np
import pytest

import stereosim
from stereosim.core.errors import ConfigError, InputError
from stereosim.sva.pipeline.pipeline import sva_ref


def _pair(h=23, w=61, shift=5, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    # left x shows base[x]; right x - shift shows base[x] too: disparity = shift everywhere
    return base[:, :w].copy(), base[:, shift:].copy()


def test_run_returns_float_disparity_with_inf_invalid_and_fixed_words():
    left, right = _pair()
    res = stereosim.run(left, right, overrides={"sva.disparities": 16})
    assert res.disparity.dtype == np.float32 and res.disparity.shape == left.shape
    invalid = res.disparity_fixed < 0
    assert np.all(np.isinf(res.disparity[invalid]))
    f = res.config.sva.subpixel_bits
    np.testing.assert_array_equal(res.disparity[~invalid], res.disparity_fixed[~invalid] / 2**f)
    # a textured pair shifted by 5 pixels: most valid pixels find d = 5 exactly
    assert np.median(res.disparity[~invalid]) == 5.0


def test_functional_model_equals_the_naive_reference_end_to_end():
    left, right = _pair(h=15, w=41, shift=3, seed=4)
    over = {"sva.disparities": 16, "nna.descriptor": "census", "nna.census.window": [5, 5],
            "nna.census.kind": "symmetric"}
    res = stereosim.run(left, right, overrides=over)
    from stereosim.nna.census_unit.census import census

    ref = sva_ref(census(left, (5, 5), "symmetric"), census(right, (5, 5), "symmetric"), left,
                  res.config.sva, 12)
    np.testing.assert_array_equal(res.disparity_fixed, ref)


def test_rgb_is_converted_with_the_documented_formula():
    left, right = _pair()
    rgb_l = np.repeat(left[:, :, None], 3, axis=2)
    rgb_r = np.repeat(right[:, :, None], 3, axis=2)
    a = stereosim.run(rgb_l, rgb_r, overrides={"sva.disparities": 16})
    b = stereosim.run(left, right, overrides={"sva.disparities": 16})
    np.testing.assert_array_equal(a.disparity_fixed, b.disparity_fixed)


def test_metrics_appear_when_gt_is_given():
    left, right = _pair()
    gt = np.full(left.shape, 5.0, np.float32)
    gt[0, 0] = np.inf
    res = stereosim.run(left, right, overrides={"sva.disparities": 16}, gt=gt)
    m = res.report["metrics"]["all"]
    assert m["n"] == left.size - 1
    assert m["totbad"] == pytest.approx(m["bad2"] + m["invalid"])


@pytest.mark.parametrize(
    "left, right, words",
    [
        (np.zeros((10, 40), np.uint8), np.zeros((10, 41), np.uint8), "differ in size"),
        (np.zeros((10, 40), np.float32), np.zeros((10, 40), np.float32), "float32"),
        (np.zeros((0, 40), np.uint8), np.zeros((0, 40), np.uint8), "at least"),
        (np.zeros((1, 1), np.uint8), np.zeros((1, 1), np.uint8), "at least"),
        (np.zeros((10, 40, 4), np.uint8), np.zeros((10, 40, 4), np.uint8), "channel"),
        ([[1, 2]], [[1, 2]], "numpy array"),
    ],
)
def test_bad_images_raise_one_line(left, right, words):
    with pytest.raises(InputError) as exc:
        stereosim.run(left, right, overrides={"sva.disparities": 16})
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_disparity_range_must_be_smaller_than_width():
    left, right = _pair(w=64)
    with pytest.raises(ConfigError, match="not smaller than the image width 64"):
        stereosim.run(left, right, overrides={"sva.disparities": 64})


def test_unknown_mode_is_refused():
    left, right = _pair()
    with pytest.raises(ConfigError, match="mode"):
        stereosim.run(left, right, mode="rtl")


def test_deterministic_reports():
    left, right = _pair()
    a = stereosim.run(left, right, overrides={"sva.disparities": 16})
    b = stereosim.run(left, right, overrides={"sva.disparities": 16})
    assert a.report == b.report
    np.testing.assert_array_equal(a.disparity_fixed, b.disparity_fixed)
