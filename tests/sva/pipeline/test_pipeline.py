"""The whole SVA: the fused streaming kernels == the composition of the naive references."""

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.nna.census_unit.census import census
from stereosim.sva.box.aggregation import box_filter_ref
from stereosim.sva.hamming.cost import hamming_cost_ref
from stereosim.sva.pipeline.pipeline import sva_ref, sva_stream
from stereosim.sva.sgm.sgm import sgm_ref
from stereosim.sva.wta.wta import INVALID


def sva_config(**overrides):
    return load_config(overrides={f"sva.{k}": v for k, v in overrides.items()}).sva


def descriptor_pair(h, w, bits, seed, flip=0.05):
    """Random descriptors; the right view is the left one shifted by a per-row disparity
    (DR(x - s) = DL(x)) with a fraction ``flip`` of its bits flipped."""
    rng = np.random.default_rng(seed)
    shifts = rng.integers(0, 12, size=h)
    weights = np.uint64(1) << np.arange(bits, dtype=np.uint64)
    scene = (rng.integers(0, 2, size=(h, w + 12, bits), dtype=np.uint64) * weights).sum(
        axis=2, dtype=np.uint64
    )
    left = scene[:, :w].copy()
    right = np.stack([scene[y, s : s + w] for y, s in enumerate(shifts)])
    right ^= ((rng.random((h, w, bits)) < flip) * weights).sum(axis=2, dtype=np.uint64)
    dtype = np.uint32 if bits <= 32 else np.uint64
    img = rng.integers(0, 256, size=(h, w), dtype=np.uint8)
    return left.astype(dtype), right.astype(dtype), img


def census_pair(h, w, seed, shift=5):
    """Census descriptors (31 bits, the chip default) of a smooth random texture and its copy
    shifted by ``shift`` pixels plus a little noise: structured costs with a real minimum."""
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, size=(h + 4, w + shift + 4)).astype(np.float64)
    smooth = (base[:-4, :-4] + base[2:-2, 2:-2] + base[4:, 4:] + base[2:-2, :-4]) / 4
    left = smooth[:, shift:].astype(np.uint8)
    right = np.clip(smooth[:, :w] + rng.integers(-3, 4, size=(h, w)), 0, 255).astype(np.uint8)
    return census(left), census(right), left


def check(desc_l, desc_r, img, cfg, bits):
    got = sva_stream(desc_l, desc_r, img, cfg, bits)
    assert got.dtype == np.int32 and got.shape == desc_l.shape
    assert_array_equal(got, sva_ref(desc_l, desc_r, img, cfg, bits))
    return got


# Every path count x sub-pixel mode x LR on/off; the remaining knobs cycle through their
# interesting values (small register widths so the saturations bite, F = 0 and F > 0,
# uniqueness off and on, adaptive P2, all box sizes and median filters).
CYCLED = [
    {
        "box_size": 5,
        "cost_bits": 11,
        "path_bits": 13,
        "sum_bits": 16,
        "subpixel_bits": 4,
        "uniqueness": 5,
        "p2_adaptive": False,
        "median": 0,
        "lr_max_diff": 1,
    },
    {
        "box_size": 3,
        "cost_bits": 6,
        "path_bits": 8,
        "sum_bits": 9,
        "subpixel_bits": 0,
        "uniqueness": 0,
        "p2_adaptive": True,
        "median": 3,
        "lr_max_diff": 0,
    },
    {
        "box_size": 1,
        "cost_bits": 7,
        "path_bits": 14,
        "sum_bits": 16,
        "subpixel_bits": 8,
        "uniqueness": 20,
        "p2_adaptive": True,
        "median": 5,
        "lr_max_diff": 2,
    },
    {
        "box_size": 7,
        "cost_bits": 15,
        "path_bits": 9,
        "sum_bits": 10,
        "subpixel_bits": 1,
        "uniqueness": 0,
        "p2_adaptive": False,
        "median": 0,
        "lr_max_diff": 1,
        "p1": 40,
        "p2": 300,
    },
]
PRODUCT = [
    dict(paths=paths, subpixel=mode, lr_check=lr, **CYCLED[i % len(CYCLED)])
    for i, (paths, mode, lr) in enumerate(
        itertools.product([1, 2, 3, 4], ["off", "parabola", "equiangular"], [False, True])
    )
]


@pytest.mark.parametrize("overrides", PRODUCT, ids=lambda o: "-".join(str(v) for v in o.values()))
def test_stream_equals_ref_config_product(overrides):
    cfg = sva_config(disparities=16, **overrides)
    dl, dr, img = descriptor_pair(7, 29, 31, seed=len(str(overrides)))
    check(dl, dr, img, cfg, 31)


@pytest.mark.parametrize(
    "overrides", PRODUCT[::5], ids=lambda o: "-".join(str(v) for v in o.values())
)
def test_stream_equals_ref_on_census(overrides):
    cfg = sva_config(disparities=16, **overrides)
    dl, dr, img = census_pair(9, 31, seed=3)
    got = check(dl, dr, img, cfg, 31)
    assert (got != INVALID).any()


@pytest.mark.parametrize(("paths", "sum_bits"), [(1, 16), (4, 9)])
def test_saturation_caps_bite(paths, sum_bits):
    # narrow registers: the box, path and sum caps all occur inside the pipeline (checked on the
    # reference stages), and the stream must still agree with the reference on every word
    cfg = sva_config(
        disparities=16,
        box_size=5,
        cost_bits=8,
        path_bits=8,
        sum_bits=sum_bits,
        p1=20,
        p2=150,
        paths=paths,
        subpixel="parabola",
        lr_check=True,
        uniqueness=0,
    )
    dl, dr, img = descriptor_pair(7, 29, 31, seed=11)
    cost = hamming_cost_ref(dl, dr, 16, 31)
    agg = box_filter_ref(cost, 5, 8)
    assert (agg == 255).any() and (agg < 100).any()
    s = sgm_ref(agg, p1=20, p2=150, paths=paths, path_bits=8, sum_bits=sum_bits)
    cap = 255 if paths == 1 else (1 << sum_bits) - 1  # one path: S = L, which hits its cap
    assert (s == cap).any() and (s < cap).any()
    got = check(dl, dr, img, cfg, 31)
    assert (got != INVALID).any()


@pytest.mark.parametrize(
    ("height", "width", "disparities"), [(5, 17, 16), (3, 33, 32), (1, 17, 16)]
)
def test_largest_disparity_range_for_the_width(height, width, disparities):
    # D = W - 1: the first D columns have no full set of right pixels
    cfg = sva_config(disparities=disparities, box_size=3, paths=4, lr_check=True)
    dl, dr, img = descriptor_pair(height, width, 31, seed=width)
    check(dl, dr, img, cfg, 31)


@pytest.mark.parametrize("paths", [1, 2, 3, 4])
def test_tall_frame_wraps_the_path_rings(paths):
    # H > W + 2: the top paths' rings of W + 1 and W + 2 path rows wrap around twice
    cfg = sva_config(disparities=16, box_size=3, paths=paths, lr_check=True, p2_adaptive=True)
    dl, dr, img = descriptor_pair(41, 17, 31, seed=paths)
    check(dl, dr, img, cfg, 31)


@pytest.mark.parametrize(
    "overrides",
    [
        {"paths": 1, "subpixel": "off", "median": 0, "lr_check": False, "uniqueness": 0},
        {"paths": 2, "subpixel": "parabola", "median": 3, "lr_check": True, "uniqueness": 10},
        {"paths": 3, "subpixel": "equiangular", "median": 5, "lr_check": True,
         "p2_adaptive": True},
        {"paths": 4, "subpixel": "parabola", "median": 3, "lr_check": False, "uniqueness": 5,
         "p2_adaptive": True},
    ],
    ids=lambda o: f"paths{o['paths']}",
)
def test_largest_disparity_range_every_path_count(overrides):
    # D = 256, the largest: a d-loop of 256 uint16 lanes per path, on an odd width
    cfg = sva_config(disparities=256, box_size=1, **overrides)
    dl, dr, img = descriptor_pair(3, 259, 31, seed=overrides["paths"])
    check(dl, dr, img, cfg, 31)


@pytest.mark.parametrize("disparities", [48, 80])
@pytest.mark.parametrize("paths", [1, 2, 3, 4])
def test_a_partial_last_chunk_of_disparities(disparities, paths):
    # the SGM's d-loop runs whole chunks of 32 uint16 lanes and then the last D mod 32 (16 for
    # these D, the configurable ones being multiples of 16) under a mask of lanes: S, the rows'
    # minima, WTA's winner and the diagonal search of the right disparity must see those last
    # disparities and nothing past them
    cfg = sva_config(disparities=disparities, box_size=3, paths=paths, lr_check=True,
                     subpixel="parabola", p2_adaptive=True, uniqueness=5)
    dl, dr, img = descriptor_pair(4, disparities + 9, 31, seed=disparities + paths)
    got = check(dl, dr, img, cfg, 31)
    assert (got != INVALID).any()


def test_largest_disparity_range():
    cfg = sva_config(disparities=256, box_size=1, paths=4, lr_check=True, median=3)
    dl, dr, img = descriptor_pair(2, 257, 31, seed=256)
    check(dl, dr, img, cfg, 31)


@pytest.mark.parametrize("shape", [(1, 20), (2, 20), (4, 21)])
@pytest.mark.parametrize("box_size", [9, 15])
def test_fewer_rows_than_the_box(shape, box_size):
    # the window is clamped at the top and the bottom at once; with k = 15 on 20 columns
    # it is clamped on both sides horizontally too
    cfg = sva_config(disparities=16, box_size=box_size, paths=4)
    dl, dr, img = descriptor_pair(*shape, 31, seed=shape[0])
    check(dl, dr, img, cfg, 31)


def test_flat_descriptors():
    dl = np.full((7, 21), 0x1234567, np.uint32)
    img = np.full((7, 21), 90, np.uint8)
    for lr in (False, True):
        cfg = sva_config(disparities=16, lr_check=lr, uniqueness=0, subpixel="parabola")
        got = check(dl, dl.copy(), img, cfg, 31)
        assert (got[:, :] <= 0).all()  # every cost ties: d* = 0, so word 0 (or invalid)


@settings(max_examples=15, deadline=None)
@given(
    h=st.integers(1, 8),
    w=st.integers(17, 30),
    box_size=st.sampled_from([1, 3, 5]),
    cost_bits=st.integers(6, 15),
    p1=st.integers(0, 50),
    p2=st.integers(0, 300),
    p2_adaptive=st.booleans(),
    p2_slope=st.integers(0, 64),
    path_bits=st.integers(8, 14),
    sum_bits=st.integers(8, 16),
    paths=st.integers(1, 4),
    uniqueness=st.sampled_from([0, 5, 40]),
    subpixel=st.sampled_from(["off", "parabola", "equiangular"]),
    subpixel_bits=st.integers(0, 8),
    lr_check=st.booleans(),
    lr_max_diff=st.integers(0, 3),
    median=st.sampled_from([0, 3, 5]),
    bits=st.sampled_from([8, 31, 64]),
    seed=st.integers(0, 2**16),
)
def test_stream_equals_ref_hypothesis(h, w, bits, seed, **overrides):
    cfg = sva_config(disparities=16, **overrides)
    dl, dr, img = descriptor_pair(h, w, bits, seed)
    check(dl, dr, img, cfg, bits)


def test_bad_inputs_raise():
    dl, dr, img = descriptor_pair(3, 16, 31, seed=0)
    with pytest.raises(InputError, match="not smaller than the image width"):
        sva_stream(dl, dr, img, sva_config(disparities=16), 31)
    dl, dr, img = descriptor_pair(3, 20, 31, seed=0)
    with pytest.raises(InputError, match="grey image"):
        sva_stream(dl, dr, img[:, :5], sva_config(disparities=16), 31)
    # a config built without load_config passes the same checks before any kernel runs
    too_wide = dataclasses.replace(sva_config(disparities=16), path_bits=15)
    with pytest.raises(ConfigError, match=r"'sva.path_bits' must be in \[8, 14\]; got 15"):
        sva_stream(dl, dr, img, too_wide, 31)
    too_many = dataclasses.replace(sva_config(disparities=16), paths=5)
    with pytest.raises(ConfigError, match=r"'sva.paths' must be in \[1, 4\]; got 5"):
        sva_stream(dl, dr, img, too_many, 31)


@pytest.mark.parametrize("box, median, paths", [(1, 0, 4), (3, 3, 2), (5, 5, 4), (7, 3, 1)])
def test_stream_fed_row_by_row_equals_whole_frame(box, median, paths):
    """The cycle model feeds SvaStream rows as they arrive; any feeding order of row counts
    must give the whole-frame result, and rows reported final must already be final."""
    from stereosim.sva.pipeline.pipeline import SvaStream

    desc_l, desc_r, img = descriptor_pair(13, 37, 32, seed=box + median)
    cfg = sva_config(disparities=16, box_size=box, median=median, paths=paths)
    whole = sva_stream(desc_l, desc_r, img, cfg, 32)
    rng = np.random.default_rng(box)
    stream = SvaStream(desc_l, desc_r, img, cfg, 32)
    rows_in, final = 0, 0
    while rows_in < 13:
        rows_in = min(13, rows_in + int(rng.integers(0, 4)))
        new_final = stream.advance(rows_in)
        assert new_final >= final
        # a row is final only when every input row it depends on has arrived
        r, m = box // 2, median // 2
        if 0 < new_final < 13:
            assert new_final + r + m <= rows_in
        assert_array_equal(stream.q[:new_final], whole[:new_final])
        final = new_final
    assert final == 13


@pytest.mark.parametrize("median", [0, 3, 5])
def test_frame_taller_than_the_median_ring(median):
    """The words before the median live in a ring of 2 m + 32 rows: a taller frame, whole or
    fed in uneven steps, must give the reference's words."""
    from stereosim.sva.pipeline.pipeline import SvaStream

    cfg = sva_config(disparities=16, box_size=3, median=median, paths=4, lr_check=True)
    desc_l, desc_r, img = descriptor_pair(83, 17, 31, seed=median)
    whole = check(desc_l, desc_r, img, cfg, 31)
    stream = SvaStream(desc_l, desc_r, img, cfg, 31)
    rng = np.random.default_rng(median)
    rows_in = 0
    while rows_in < 83:
        rows_in = min(83, rows_in + int(rng.integers(0, 40)))
        final = stream.advance(rows_in)
        assert_array_equal(stream.q[:final], whole[:final])
    assert final == 83


@pytest.mark.parametrize("median", [0, 3, 5])
def test_stream_keeps_no_second_frame(median):
    """Besides its inputs and the output words, the stream's buffers grow with W x D, never
    with H x W: the words before the median are a ring of rows."""
    from stereosim.sva.pipeline.pipeline import SvaStream

    h, w, dn = 200, 40, 16
    desc_l, desc_r, img = descriptor_pair(h, w, 31, seed=1)
    stream = SvaStream(desc_l, desc_r, img, sva_config(disparities=dn, median=median), 31)
    stream.advance(h)

    def arrays(obj):
        if isinstance(obj, np.ndarray):
            yield obj
        elif isinstance(obj, tuple):
            for item in obj:
                yield from arrays(item)

    inputs = {id(stream.desc_l), id(stream.desc_r), id(stream.img_l), id(stream.q)}
    state = [a for v in vars(stream).values() for a in arrays(v) if id(a) not in inputs]
    assert state, "the stream's state was not found"
    for a in state:
        assert a.nbytes <= 4 * (w + dn) * (dn + 2) * 2 + 4 * w * (2 * (median // 2) + 32)


@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {"median": 0, "lr_check": False, "box_size": 1, "paths": 2},
        {"subpixel": "parabola", "uniqueness": 5, "median": 5, "p2_adaptive": True},
    ],
)
def test_cost_volume_backend_equals_stream(overrides):
    from stereosim.sva.hamming.cost import hamming_cost
    from stereosim.sva.pipeline.pipeline import sva_cost_volume

    for h, w, bits, seed in ((17, 41, 32, 3), (9, 35, 31, 4)):
        left, right, img = descriptor_pair(h, w, bits, seed)
        cfg = sva_config(disparities=16, **overrides)
        want = sva_stream(left, right, img, cfg, bits)
        got = sva_cost_volume(hamming_cost(left, right, 16, bits), img, cfg)
        assert_array_equal(got, want)
        assert np.count_nonzero(want >= 0) > want.size // 4  # not a trivially invalid map


def test_cost_volume_backend_refuses_bad_volumes():
    from stereosim.sva.pipeline.pipeline import sva_cost_volume

    cfg = sva_config(disparities=16)
    img = np.zeros((8, 30), np.uint8)
    with pytest.raises(InputError, match="uint8"):
        sva_cost_volume(np.zeros((8, 30, 16), np.uint16), img, cfg)
    with pytest.raises(InputError, match="disparities"):
        sva_cost_volume(np.zeros((8, 30, 32), np.uint8), img, cfg)
