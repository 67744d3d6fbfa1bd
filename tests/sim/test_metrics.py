import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from stereosim.core.errors import InputError
from stereosim.sim.metrics import (
    BAD_KEYS,
    BAD_THRESHOLDS,
    DENSE_KEYS,
    METRIC_KEYS,
    T_KEYS,
    T_THRESHOLDS,
    evaluate,
    fill_invalid,
    format_table,
    mean_metrics,
)

NAN = np.nan
INF = np.inf


def _hand_scene():
    """12 pixels; 'all' evaluates 10 of them (one GT unknown, one masked out).

    Signed errors d - gt, row by row ('x' = invalid disparity):
        row 0:  0    +0.1  -0.2  +0.3  -0.6  +0.9
        row 1: -1.5  +3.0   x    -5.0  (GT unknown)  (masked out, error 100)
    """
    gt = np.full((2, 6), 10.0)
    gt[1, 4] = INF
    err = np.array([[0, 0.1, -0.2, 0.3, -0.6, 0.9], [-1.5, 3.0, 0, -5.0, 0, 100.0]])
    disp = gt + err
    disp[1, 2] = NAN
    disp[1, 4] = 7.0
    mask_all = np.ones((2, 6), bool)
    mask_all[1, 5] = False
    nonocc = np.zeros((2, 6), bool)
    nonocc[0, :3] = True  # errors 0, 0.1, 0.2
    nonocc[1, 2] = True  # invalid
    nonocc[1, 4] = True  # GT unknown: not counted
    return disp, gt, {"all": mask_all, "nonocc": nonocc}


def test_hand_computed_all_mask():
    disp, gt, masks = _hand_scene()
    r = evaluate(disp, gt, masks)["all"]
    # n = 10 evaluated, 9 valid with |errors| 0 .1 .2 .3 .6 .9 1.5 3 5, 1 invalid.
    assert r["n"] == 10
    assert r["bad0.5"] == pytest.approx(50.0)  # .6 .9 1.5 3 5
    assert r["bad1"] == pytest.approx(30.0)  # 1.5 3 5
    assert r["bad2"] == pytest.approx(20.0)  # 3 5
    assert r["bad4"] == pytest.approx(10.0)  # 5
    assert r["invalid"] == pytest.approx(10.0)
    assert r["totbad"] == pytest.approx(30.0)
    assert r["avgerr"] == pytest.approx(11.6 / 9)
    assert r["rms"] == pytest.approx(math.sqrt(37.56 / 9))
    assert r["rms_valid"] == r["rms"]
    assert r["fill_factor"] == pytest.approx(90.0)
    # T: percent of the 9 valid pixels.
    assert r["T0.125"] == pytest.approx(700 / 9)
    assert r["T0.25"] == pytest.approx(600 / 9)
    assert r["T0.5"] == pytest.approx(500 / 9)
    assert r["T0.75"] == pytest.approx(400 / 9)
    assert r["T1"] == pytest.approx(300 / 9)
    assert r["T2"] == pytest.approx(200 / 9)
    assert r["T4"] == pytest.approx(100 / 9)
    # M: among the 6 valid pixels with error <= 1 (0 .1 .2 .3 .6 .9).
    assert r["M0.125"] == pytest.approx(400 / 6)
    assert r["M0.25"] == pytest.approx(300 / 6)
    assert r["M0.5"] == pytest.approx(200 / 6)
    assert r["M0.75"] == pytest.approx(100 / 6)
    # F: precision g/9, recall g/10, so F = 2g / 19.
    assert r["F0.5"] == pytest.approx(8 / 19)  # g = 4
    assert r["F0.75"] == pytest.approx(10 / 19)  # g = 5
    assert r["F1.0"] == pytest.approx(12 / 19)  # g = 6
    assert set(r) == set(METRIC_KEYS)


def test_hand_computed_nonocc_mask():
    disp, gt, masks = _hand_scene()
    r = evaluate(disp, gt, masks)["nonocc"]
    assert r["n"] == 4
    assert all(r[k] == 0 for k in BAD_KEYS)
    assert r["invalid"] == pytest.approx(25.0)
    assert r["totbad"] == pytest.approx(25.0)
    assert r["fill_factor"] == pytest.approx(75.0)
    assert r["avgerr"] == pytest.approx(0.1)
    assert r["rms"] == pytest.approx(math.sqrt(0.05 / 3))
    assert r["T0.125"] == pytest.approx(100 / 3)
    assert r["T0.25"] == 0
    assert r["M0.125"] == pytest.approx(100 / 3)
    assert r["F0.5"] == pytest.approx(6 / 7)


def test_uint8_mask_and_float32_inputs():
    disp, gt, masks = _hand_scene()
    as_u8 = {k: m.astype(np.uint8) * 255 for k, m in masks.items()}
    a = evaluate(disp.astype(np.float32), gt.astype(np.float32), as_u8)
    assert a["all"]["n"] == 10
    assert a["all"]["bad2"] == pytest.approx(20.0)


def test_empty_and_all_invalid():
    gt = np.full((2, 2), 5.0)
    disp = np.full((2, 2), NAN)
    r = evaluate(disp, gt, {"none": np.zeros((2, 2), bool), "all": np.ones((2, 2), bool)})
    assert r["none"]["n"] == 0
    assert math.isnan(r["none"]["bad2"]) and math.isnan(r["none"]["avgerr"])
    a = r["all"]
    assert a["invalid"] == 100 and a["fill_factor"] == 0 and a["bad2"] == 0
    assert a["totbad"] == 100
    assert math.isnan(a["avgerr"]) and math.isnan(a["T1"]) and math.isnan(a["F1.0"])


def test_perfect_disparity():
    gt = np.array([[1.25, 2.0], [INF, 9.5]])
    r = evaluate(gt.copy(), gt, {"all": np.ones((2, 2), bool)})["all"]
    assert r["n"] == 3 and r["totbad"] == 0 and r["avgerr"] == 0 and r["fill_factor"] == 100
    assert r["F0.5"] == 1.0 and r["M0.125"] == 0


def test_shape_mismatch_raises():
    with pytest.raises(InputError, match="GT"):
        evaluate(np.zeros((2, 3)), np.zeros((3, 2)), {})
    with pytest.raises(InputError, match="mask 'nonocc'"):
        evaluate(np.zeros((2, 3)), np.zeros((2, 3)), {"nonocc": np.ones((2, 2), bool)})
    with pytest.raises(InputError, match="2-D"):
        evaluate(np.zeros(4), np.zeros(4), {})


def _naive(disp, gt, mask):
    """Per-pixel loop, written independently of sim.metrics."""
    n = nv = 0
    bad = dict.fromkeys(BAD_THRESHOLDS, 0)
    over = dict.fromkeys(T_THRESHOLDS, 0)
    for d, g, m in zip(disp.ravel(), gt.ravel(), mask.ravel(), strict=True):
        if not m or not math.isfinite(g):
            continue
        n += 1
        if not math.isfinite(d):
            continue
        nv += 1
        e = abs(float(d) - float(g))
        for t in bad:
            bad[t] += e > t
        for t in over:
            over[t] += e > t
    return n, nv, bad, over


finite_or_not = st.one_of(
    st.floats(-8, 72, allow_nan=False, width=32), st.sampled_from([NAN, INF, -INF])
)


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(st.integers(1, 6), st.integers(1, 7)).flatmap(
        lambda shape: st.tuples(
            arrays(np.float32, shape, elements=finite_or_not),
            arrays(np.float32, shape, elements=finite_or_not),
            arrays(np.bool_, shape),
        )
    )
)
def test_properties_against_naive_loop(data):
    disp, gt, mask = data
    r = evaluate(disp, gt, {"m": mask})["m"]
    n, nv, bad, over = _naive(disp, gt, mask)
    assert r["n"] == n
    if n == 0:
        assert math.isnan(r["totbad"]) and math.isnan(r["fill_factor"])
        return
    assert r["totbad"] == pytest.approx(r["bad2"] + r["invalid"])
    assert r["fill_factor"] == pytest.approx(100 - r["invalid"])
    assert r["invalid"] == pytest.approx(100 * (n - nv) / n)
    for key, t in zip(BAD_KEYS, BAD_THRESHOLDS, strict=True):
        assert r[key] == pytest.approx(100 * bad[t] / n)
    for key, t in zip(T_KEYS, T_THRESHOLDS, strict=True):
        if nv:
            assert r[key] == pytest.approx(100 * over[t] / nv)
            if t in bad:  # bad_t counts the same pixels over n instead of over the valid ones
                assert r[key] * r["fill_factor"] / 100 == pytest.approx(r[f"bad{t:g}"])
        else:
            assert math.isnan(r[key])
    for key in ("F0.5", "F0.75", "F1.0"):
        assert nv == 0 or 0 <= r[key] <= 1


def test_mean_metrics_is_plain_mean_per_mask_and_key():
    a = {"all": {"bad2": 10.0, "n": 100}, "nonocc": {"bad2": 4.0}}
    b = {"all": {"bad2": 20.0, "n": 300}}
    m = mean_metrics([a, b])
    assert m == {"all": {"bad2": 15.0, "n": 200.0}, "nonocc": {"bad2": 4.0}}


def test_format_table_exact_text():
    rows = [("A", {"n": 10.0, "bad2": 1.0}), ("Bee", {"n": 20.0, "bad2": 2.5})]
    expected = (
        "scene   n   bad2  avgerr\n"
        "-----  --  -----  ------\n"
        "A      10  1.000       -\n"
        "Bee    20  2.500       -\n"
        "-----  --  -----  ------\n"
        "MEAN   15  1.750       -\n"
    )
    assert format_table(rows, ["n", "bad2", "avgerr"]) == expected
    assert format_table([], ["bad2"]) == "scene  bad2\n-----  ----\n"


# ---- dense metrics: the map filled as the Middlebury evaluation fills sparse results ----------


def _fill_reference(disp):
    """The fill rule as written: for each invalid pixel, walk left and right along its row to
    the nearest valid disparities and take the smaller (the one there is at a row's end)."""
    d = np.array(disp, dtype=np.float64)
    out = d.copy()
    h, w = d.shape
    for y in range(h):
        for x in range(w):
            if np.isfinite(d[y, x]):
                continue
            seen = []
            for step in (-1, 1):
                k = x + step
                while 0 <= k < w and not np.isfinite(d[y, k]):
                    k += step
                if 0 <= k < w:
                    seen.append(d[y, k])
            out[y, x] = min(seen) if seen else np.inf
    return out


def test_fill_invalid_by_hand():
    d = np.array([[np.inf, 3, np.inf, np.inf, 5, np.inf],
                  [np.inf] * 6,
                  [1, np.nan, 2, 7, -np.inf, 4]])
    np.testing.assert_array_equal(fill_invalid(d), [[3, 3, 3, 3, 5, 5],
                                                    [np.inf] * 6,
                                                    [1, 1, 2, 7, 4, 4]])


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 6), st.integers(1, 12), st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_fill_invalid_equals_the_reference(h, w, seed, holes):
    rng = np.random.default_rng(seed)
    d = rng.uniform(0, 64, (h, w))
    d[rng.random((h, w)) < holes] = np.inf
    np.testing.assert_array_equal(fill_invalid(d), _fill_reference(d))


def test_dense_metrics_score_the_filled_map():
    rng = np.random.default_rng(3)
    gt = rng.uniform(0, 30, (20, 30))
    disp = gt + rng.normal(0, 1.5, gt.shape)
    disp[rng.random(gt.shape) < 0.2] = np.inf
    masks = {"all": np.ones(gt.shape, bool), "left": np.zeros(gt.shape, bool)}
    masks["left"][:, :15] = True
    got = evaluate(disp, gt, masks)
    filled = evaluate(fill_invalid(disp), gt, masks)
    for mask in masks:
        for key in DENSE_KEYS:
            assert got[mask][f"dense_{key}"] == filled[mask][key]
        assert filled[mask]["invalid"] == 0.0 and got[mask]["invalid"] > 0
    dense_only = evaluate(gt + 0.25, gt, {"all": masks["all"]})["all"]
    for key in DENSE_KEYS:  # nothing to fill: dense = sparse
        assert dense_only[f"dense_{key}"] == dense_only[key]
