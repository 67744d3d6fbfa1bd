"""The hybrid descriptor as a chip option: the cycle model (both engines) equals the functional
model bit for bit, the plan sizes what the wider words and the census unit need, and a
configuration that cannot be built says so in one line."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.core.timing import lg, tree_cycles
from stereosim.nna.descriptor import compute_descriptor, descriptor_parts
from stereosim.nna.geometry import census_rows, layer_rows
from stereosim.sim.api import run, run_stream
from stereosim.sim.cycle.plan import build_plan
from stereosim.sva.hamming.timing import hamming_levels

ROBUST = "benchmarks/models/mixed5x5-wide-n6.int8.npz"
HYBRID = {"nna.descriptor": "hybrid", "sva.disparities": 16}


def pair(h=26, w=72, shift=3, seed=0, sigma=0.0):
    """A textured pair, the right view the left shifted by ``shift``, with noise of ``sigma``
    on both."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w + shift]
    base = (128 + 60 * np.sin(x / 3.0 + seed) * np.cos(y / 4.0)  # smooth, with fine texture
            + rng.integers(-3, 4, (h, w + shift)))
    left, right = base[:, shift:], base[:, :w]
    out = []
    for img in (left, right):
        noisy = img + rng.normal(0, sigma, img.shape) if sigma else img
        out.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8))
    return out


CASES = {
    "single layer": {},
    "three layers, auto": {"nna.cnn.weights": ROBUST, "sva.weight_mode": "auto"},
    "column tiles, wide census": {"nna.stereo_submodules": 4, "nna.census.window": [13, 3],
                                  "nna.census.kind": "symmetric", "nna.cnn.weights": ROBUST},
    "row bands, auto": {"nna.stereo_submodules": 6, "nna.split": "rows",
                        "sva.weight_mode": "auto", "sva.noisy_weights": [1, 0]},
    "small FIFOs, three layers": {"nna.cnn.weights": ROBUST, "fifo.nna_to_sva_depth": 2,
                                  "fifo.source_to_nna_depth": 1, "sva.cost_weights": [1, 3]},
}


@pytest.mark.parametrize("engine", ["readable", "fast"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_cycle_model_equals_functional(case, engine):
    over = {**HYBRID, **CASES[case]}
    left, right = pair(sigma=9.0 if "auto" in case else 0.0)
    want = run(left, right, mode="functional", overrides=over)
    got = run(left, right, mode="cycle", overrides={**over, "sim.engine": engine})
    np.testing.assert_array_equal(got.disparity_fixed, want.disparity_fixed)
    assert got.report["descriptor"]["frame"] == want.report["descriptor"]["frame"]
    if "auto" in case:  # sigma 9 on both views: the noisy weights
        frame = got.report["descriptor"]["frame"]
        assert frame["noise"]["noisy"] and frame["weights"] == list(got.config.sva.noisy_weights)


def test_a_stream_reports_each_frames_weights_and_both_engines_agree():
    over = {**HYBRID, "sva.weight_mode": "auto"}
    frames = [pair(seed=1), pair(seed=2, sigma=10.0), pair(seed=3)]
    words = {}
    for engine in ("readable", "fast"):
        stream = run_stream(frames, overrides={**over, "sim.engine": engine})
        words[engine] = [out.disparity_fixed for out in stream]
        noisy = [f["noise"]["noisy"] for f in stream.report["descriptor"]["frames"]]
        assert noisy == [False, True, False]
    for a, b in zip(words["readable"], words["fast"], strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_descriptor_word_is_the_cnn_bits_below_the_census_bits():
    cfg = load_config(overrides=HYBRID).nna
    left, _ = pair()
    word = compute_descriptor(left, cfg)
    cnn = compute_descriptor(left, load_config().nna)
    census = compute_descriptor(left, load_config(overrides={"nna.descriptor": "census"}).nna)
    assert word.dtype == np.uint64
    np.testing.assert_array_equal(word & np.uint64(0xFFFFFFFF), cnn.astype(np.uint64))
    np.testing.assert_array_equal(word >> np.uint64(32), census.astype(np.uint64))
    assert descriptor_parts(cfg) == (("cnn", 32), ("census", 32))


def test_the_plan_follows_the_wider_words_and_the_weighted_cost():
    plan = build_plan(load_config(overrides={**HYBRID, "sva.weight_mode": "auto"}), (40, 80))
    one = build_plan(load_config(overrides={"sva.disparities": 16}), (40, 80))
    w_cnn, w_census = plan.cfg.sva.cost_weights
    assert plan.descriptor_bits == 64 and plan.cost_max == 32 * (w_cnn + w_census)
    assert plan.beat_bits == 64 + 8 and plan.fifo("nna_left_to_sva").width_bits == 72
    rows = next(b for b in plan.block("sva").buffers if b.name == "sva.descriptor_rows")
    assert rows.bits == 2 * 9 * 80 * 64  # k + 2 rows of each view, 64 bits a descriptor
    ham = next(st for st in plan.block("sva").stages if st.name == "hamming")
    v = plan.cfg.sva.compare_levels
    assert hamming_levels((32, 32)) == lg(32) + 2
    assert ham.latency == 1 + tree_cycles(lg(32) + 2, v)
    assert next(st for st in one.block("sva").stages
                if st.name == "hamming").latency == 1 + tree_cycles(lg(32), v)
    assert plan.cfg.sva.cost_bits == (49 * plan.cost_max).bit_length()  # a 7x7 box of them
    names = [b.name for b in plan.block("sva").buffers]
    assert "sva.noise_rows" in names and "sva.noise_registers" in names
    assert "census_unit" in [st.name for st in plan.block("nna_left").stages]


def test_census_rows_beside_a_network_of_several_layers():
    cfg = load_config(overrides={**HYBRID, "nna.cnn.weights": ROBUST})
    plan = build_plan(cfg, (40, 80))
    buf = next(b for b in plan.block("nna_left").buffers if b.name == "nna.census_rows")
    want = sum(layer_rows(cfg.nna)) + 1  # every layer's rows and the census's half height
    assert buf.rows == census_rows(cfg.nna) == want
    assert buf.bits == want * 80 * 8
    # one layer: the census reads layer 0's line buffer, no rows of its own
    assert census_rows(load_config(overrides=HYBRID).nna) == 0
    # column tiles: the halo covers the wider of the CNN's reach and the census's half width
    wide = build_plan(load_config(overrides={**HYBRID, "nna.stereo_submodules": 4,
                                             "nna.census.window": [13, 3],
                                             "nna.census.kind": "symmetric"}), (40, 80))
    assert wide.tiles[0].in_x1 - wide.tiles[0].x1 == 6


@pytest.mark.parametrize(("over", "match"), [
    ({"sva.cost_weights": [1, 1]}, "nna.descriptor is cnn"),
    ({"sva.weight_mode": "auto"}, "nna.descriptor is cnn"),
    ({**HYBRID, "sva.cost_weights": [0, 0]}, "weighs both distances by 0"),
    ({**HYBRID, "sva.weight_mode": "auto", "sva.noisy_weights": [0, 0]}, "by 0"),
    ({**HYBRID, "sva.cost_weights": [4, 1]}, r"must be in \[0, 3\]"),
])
def test_bad_weights_are_one_line(over, match):
    with pytest.raises(ConfigError, match=match):
        load_config(overrides=over)


@pytest.mark.parametrize(("over", "match"), [
    ({"nna.census.window": [9, 7]}, "more than the 64"),
    ({"nna.census.window": [3, 11]}, "at most 9 rows tall"),
])
def test_a_hybrid_that_does_not_fit_is_refused(over, match):
    with pytest.raises(ConfigError, match=match):
        build_plan(load_config(overrides={**HYBRID, **over}), (40, 80))


def test_widths_follow_the_heaviest_weight_set():
    fixed = load_config(overrides={**HYBRID, "sva.cost_weights": [1, 1]}).sva
    auto = load_config(overrides={**HYBRID, "sva.cost_weights": [1, 1],
                                  "sva.weight_mode": "auto", "sva.noisy_weights": [3, 2]}).sva
    assert fixed.cost_bits == (49 * 64).bit_length()
    assert auto.cost_bits == (49 * (3 * 32 + 2 * 32)).bit_length()


def test_energy_counts_the_census_unit_and_the_noise_unit():
    left, right = pair()
    over = {**HYBRID, "sva.weight_mode": "auto"}
    items = run(left, right, mode="cycle", overrides=over).report["energy"]["items"]
    whats = " | ".join(it["what"] for it in items)
    assert "census comparisons" in whats and "noise statistic" in whats
