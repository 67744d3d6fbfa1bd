"""The NNA submodule as a pipeline of layer stages (nna.geometry's layer rules, the plan's
LayerPlan, the readable kernel's chain of line buffers and MAC arrays).

Timing, with a memory source whose pixel k (raster) leaves in cycle k and is popped in cycle
a + k, a = 1, and nothing stalling (the line buffers' slack and the FIFOs deep enough): layer
0's input row r (image row) is complete in

    D_-1(r) = a + r W + in_x1 - 1            (in_x1: the end of the tile's input columns)

and layer l's output row y (rows of its output region) starts and ends in

    S_l(y) = max(D_l-1(min(y + h_l, H - 1)), D_l(y - 1)) + 1,    D_l(y) = S_l(y) + W_l II_l - 1

(W_l its output region's width, II_l = ceil(m_l / macs_l)); the first descriptor leaves in
S_L-1(y0) + cpp_L-1 - 1 and the last in D_L-1(y1 - 1). One layer: the first in a + (h + 1) W - 1
+ c, as docs/architecture.md has it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

import stereosim.sim.cycle.readable.blocks.nna as nna_block
from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.nna.descriptor import compute_descriptor
from stereosim.nna.geometry import Tile, layer_rows, layer_tiles, mac_shares, split_frame
from stereosim.nna.submodule.timing import layer_cycles
from stereosim.quant.intconv import int_forward_ref, int_layer_rows, signs_ref
from stereosim.sim.api import run
from stereosim.sim.cycle.buffers import BufferOverflow
from stereosim.sim.cycle.compiled.layout import INF
from stereosim.sim.cycle.compiled.run import _last as compiled_last
from stereosim.sim.cycle.compiled.run import _pass as compiled_pass
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import BudgetExceeded
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import build_chip, run_readable
from stereosim.sim.cycle.simulate import simulate
from stereosim.traces.vcd import vcd_bytes

MODELS = Path(__file__).resolve().parents[3] / "benchmarks" / "models"
# equal clocks, a 16-disparity SVA (II 2) and 64 MACs: the NNA, at 3 or more cycles a
# descriptor, never waits for the SVA
BASE = {"nna.descriptor": "cnn", "sva.disparities": 16, "clocks.sva_mhz": 460.0,
        "nna.macs": 64}


ENGINES = ["readable", "fast"]
NETS = {
    "one5x5": ((5, 1, 8),),
    "two3x3": ((3, 1, 4), (3, 4, 8)),
    "5x5then1x1": ((5, 1, 6), (1, 6, 8)),
    "four3x3": ((3, 1, 4), (3, 4, 4), (3, 4, 8), (3, 8, 8)),
}


@pytest.fixture(scope="module")
def weights(network_file):
    """name -> (artifact path, network) of the random networks of NETS."""
    return {name: network_file(shapes, seed=i) for i, (name, shapes) in enumerate(NETS.items())}


def _cfg(path, **over):
    return load_config(overrides={**BASE, "nna.cnn.weights": path,
                                  "nna.cnn.channels": 8 if "mccnn" not in path else 32, **over})


def _pair(h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift)).astype(np.float64)
    base = ((base + np.roll(base, 1, 0) + np.roll(base, 1, 1)) / 3).astype(np.uint8)
    return np.ascontiguousarray(base[:, shift:]), np.ascontiguousarray(base[:, :w])


# ---- the rules ----------------------------------------------------------------------------------


def test_the_macs_are_shared_in_proportion_by_largest_remainder():
    """mccnn4 (m = 288, 9216, 9216, 9216) on 288 MACs: quotas 2.97, 95.01 x 3, floors 2, 95, 95,
    95 and the one left over to the largest remainder (layer 0): 3, 95, 95, 95 -> 96, 98, 98,
    98 cycles per pixel; mccnn4-slim (36, 144, 288, 2304): 4, 15, 30, 239 -> 9, 10, 10, 10."""
    cfg = load_config(overrides={"nna.cnn.weights": str(MODELS / "mccnn4.int8.npz")}).nna
    assert mac_shares(cfg) == (3, 95, 95, 95)
    assert layer_cycles(cfg) == (96, 98, 98, 98)
    slim = load_config(overrides={"nna.cnn.weights": str(MODELS / "mccnn4-slim.int8.npz")}).nna
    assert mac_shares(slim) == (4, 15, 30, 239)
    assert layer_cycles(slim) == (9, 10, 10, 10)
    # each layer at least one: with 4 MACs every layer of mccnn4 gets one
    assert mac_shares(dataclasses.replace(cfg, macs=4)) == (1, 1, 1, 1)
    # a layer the floor leaves at 0 takes one from the richest: 5 MACs -> floors 0, 1, 1, 1
    # + 2 left over (layers 1, 2) -> 0, 2, 2, 1 -> 1, 1, 2, 1
    assert mac_shares(dataclasses.replace(cfg, macs=5)) == (1, 1, 2, 1)
    # one layer: the whole array, today's ceil(K*K*C / macs)
    single = load_config().nna
    assert mac_shares(single) == (288,) and layer_cycles(single) == (9,)
    assert layer_cycles(load_config(overrides={"nna.descriptor": "census"}).nna) == (1,)


def test_the_mac_shares_can_be_given_and_are_checked():
    path = str(MODELS / "mccnn4.int8.npz")
    cfg = load_config(overrides={"nna.cnn.weights": path, "nna.layer_macs": [8, 96, 96, 88]})
    assert mac_shares(cfg.nna) == (8, 96, 96, 88)
    assert layer_cycles(cfg.nna) == (36, 96, 96, 105)
    for bad in ([8, 96, 96], [100, 100, 100, 100]):
        with pytest.raises(ConfigError, match="nna.layer_macs=.* one MAC share per layer"):
            build_plan(load_config(overrides={"nna.cnn.weights": path, "nna.layer_macs": bad,
                                              "sva.disparities": 16}), (12, 40))
    with pytest.raises(ConfigError, match="nna.macs=3 cannot give each of the network's 4"):
        build_plan(load_config(overrides={"nna.cnn.weights": path, "nna.macs": 3,
                                          "sva.disparities": 16}), (12, 40))


def test_line_buffer_rows_and_regions(weights):
    """Layer 0 holds nna.line_buffer_rows (at least K_0, no longer the receptive field), layer
    l K_l + the same slack; a column tile's layer regions widen by the half kernels after it."""
    path, _ = weights["5x5then1x1"]
    cfg = _cfg(path, **{"nna.line_buffer_rows": 6}).nna
    assert layer_rows(cfg) == (6, 2)  # slack 1: 5 + 1, 1 + 1
    four = _cfg(weights["four3x3"][0], **{"nna.line_buffer_rows": 3}).nna
    assert layer_rows(four) == (3, 3, 3, 3)  # the 9-row receptive field is not needed
    build_plan(_cfg(weights["four3x3"][0], **{"nna.line_buffer_rows": 3}), (12, 40))
    with pytest.raises(ConfigError, match="cannot hold the 5-row window of the network's first"):
        build_plan(_cfg(path, **{"nna.line_buffer_rows": 4}), (12, 40))
    tiles = split_frame((12, 40), 2, "columns", four)
    assert tiles[1] == Tile(20, 40, 0, 12, 16, 40, 0, 12)
    assert [(t.x0, t.x1, t.in_x0, t.in_x1) for t in layer_tiles(tiles[1], four, (12, 40))] == [
        (17, 40, 16, 40), (18, 40, 17, 40), (19, 40, 18, 40), (20, 40, 19, 40)]
    rows = split_frame((12, 40), 2, "rows", four)[0]
    assert [(t.y0, t.y1, t.in_y0, t.in_y1) for t in layer_tiles(rows, four, (12, 40))] == [
        (0, 9, 0, 10), (0, 8, 0, 9), (0, 7, 0, 8), (0, 6, 0, 7)]


def test_one_layer_is_one_stage_with_todays_figures():
    plan = build_plan(load_config(), (720, 1280))
    (lay,) = plan.block("nna_left").layers
    assert (lay.rows, lay.half, lay.ii, lay.macs, lay.tile) == (10, 4, 9, 288,
                                                                     plan.tiles[0])
    assert lay.buffer.name == "nna.line_buffer" and lay.buffer.bits == 10 * 1280 * 8
    assert [s.name for s in plan.block("nna_left").stages] == ["line_buffer", "mac_array",
                                                                "requantise_sign"]


def test_a_layer_of_received_rows_is_the_definition(weights):
    """quant.intconv.int_layer_rows, row by row from a window of received rows, layer after
    layer, gives the int64 definition's descriptors."""
    _, net = weights["four3x3"]
    img = np.random.default_rng(3).integers(0, 256, (9, 14), dtype=np.uint8)
    x = img
    for layer in range(net.n_layers):
        h = net.halves[layer]
        rows = []
        for y in range(img.shape[0]):
            lo, hi = max(0, y - h), min(img.shape[0], y + h + 1)
            rows.append(int_layer_rows(net, layer, x[..., lo:hi, :], lo, y, y + 1))
        x = np.concatenate(rows, axis=-2)
    assert_array_equal(x, signs_ref(int_forward_ref(img, *net.args)))


# ---- timing: exact cycles -----------------------------------------------------------------------


def _expected(plan, block):
    """(first, last) push of ``block`` from the formula of the module docstring."""
    h, w = plan.shape
    entry = plan.block(block)
    t0 = entry.tile
    a = 1
    done = {r: a + r * w + t0.in_x1 - 1 for r in range(t0.in_y0, t0.in_y1)}
    first = None
    for lay in entry.layers:
        t = lay.tile
        width = t.x1 - t.x0
        out = {}
        prev = -1
        for y in range(t.y0, t.y1):
            start = max(done[min(y + lay.half, h - 1)], prev) + 1
            if y == t.y0 and lay.index == len(entry.layers) - 1:
                first = start + lay.ii - 1
            out[y] = prev = start + width * lay.ii - 1
        done = out
    return first, done[entry.tile.y1 - 1]


CHAINS = [
    ("one5x5", {}),
    ("one5x5", {"nna.macs": 17}),
    ("two3x3", {}),
    ("two3x3", {"nna.layer_macs": [9, 12]}),  # layer 1 the slower: layer 0 waits for room
    ("two3x3", {"nna.layer_macs": [2, 62]}),  # layer 0 the slower: layer 1 starves
    ("5x5then1x1", {"nna.macs": 20}),
    ("four3x3", {}),
    ("four3x3", {"nna.macs": 40}),
    ("four3x3", {"nna.macs": 100, "nna.layer_macs": [36, 8, 30, 9]}),
]


def _layer_outputs(plan, engine, left, right):
    """Per NNA submodule, per layer: the cycles its first and last output left, on ``engine``
    (the compiled engine reports them with several layers; with one, its MAC array's first
    and last push are read off its event stream)."""
    subs = plan.blocks_of("nna")
    if engine == "readable":
        chip = build_chip(left, right, plan)
        chip.run()
        return {e.name: [(s["first_output_cycle"], s["last_output_cycle"])
                         for s in chip.blocks[e.name].layer_stats()] for e in subs}
    if len(subs[0].layers) > 1:
        stats = run_compiled(plan, left, right).stats["nna_layers"]
        return {name: [(s["first_output_cycle"], s["last_output_cycle"]) for s in layers]
                for name, layers in stats.items()}
    net, names = compiled_pass(plan, None, INF, False)
    out = {}
    for e in subs:
        s = names["mac_push"][e.side, plan.tiles.index(e.tile) if plan.parts > 1 else 0]
        out[e.name] = [(int(net.ring[net.streams[s]["off"]]), compiled_last(net, s))]
    return out


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("split", [1, 2])
@pytest.mark.parametrize("name,over", CHAINS)
def test_first_and_last_descriptor_in_exact_cycles(weights, name, over, split, engine):
    path, _ = weights[name]
    h, w = 11, 40
    plan = build_plan(_cfg(path, **{"nna.stereo_submodules": 2 * split, **over}), (h, w))
    outputs = _layer_outputs(plan, engine, *_pair(h, w))
    for entry in plan.blocks_of("nna"):
        assert outputs[entry.name][-1] == _expected(plan, entry.name), entry.name
    if split == 1 and len(plan.block("nna_left").layers) > 1:
        # the receptive field decides the first descriptor: 2 reach + 1 rows, whatever the
        # layers (here: the first descriptor needs input row `reach`)
        lay0 = plan.block("nna_left").layers[0]
        assert outputs["nna_left"][0][0] == (lay0.half + 1) * w + lay0.ii


@pytest.mark.parametrize("engine", ENGINES)
def test_the_first_descriptor_waits_for_the_receptive_field_not_the_layers(weights, engine):
    """Four 3x3 layers and one 9x9 read the same 9 rows: with one cycle a layer's output (the
    1044 MACs of the four layers, each its own m_l), the first descriptor leaves after row 4 is
    in plus one row of each of layers 0..2 and the last layer's cycle."""
    path, _ = weights["four3x3"]
    h, w = 12, 40
    plan = build_plan(_cfg(path, **{"nna.macs": 1044}), (h, w))
    assert [lay.ii for lay in plan.block("nna_left").layers] == [1, 1, 1, 1]
    first = _layer_outputs(plan, engine, *_pair(h, w))["nna_left"][-1][0]
    # input row 4 (the receptive field's last) is complete in 5W; then layers 0..2 each
    # finish one more row of W cycles (the row the next layer's first row reads below it)
    assert first == _expected(plan, "nna_left")[0] == 5 * w + 3 * w + 1


# ---- data: cycle == functional ------------------------------------------------------------------

SPLITS = [{}, {"nna.stereo_submodules": 4}, {"nna.stereo_submodules": 4, "nna.split": "rows"},
          {"nna.stereo_submodules": 6}]


@pytest.mark.parametrize("over", SPLITS)
@pytest.mark.parametrize("name", ["two3x3", "5x5then1x1", "four3x3"])
def test_random_networks_cycle_equals_functional(weights, name, over):
    path, _ = weights[name]
    left, right = _pair(17, 37, seed=len(over))
    cfg = _cfg(path, **over)
    cycle = run(left, right, mode="cycle", config=cfg)
    functional = run(left, right, mode="functional", config=cfg)
    assert_array_equal(cycle.disparity_fixed, functional.disparity_fixed)
    assert cycle.report["engine"] == "fast"


@pytest.mark.parametrize("name", ["mccnn4", "mccnn4-slim"])
def test_shipped_networks_descriptors_leave_the_chip_bit_exact(name):
    """The descriptors the SVA receives are compute_descriptor's (row bands, column tiles)."""
    cfg = load_config(overrides={**BASE, "nna.cnn.weights": str(MODELS / f"{name}.int8.npz"),
                                 "nna.macs": 2592, "nna.stereo_submodules": 4})
    left, right = _pair(13, 33, seed=5)
    chip = build_chip(left, right, cfg)
    seen = np.zeros(left.shape, np.uint64)
    fifo = chip.fifos["nna_left_to_sva"]
    push = fifo.push

    def record(beat):
        seen[beat.y, beat.x] = beat.descriptor
        push(beat)

    fifo.push = record
    chip.run()
    assert_array_equal(seen, compute_descriptor(left, cfg.nna).astype(np.uint64))


# ---- engines ------------------------------------------------------------------------------------


def test_engines_auto_and_fast_run_layers_on_the_compiled_engine(weights):
    path, _ = weights["two3x3"]
    left, right = _pair(9, 24)
    for engine in ("auto", "fast"):
        result = simulate(build_plan(_cfg(path, **{"sim.engine": engine}), (9, 24)), left, right)
        assert result.report["engine"] == "fast" and "engine_reason" not in result.report


SHIPPED = [{}, {"nna.stereo_submodules": 4}, {"nna.stereo_submodules": 4, "nna.split": "rows"}]


@pytest.mark.parametrize("over", SHIPPED)
@pytest.mark.parametrize("name", ["mccnn4", "mccnn4-slim"])
def test_shipped_networks_equal_on_both_engines(name, over, engines_agree):
    """mccnn4 and mccnn4-slim on a small frame (whole, column tiles, row bands): words, report
    (nna_layers included), statistics and frame instants equal; the row instants too."""
    cfg = load_config(overrides={**BASE, "nna.cnn.weights": str(MODELS / f"{name}.int8.npz"),
                                 "nna.cnn.channels": 32, "nna.macs": 400, **over})
    left, right = _pair(14, 36, seed=3)
    plan = build_plan(cfg, left.shape)
    slow, _ = engines_agree(plan, left, right)
    assert len(slow.report["nna_layers"][plan.blocks_of("nna")[0].name]) == 4
    assert_array_equal(run_compiled(plan, left, right).row_times, slow.row_times)


@pytest.mark.parametrize("name", ["mccnn4", "mccnn4-slim"])
def test_shipped_networks_stop_and_trace_alike(name):
    """A run stopped by sim.max_cycles raises the same error (message, every FIFO's and block's
    state) on both engines, with the same trace up to the stop; a traced window of a run that
    completes has the same VCD."""
    over = {**BASE, "nna.cnn.weights": str(MODELS / f"{name}.int8.npz"),
            "nna.cnn.channels": 32, "nna.macs": 400, "nna.stereo_submodules": 4}
    left, right = _pair(12, 34, seed=4)
    p_nna = build_plan(load_config(overrides=over), left.shape).domains["nna"].period_fs
    window = (300 * p_nna, 2500 * p_nna)
    stopped = build_plan(load_config(overrides={**over, "sim.max_cycles": 2000}), left.shape)
    errors = []
    for fn in (run_readable, run_compiled):
        with pytest.raises(BudgetExceeded) as err:
            fn(stopped, left, right, window=window)
        errors.append(err.value)
    slow, fast = errors
    assert str(fast) == str(slow)
    for attr in ("blocks", "fifos", "cycles", "time_fs"):
        assert getattr(fast, attr) == getattr(slow, attr)
    assert vcd_bytes(fast.trace, version="t") == vcd_bytes(slow.trace, version="t")
    plan = build_plan(load_config(overrides=over), left.shape)
    slow, fast = (fn(plan, left, right, window=window) for fn in (run_readable, run_compiled))
    assert vcd_bytes(fast.trace, version="t") == vcd_bytes(slow.trace, version="t")
    assert fast.outputs_in_window == slow.outputs_in_window and fast.report == slow.report


# ---- mutants: each must be caught ---------------------------------------------------------------


def _short(plan, block, buffer):
    """The plan with one buffer's capacity one row below what it holds."""
    def shrink(b):
        if b.name != block:
            return b
        return dataclasses.replace(b, buffers=tuple(
            dataclasses.replace(x, rows=x.rows - 1, bits=x.bits // x.rows * (x.rows - 1))
            if x.name == buffer else x for x in b.buffers))

    return dataclasses.replace(plan, blocks=tuple(shrink(b) for b in plan.blocks))


# each layer l >= 1 in turn the slowest, so that the layer before fills its line buffer
SHORT = [("two3x3", {"nna.layer_macs": [36, 4]}, "nna.layer1.line_buffer"),
         ("four3x3", {"nna.macs": 400, "nna.layer_macs": [36, 4, 30, 30]},
          "nna.layer1.line_buffer"),
         ("four3x3", {"nna.macs": 400, "nna.layer_macs": [36, 144, 6, 100]},
          "nna.layer2.line_buffer"),
         ("four3x3", {"nna.macs": 400, "nna.layer_macs": [36, 144, 144, 10]},
          "nna.layer3.line_buffer"),
         ("four3x3", {}, "nna.layer0.line_buffer")]


@pytest.mark.parametrize("name,over,buffer", SHORT)
def test_a_layer_buffer_one_row_short_is_caught(weights, name, over, buffer):
    path, _ = weights[name]
    plan = build_plan(_cfg(path, **{"nna.line_buffer_rows": 4, **over}), (14, 24))
    left, right = _pair(14, 24)
    rep = run_readable(plan, left, right).report["buffers"]["nna_left"][buffer]
    assert rep["peak_rows"] == rep["capacity_rows"]  # it fills: a row less must not do
    with pytest.raises(BufferOverflow, match=f"buffer nna_left.{buffer} held"):
        run_readable(_short(plan, "nna_left", buffer), left, right)


def test_a_row_started_one_row_early_is_caught(weights, monkeypatch):
    """A layer that starts an output row before its last input row is in reads rows its line
    buffer has not received: the descriptors, and the disparities, are wrong."""
    path, _ = weights["four3x3"]
    cfg = _cfg(path, **{"sim.engine": "readable"})  # the mutant is the readable block's
    left, right = _pair(13, 30, seed=2)
    functional = run(left, right, mode="functional", config=cfg)
    early = nna_block.nna_last_input_row
    monkeypatch.setattr(nna_block, "nna_last_input_row",
                        lambda y, half, rows: early(y, half, rows) - (y + half < rows - 1))
    cycle = run(left, right, mode="cycle", config=cfg)
    assert (cycle.disparity_fixed != functional.disparity_fixed).any()


def test_a_room_rule_one_row_late_is_caught(weights, monkeypatch):
    """Every layer's line buffer admits one row more than it holds: the layer before the
    slow one overfills it."""
    path, _ = weights["two3x3"]
    plan = build_plan(_cfg(path, **{"nna.layer_macs": [36, 4]}), (14, 24))
    left, right = _pair(14, 24)
    rule = nna_block.nna_rows_started_before_input
    monkeypatch.setattr(nna_block, "nna_rows_started_before_input",
                        lambda r, rows, half, top, out_rows, in_rows:
                        rule(r, rows + 1, half, top, out_rows, in_rows))
    with pytest.raises(BufferOverflow, match="buffer nna_left.nna.layer1.line_buffer held"):
        run_readable(plan, left, right)


def test_layers_are_traced_and_reported_per_layer(weights):
    """Per layer: signals (layer<l>.line_buffer.fill, layer<l>.mac.phase, ...), the report's
    nna_layers (activity adds up to the NNA's cycles; the first row's latency as the formula
    has it) and energy lines; one layer keeps today's names."""
    path, _ = weights["two3x3"]
    h, w = 16, 24
    plan = build_plan(_cfg(path, **{"nna.layer_macs": [9, 12]}), (h, w))
    names = {s.path for s in plan.signals}
    for key in ("status", "line_buffer.row_in", "line_buffer.fill", "mac.phase", "mac.row",
                "mac.col"):
        assert f"top.nna.left.sub0.layer1.{key}" in names
    assert "top.nna.left.sub0.line_buffer.fill" not in names
    single = {s.path for s in build_plan(load_config(overrides=BASE), (h, w)).signals}
    assert "top.nna.left.sub0.line_buffer.fill" in single
    result = simulate(plan, *_pair(h, w), window=(0, 10**12))
    assert result.trace is not None
    rep = result.report["nna_layers"]["nna_left"]
    total = result.report["cycles"]["total"]["nna"]
    for lay in rep:
        assert sum(lay[a] for a in ("busy", "starved", "blocked", "idle")) == total
    assert [lay["cycles_per_pixel"] for lay in rep] == [4, 24]
    assert rep[1]["first_output_cycle"] == _expected(plan, "nna_left")[0]
    assert rep[0]["blocked"] > 0 and rep[1]["line_buffer"]["peak_rows"] == 10  # layer 1 slow
    what = [i["what"] for i in result.report["energy"]["items"] if i["block"] == "nna"]
    assert "layer1: int8 multiply-accumulates, both cameras" in what
