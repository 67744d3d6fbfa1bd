"""The cycle model on the readable kernel: exact cycles, bit-exactness, stalls and deadlock."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim.api import run
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import CameraOverflow, DeadlockError
from stereosim.sim.cycle.fifo.readable import Fifo, KernelError
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.blocks.nna import NnaSubmodule

# Equal NNA and SVA clocks make the crossing easy to count by hand: an item pushed at NNA cycle
# t is visible at SVA cycle t + 2 (latency 1 + synchroniser 2 - 1, edges coinciding).
# The hand derivations below take the 3x3 median (half-height m = 1) and the 5x5 box (r = 2).
SAME_CLOCKS = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16,
               "nna.descriptor": "census", "sva.median": 3, "sva.box_size": 5}


def _pair(h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, :w].copy(), base[:, shift:].copy()


def _frame(engine, run_cycle, left, right, cfg):
    """(words, report, sink's first and last pop cycle) on the readable kernel or on the
    compiled engine (sim/cycle/engine), which computes the same cycles from the event
    streams."""
    if engine == "readable":
        words, report, chip = run_cycle(left, right, cfg)
        return words, report, chip.sink.first_cycle, chip.sink.last_cycle
    frame = run_compiled(build_plan(cfg, left.shape), left, right)
    cyc = frame.report["cycles"]
    return frame.words, frame.report, cyc["first_output"]["sva"], cyc["last_output"]["sva"]


@pytest.mark.parametrize("engine", ["readable", "compiled"])
@pytest.mark.parametrize("h, w", [(11, 53), (7, 57), (5, 64)])
def test_census_first_and_last_output_cycles(h, w, engine, run_cycle):
    """Census (1 cycle per descriptor, window half-height 1), memory at one pixel per cycle;
    box 5 (r = 2, k - 1 = 4 passes), 3x3 median (m = 1: skew S = W + 1 words), II 2, slot II 1.

    Source pixel k leaves in cycle k and is popped by the NNA in cycle k + 1. NNA output row 0
    needs input row 1 complete (popped in cycle 2W), so descriptor (x, y) leaves in cycle
    (y + 2)W + 1 + x and is popped by the SVA two cycles later: input row q is complete (ready)
    in c_q = (q + 3)W + 3. The sink is free, so the SVA's tick is its cycle. The passes add rows
    0, 0, 0, 1: they start in c_0 = 3W + 3, W slots each, the fourth waits for nothing (c_1 =
    4W + 3 is before 6W + 3), and end in 7W + 3. Box row 0's first word goes r slots later,
    7W + 5 (its row r = 2 was ready in 5W + 3), its others an II apart; each later row's first
    word r + 1 = 3 ticks after the previous row's last (3 > II; its input row y + 2 is in by
    then: input row q may enter once box row q - 4 is issued). So box row y starts in
    7W + 5 + y(2W + 1). Word 0 leaves with word S = (1, 1), issued in 9W + 8, reaches the
    output register L later and the sink pops it one cycle after: 9W + 9 + L. The last word
    leaves with the S-th flush tick after the frame's last word, issued in 9W + 3 + (H - 1)(2W
    + 1): the sink pops it in 10W + 5 + (H - 1)(2W + 1) + L.
    """
    left, right = _pair(h, w)
    cfg = load_config(overrides=SAME_CLOCKS)
    words, report, first, last = _frame(engine, run_cycle, left, right, cfg)
    lat = build_plan(cfg, (h, w)).block("sva").latency  # tests/sim/cycle/test_stages.py checks it
    assert first == 9 * w + 9 + lat
    assert last == 10 * w + 5 + (h - 1) * (2 * w + 1) + lat
    assert report["throughput"]["bottleneck"] == "sva"
    functional = run(left, right, mode="functional", config=cfg).disparity_fixed
    np.testing.assert_array_equal(words, functional)


@pytest.mark.parametrize("engine", ["readable", "compiled"])
@pytest.mark.parametrize("h, w", [(11, 37), (7, 41), (5, 33)])
def test_cnn_first_and_last_output_cycles(h, w, engine, run_cycle):
    """CNN: ceil(81 * 32 / 288) = 9 cycles per descriptor, window half-height 4; the SVA as
    in the census test (box 5: r = 2, passes on rows 0, 0, 0, 1; 3x3 median: S = W + 1).

    NNA output row 0 needs input row 4 (popped in cycle 5W): it starts in 5W + 1 and pushes
    descriptor j in cycle 5W + 9 + 9j (the line buffer of 10 rows always has the next rows in
    time). The SVA pops pair j in 5W + 11 + 9j: input row q is ready in c_q = (9q + 14)W + 3.
    The passes end long before box row 0's row 2 is in; box row y (y <= H - 3) starts r = 2
    ticks after its row y + 2 is ready, (9y + 32)W + 5, and its words follow an II apart
    (the input is slower than the SVA). Word 0 leaves with word S = (1, 1), issued in
    41W + 7: the sink pops it in 41W + 8 + L. Box rows H - 3 .. H - 1 all wait for input row
    H - 1 (ready in (9H + 5)W + 3): row H - 3 starts in (9H + 5)W + 5 and the three go back
    to back, 2W + 1 ticks a row, so the frame's last word is issued in (9H + 11)W + 5 and
    leaves with the S-th flush tick after it: the sink pops it in (9H + 12)W + 7 + L.
    """
    left, right = _pair(h, w, seed=1)
    cfg = load_config(overrides={**SAME_CLOCKS, "nna.descriptor": "cnn"})
    words, report, first, last = _frame(engine, run_cycle, left, right, cfg)
    lat = build_plan(cfg, (h, w)).block("sva").latency
    assert first == 41 * w + 8 + lat
    assert last == (9 * h + 12) * w + 7 + lat
    assert report["throughput"]["bottleneck"] in ("nna_left", "nna_right")
    # the bottleneck's busy time per frame is its descriptors x 9 cycles
    assert report["blocks"]["nna_left"]["busy"] >= 9 * h * w
    functional = run(left, right, mode="functional", config=cfg).disparity_fixed
    np.testing.assert_array_equal(words, functional)


@pytest.mark.parametrize(
    "over",
    [
        {"sva.paths": 1, "sva.lr_check": False, "sva.median": 0},
        {"sva.paths": 2, "sva.box_size": 3, "sva.median": 5},
        {"sva.paths": 3, "sva.disparities": 32, "sva.subpixel": "parabola"},
        {"sva.paths": 4, "fifo.source_to_nna_depth": 1, "fifo.nna_to_sva_depth": 1,
         "fifo.sva_to_sink_depth": 1},
        {"nna.descriptor": "cnn", "fifo.nna_to_sva_depth": 2, "clocks.sva_mhz": 930},
        {"source.kind": "camera", "clocks.camera_mhz": 20, "source.camera_hblank": 7},
        {"nna.line_buffer_rows": 9, "nna.descriptor": "cnn", "sva.uniqueness": 5},
        {"source.memory_gbps": 0.1, "clocks.nna_mhz": 300, "clocks.sva_mhz": 700},
    ],
)
def test_cycle_model_is_bit_exact_with_the_functional_model(over, run_cycle):
    left, right = _pair(13, 45, seed=len(over))
    cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "census", **over})
    words, _, _ = run_cycle(left, right, cfg)
    functional = run(left, right, mode="functional", config=cfg).disparity_fixed
    np.testing.assert_array_equal(words, functional)


def test_backpressure_from_a_stalling_sink_keeps_data_exact(run_cycle):
    left, right = _pair(9, 35, seed=5)
    cfg = load_config(overrides={**SAME_CLOCKS, "fifo.sva_to_sink_depth": 1})
    words, report, chip = run_cycle(left, right, cfg, sink_stall=lambda c: c % 3 != 0)
    functional = run(left, right, mode="functional", config=cfg).disparity_fixed
    np.testing.assert_array_equal(words, functional)
    assert report["blocks"]["sva"]["blocked"] > 0
    # the sink pops at most every third cycle: the frame cannot end sooner
    assert chip.sink.last_cycle - chip.sink.first_cycle >= 3 * (9 * 35 - 1)


def test_deeper_fifo_removes_the_nna_stalls(run_cycle):
    """Census NNA (1 per cycle) feeds the SVA (2 per cycle, bounded look-ahead): a shallow
    NNA-to-SVA FIFO blocks the NNA; one that holds the whole frame never does."""
    left, right = _pair(9, 35, seed=6)
    blocked = []
    for depth in (1, 4, 64, 9 * 35):
        cfg = load_config(overrides={**SAME_CLOCKS, "fifo.nna_to_sva_depth": depth})
        _, report, _ = run_cycle(left, right, cfg)
        blocked.append(report["blocks"]["nna_left"]["blocked"])
        assert report["fifos"]["nna_left_to_sva"]["max_producer_occupancy"] <= depth
    assert blocked == sorted(blocked, reverse=True) and blocked[0] > 0 and blocked[-1] == 0


def test_evaluation_order_does_not_change_anything(run_cycle):
    left, right = _pair(7, 29, seed=7)
    cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "cnn"})
    results = [run_cycle(left, right, cfg, order_seed=seed) for seed in (None, 1, 2, 3)]
    for words, report, _ in results[1:]:
        np.testing.assert_array_equal(words, results[0][0])
        assert report == results[0][1]


def test_a_sink_that_never_drains_is_reported_as_a_deadlock(run_cycle):
    left, right = _pair(7, 29, seed=8)
    cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "census",
                                 "sim.watchdog_cycles": 500})
    with pytest.raises(DeadlockError) as exc:
        run_cycle(left, right, cfg, sink_stall=lambda c: True)
    msg = str(exc.value)
    assert "full FIFOs: sva_to_sink 16/16" in msg and "\n" not in msg
    assert exc.value.fifos["sva_to_sink"] == {"occupancy": 16, "depth": 16}
    assert "nna_left_to_sva" in exc.value.fifos
    assert exc.value.blocks["sva"]["status"] == "blocked"


def test_a_camera_faster_than_the_nna_overflows(run_cycle):
    left, right = _pair(25, 29, seed=9)  # taller than the 10-row line buffer
    cfg = load_config(overrides={"sva.disparities": 16, "source.kind": "camera",
                                 "nna.descriptor": "cnn", "clocks.camera_mhz": 400,
                                 "source.camera_hblank": 0})
    with pytest.raises(CameraOverflow, match="overflowed FIFO src_left_to_nna"):
        run_cycle(left, right, cfg)


@pytest.mark.parametrize(
    "over",
    [
        {"nna.stereo_submodules": 4},
        {"nna.stereo_submodules": 6, "nna.descriptor": "cnn"},
        {"nna.stereo_submodules": 4, "nna.split": "rows"},
        {"nna.stereo_submodules": 6, "nna.split": "rows", "nna.descriptor": "cnn",
         "fifo.nna_to_sva_depth": 2},
        {"nna.stereo_submodules": 4, "source.kind": "camera", "clocks.camera_mhz": 30},
    ],
)
def test_split_frames_are_bit_exact(over, run_cycle):
    """Column tiles and row bands with their halos, merged back into raster order, give the
    functional model's words: the halo and border handling of every tile is right."""
    left, right = _pair(19, 45, seed=11)
    cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "census", **over})
    words, report, _ = run_cycle(left, right, cfg)
    functional = run(left, right, mode="functional", config=cfg).disparity_fixed
    np.testing.assert_array_equal(words, functional)
    parts = over["nna.stereo_submodules"] // 2
    assert {f"nna_left{t}" for t in range(parts)} <= set(report["blocks"])


def test_column_tiles_speed_up_an_nna_bound_frame(run_cycle):
    """CNN descriptors (9 cycles each) make the NNA the bottleneck; two column tiles per camera
    share the work, so the frame ends sooner and the busiest submodule does about half."""
    left, right = _pair(15, 64, seed=12)
    ends, busiest = [], []
    for k in (2, 4):
        cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "cnn",
                                     "nna.stereo_submodules": k})
        _, report, chip = run_cycle(left, right, cfg)
        ends.append(chip.sink.last_cycle)
        busiest.append(max(v for n, v in report["throughput"]["work_ms_per_frame"].items()
                           if n.startswith("nna_left")))
    assert ends[1] < ends[0]
    # a tile of 32 (+4 halo) columns does at least 9 x 15 x 32 MAC-array cycles
    assert busiest[1] < 0.6 * busiest[0]


def test_bad_split_configurations_are_refused(run_cycle):
    from stereosim.core.errors import ConfigError

    with pytest.raises(ConfigError, match="must be even"):
        load_config(overrides={"nna.stereo_submodules": 3})
    with pytest.raises(ConfigError, match="exceeds nna.submodules"):
        load_config(overrides={"nna.stereo_submodules": 12})
    left, right = _pair(4, 20, seed=13)
    cfg = load_config(overrides={"sva.disparities": 16, "nna.stereo_submodules": 10,
                                 "nna.split": "rows"})
    with pytest.raises(ConfigError, match="cannot split 4 rows into 5 parts"):
        run_cycle(left, right, cfg)


def test_a_block_handed_fifos_its_plan_entry_does_not_name_is_refused():
    """A chip block takes its ports' FIFOs from the parent in the order its plan entry names
    them; anything else is a wiring bug."""
    plan = build_plan(load_config(overrides=SAME_CLOCKS), (6, 40))
    entry = plan.block("nna_left")
    fifos = {f.name: Fifo(f.name, f.depth, f.width_bits, src=plan.domains[f.src].clock(),
                          dst=plan.domains[f.dst].clock()) for f in plan.fifos}
    inp, out = fifos["src_left_to_nna"], fifos["nna_left_to_sva"]
    assert NnaSubmodule(plan, entry, [inp], [out]).name == "nna_left"
    with pytest.raises(KernelError, match="'nna_left' was handed inputs \\['src_right_to_nna'\\]; "
                       "its plan entry names \\['src_left_to_nna'\\]"):
        NnaSubmodule(plan, entry, [fifos["src_right_to_nna"]], [out])
    with pytest.raises(KernelError, match="handed outputs"):
        NnaSubmodule(plan, entry, [inp], [out, fifos["nna_right_to_sva"]])
