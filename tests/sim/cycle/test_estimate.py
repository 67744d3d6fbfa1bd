"""The analytic model (sim/cycle/estimate.py) against the cycle model, over a grid of
configurations.

Throughput (the work-based frame rate and bottleneck), FIFO traffic and SRAM must agree exactly;
first-output and frame latency to the cycle where the model is exact (see docs/whatif.md: no
FIFO fills but the NNA->SVA one, whose handshake the estimate walks beat by beat when it is
within a beat of its round trip), and within 1 % everywhere in the grid.
"""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import InputError
from stereosim.sim.api import run, run_stream
from stereosim.sim.cycle.contract import CameraOverflow, FrameBufferFull
from stereosim.sim.cycle.estimate import estimate, paper_analysis, parse_size
from stereosim.sim.summary import format_estimate

SMALL, SPLIT = (20, 112), (16, 48)  # split frames run on the readable engine: keep them tiny
MID = (24, 64)
# The grid's rows are census unless they say cnn (census: 1 NNA cycle per descriptor, so the
# rows exercise the SVA- and FIFO-bound cases; the cnn rows the NNA-bound ones).
BASE = {"sva.disparities": 32, "nna.descriptor": "census", "sva.median": 3}

FB = {"source.kind": "camera", "source.frame_buffers": 2, "source.on_overflow": "drop_frame"}

# (shape, overrides, exact to the cycle?)
GRID = [
    (SMALL, {}, True),
    (SMALL, {"nna.descriptor": "cnn"}, True),
    (SMALL, {"clocks.nna_mhz": 465.0}, True),
    (SMALL, {"sva.lanes": 8}, True),
    (SMALL, {"nna.descriptor": "cnn", "nna.macs": 864}, True),
    (SMALL, {"fifo.nna_to_sva_depth": 4}, True),
    (SMALL, {"fifo.sva_to_sink_depth": 1, "clocks.sva_mhz": 1000.0}, True),
    (SMALL, {"clocks.sva_mhz": 1000.0}, True),  # the SVA faster than the NNA
    (SMALL, {"nna.descriptor": "cnn", "nna.macs": 2592, "clocks.sva_mhz": 1000.0}, True),
    (SMALL, {"source.memory_gbps": 0.1}, True),
    (SMALL, {"source.memory_gbps": 0.3, "nna.descriptor": "cnn"}, True),
    (SMALL, {"sva.disparities": 16, "sva.paths": 2, "sva.median": 0, "sva.box_size": 3}, True),
    (SMALL, {"sva.median": 5, "sva.box_size": 7, "sva.paths": 1}, True),
    (SMALL, {"clocks.sva_mhz": 200.0}, True),
    # the hybrid's automatic weights: the frame's first slot waits for the noise band
    (SMALL, {"nna.descriptor": "hybrid", "sva.weight_mode": "auto", "sva.median": 5}, True),
    (SMALL, {"fifo.sync_cycles": 3, "fifo.latency_cycles": 2}, True),
    (SMALL, {"nna.line_buffer_rows": 9, "nna.descriptor": "cnn"}, True),
    (SPLIT, {"nna.stereo_submodules": 4}, True),
    (SPLIT, {"nna.stereo_submodules": 4, "nna.descriptor": "cnn"}, True),
    (SPLIT, {"nna.stereo_submodules": 6, "nna.descriptor": "cnn"}, True),
    (SPLIT, {"nna.stereo_submodules": 4, "nna.split": "rows"}, True),
    (SMALL, {"fifo.nna_to_sva_depth": 2}, True),
    (SMALL, {"fifo.nna_to_sva_depth": 2, "sva.median": 5}, True),
    # shallow NNA->SVA FIFOs (within a beat of their round trip: walked beat by beat), with the
    # look-ahead window holding rows back (medians 0, 3, 5) on a frame whose rows the row
    # model's mean rate got 1-2 cycles wrong
    *[(MID, {"fifo.nna_to_sva_depth": d, "sva.median": m}, True)
      for d in (1, 2, 3) for m in (0, 3, 5)],
    # a camera at the NNA's clock: blanking only
    (SMALL, {"source.kind": "camera", "source.camera_hblank": 20}, True),
    # cameras writing into DRAM frame buffers read by the memory sources: the first NNA edge
    # after the camera wrote a pixel; through the DRAM channel a burst read once written
    (SMALL, FB, True),
    (SMALL, {**FB, "nna.descriptor": "cnn", "clocks.camera_mhz": 148.5,
             "source.camera_hblank": 20}, True),
    (SMALL, {**FB, "dram.model": "tdm"}, True),
    (SMALL, {**FB, "dram.model": "tdm", "nna.descriptor": "cnn"}, True),
    (SMALL, {**FB, "dram.model": "tdm", "dram.latency_ns": 500.0, "clocks.camera_mhz": 148.5,
             "source.camera_hblank": 20}, True),
    (SMALL, {"dram.model": "tdm"}, True),
    # approximations (docs/whatif.md): a FIFO that fills, camera clock alignment, row bands
    (SMALL, {"fifo.source_to_nna_depth": 1}, False),
    (SMALL, {"source.kind": "camera", "clocks.camera_mhz": 20.0, "nna.descriptor": "cnn"}, False),
    (SPLIT, {"nna.stereo_submodules": 4, "nna.descriptor": "cnn", "nna.split": "rows"}, False),
]


def _pair(shape, seed):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, shape, dtype=np.uint8)
    return left, np.roll(left, -5, axis=1)


@pytest.mark.parametrize("shape, over, exact", GRID,
                         ids=[f"{g[0][1]}x{g[0][0]} {g[1]}" for g in GRID])
def test_estimate_agrees_with_the_cycle_model(shape, over, exact):
    cfg = load_config(overrides={**BASE, **over})
    rep = run(*_pair(shape, len(over)), mode="cycle", config=cfg).report
    est = estimate(cfg, shape)
    thr, ethr = rep["throughput"], est["throughput"]
    assert ethr["bottleneck"] == thr["bottleneck"]
    assert ethr["fps_bound"] == thr["fps_bound"]
    for block, ms in thr["work_ms_per_frame"].items():
        if block.startswith("memory_") and cfg.source.memory_gbps * 1e9 < cfg.clocks.nna_mhz * 1e6:
            # a bandwidth-limited source that is also back-pressured banks tokens while
            # blocked and works less than the formula: an upper bound (docs/whatif.md)
            assert ethr["work_ms_per_frame"][block] >= ms
        else:
            assert ethr["work_ms_per_frame"][block] == ms
    assert set(ethr["work_ms_per_frame"]) == set(thr["work_ms_per_frame"])
    assert est["fifo_bytes_per_frame"] == rep["fifo_bytes_per_frame"]
    assert est["fifo_sram_bits"] == rep["fifo_sram_bits"]
    assert est["sram_bits"] == rep["architecture"]["sram_bits"]
    lat = est["latency"]
    if exact:
        assert lat["first_output_sva_cycle"] == rep["cycles"]["first_output"]["sva"]
        assert lat["last_output_sva_cycle"] == rep["cycles"]["last_output"]["sva"]
    assert lat["first_output_us"] == pytest.approx(rep["latency"]["first_output_us"], rel=0.01)
    assert lat["frame_ms"] == pytest.approx(rep["latency"]["frame_ms"], rel=0.01)


def test_the_grid_is_large_and_mostly_exact():
    assert len(GRID) >= 20
    assert sum(exact for _, _, exact in GRID) >= 15


def test_a_fifo_too_shallow_for_its_round_trip_is_seen_by_the_estimate():
    """A 1-deep NNA->SVA FIFO moves one descriptor per clock-crossing round trip (~4 cycles),
    slower than the SVA's 2 cycles per pixel: the frame takes longer than the block rates say
    (1.4 x here: the SVA's passes and flush take the same time either way),
    and the estimate, walking the FIFO's handshake, says by how much to the cycle."""
    shape = SMALL
    deep = load_config(overrides=BASE)
    shallow = load_config(overrides={**BASE, "fifo.nna_to_sva_depth": 1})
    rep = run(*_pair(shape, 1), mode="cycle", config=shallow).report
    e_deep, e_shallow = estimate(deep, shape), estimate(shallow, shape)
    assert e_shallow["latency"]["frame_ms"] > 1.3 * e_deep["latency"]["frame_ms"]
    assert e_shallow["latency"]["last_output_sva_cycle"] == rep["cycles"]["last_output"]["sva"]


def test_720p_calibration_matches_the_paper_figures():
    cnn = estimate(load_config(overrides={"nna.descriptor": "cnn"}), (720, 1280))
    assert cnn["throughput"]["bottleneck"] == "nna_left"
    # ~55 fps, rounded to 3 decimals
    assert cnn["throughput"]["fps_bound"] == pytest.approx(460e6 / (9 * 921_600), abs=1e-3)
    census = estimate(load_config(overrides={"nna.descriptor": "census"}), (720, 1280))
    # the SVA's frame (box 7: r = 3, 6 passes; 5x5 median: S = 2 x 1281; II 2, slot II 1):
    # 720 rows of 1279 II, 719 row starts of (r + 1) = 4, the frame start 4 + S + 6 x 1280
    ticks = 720 * 1279 * 2 + 719 * 4 + 4 + 2 * 1281 + 6 * 1280
    assert census["throughput"]["fps_bound_per_block"]["sva"] == pytest.approx(
        465e6 / ticks, abs=1e-3)  # 250.69: the paper's ~250
    # 40-bit beats: the 32-bit descriptor (the paper's 3.69 MB) and the pixel the adaptive P2
    # compares
    assert cnn["fifo_bytes_per_frame"]["nna_left_to_sva"] == 1280 * 720 * 5
    assert cnn["macs_per_frame"] == 2 * 2592 * 921_600


def test_paper_analysis_reproduces_the_reference_arithmetic():
    p = paper_analysis((720, 1280))
    assert p["macs_per_frame"]["four_layer_3x3"] == (288 + 3 * 9216) * 921_600  # 25.7 G
    assert p["macs_per_frame"]["single_layer_9x9"] == 2592 * 921_600  # 2.39 G
    assert p["weights"]["four_layer_3x3"] == 27_936
    assert p["descriptor_bytes_per_frame"]["float32_32ch"] == 117_964_800  # "118 MB"
    assert p["descriptor_bytes_per_frame"]["binary_32bit"] == 3_686_400  # "3.6 MB"


def test_camera_overflow_risk_is_warned():
    cfg = load_config(overrides={"nna.descriptor": "cnn", "source.kind": "camera"})
    assert any("overflow" in w for w in estimate(cfg, (720, 1280))["warnings"])
    # two column tiles per camera keep up with the camera only if the merge FIFOs let them
    # work at once (the cycle model overflows at the default depth 64, runs at 60 fps at 71)
    over = {"nna.descriptor": "cnn", "source.kind": "camera", "nna.stereo_submodules": 4}
    est = estimate(load_config(overrides=over), (720, 1280))
    need = est["throughput"]["merge_depth_needed"]
    assert need == 72  # an upper bound behind a camera: the cycle model's least is 71
    (warning,) = est["warnings"]
    assert "merge FIFOs" in warning and "overflow" in warning
    assert f"fifo.nna_to_merge_depth={need} or more" in warning
    cfg = load_config(overrides={**over, "fifo.nna_to_merge_depth": need})
    assert not estimate(cfg, (720, 1280))["warnings"]


# a CNN behind a 720p-clocked camera whose short blanking gives the NNA too little time a row
FAST_CAMERA = {**BASE, "nna.descriptor": "cnn", "source.kind": "camera",
               "source.camera_hblank": 10, "source.camera_vblank": 2}


def test_only_a_camera_streaming_into_the_nna_is_warned_of_an_overflow():
    """The cycle model overflows the source FIFO only where the camera feeds it; a camera that
    writes into frame buffers drops the frames the chip cannot take, and the estimate says so
    without a warning."""
    shape = SMALL
    direct = load_config(overrides=FAST_CAMERA)
    assert any("overflow the source FIFO" in w for w in estimate(direct, shape)["warnings"])
    with pytest.raises(CameraOverflow):
        run_stream([_pair(shape, 2)] * 2, config=direct)
    buffered = load_config(overrides={**FAST_CAMERA, **FB})
    est = estimate(buffered, shape)
    assert est["warnings"] == []
    assert "drops" in est["throughput"]["fps_delivered_basis"]
    rep = run_stream([_pair(shape, 2)] * 6, config=buffered).report
    assert est["throughput"]["fps_delivered"] == pytest.approx(rep["stream"]["sustained_fps"],
                                                               rel=1e-4)


def test_frame_buffers_the_chip_cannot_empty_in_time():
    """One frame buffer: the camera's next frame is taken only if it starts after the reader
    finished the last (one camera frame in two here); the error policy stops a stream at the
    first frame that finds no free buffer, and the estimate warns of it."""
    shape = SMALL
    over = {**FAST_CAMERA, **FB, "source.camera_vblank": 0, "source.camera_hblank": 5}
    one = load_config(overrides={**over, "source.frame_buffers": 1})
    est = estimate(one, shape)
    thr = est["throughput"]
    rep = run_stream([_pair(shape, 2)] * 6, config=one).report["stream"]
    assert rep["frames_dropped"] > 0
    assert thr["fps_delivered"] < thr["fps_bound"]
    assert thr["fps_delivered"] == pytest.approx(rep["sustained_fps"], rel=1e-4)
    stop = load_config(overrides={**over, "source.on_overflow": "error"})
    assert any("no free frame buffer" in w for w in estimate(stop, shape)["warnings"])
    with pytest.raises(FrameBufferFull):
        run_stream([_pair(shape, 2)] * 6, config=stop)


# Merge FIFO depths (merge_depth_needed), frames from memory: (H, W), overrides. The widths make
# the share P of the docstring whole or fractional, tiles equal or not (410 / 4: 102, 103, ...).
MERGE_CASES = [
    ((40, 300), {"nna.stereo_submodules": 6}),  # the NNA's bound: w (k - 1) / k = 66.7
    # unequal tiles: P = 76.75; an SVA fast enough that its frame start (passes, the median's
    # flush) does not hold the NNA back at the frame boundary (merge_depth_needed's docstring)
    ((40, 410), {"nna.stereo_submodules": 8, "clocks.sva_mhz": 700.0}),
    ((40, 303), {"nna.stereo_submodules": 8, "nna.macs": 162, "fifo.latency_cycles": 4}),
    ((40, 384), {"nna.stereo_submodules": 6, "nna.macs": 576}),  # the SVA's bound
    ((40, 384), {"nna.stereo_submodules": 6, "source.memory_gbps": 0.1}),  # the memory's
    ((40, 384), {"nna.stereo_submodules": 4, "nna.descriptor": "census"}),  # round trip: 2
]


def _sustained_ratio(shape, over, depth) -> float:
    """The cycle model's sustained rate over three frames as a share of the work bound."""
    cfg = load_config(overrides={"nna.descriptor": "cnn", **over,
                                 "fifo.nna_to_merge_depth": depth})
    rep = run_stream([_pair(shape, 3)] * 3, config=cfg).report
    return rep["stream"]["sustained_fps"] / rep["throughput"]["fps_bound"]


# the sustained rate is measured between SVA edges and rounded: equal to the bound within this
AT_BOUND = 1 - 1e-4


@pytest.mark.parametrize("shape, over", MERGE_CASES,
                         ids=[f"{c[0][1]}x{c[0][0]} {c[1]}" for c in MERGE_CASES])
def test_the_merge_depth_estimate_is_the_least_that_reaches_the_bound(shape, over):
    cfg = load_config(overrides={"nna.descriptor": "cnn", **over})
    need = estimate(cfg, shape)["throughput"]["merge_depth_needed"]
    assert need > 1
    assert _sustained_ratio(shape, over, need) >= AT_BOUND
    assert _sustained_ratio(shape, over, need - 1) < AT_BOUND


def test_the_merge_depth_estimate_is_enough_behind_a_camera():
    """A camera staggers the tiles by itself: the estimate is an upper bound there."""
    shape = (40, 384)
    over = {"nna.stereo_submodules": 6, "source.kind": "camera", "clocks.camera_mhz": 100.0,
            "source.camera_hblank": 50}
    need = estimate(load_config(overrides={"nna.descriptor": "cnn", **over}),
                    shape)["throughput"]["merge_depth_needed"]
    assert need == 54  # the cycle model's least is 52
    assert _sustained_ratio(shape, over, need) >= AT_BOUND


def test_no_merge_depth_without_column_tiles():
    for over in ({}, {"nna.stereo_submodules": 4, "nna.split": "rows"}):
        cfg = load_config(overrides={"sva.disparities": 32, **over})
        assert estimate(cfg, (40, 120))["throughput"]["merge_depth_needed"] is None


@pytest.mark.parametrize("text", ["1280", "axb", "1x1", "0x5", "12x-3"])
def test_bad_sizes_are_refused(text):
    with pytest.raises(InputError):
        parse_size(text)


def test_the_printed_estimate_gives_chip_totals_a_user_can_quote():
    """The chip's SRAM with every NNA submodule instance counted once (not one submodule's),
    in bits and Mbit, and the energy a frame and the power at the rate it names."""
    cfg = load_config(overrides={"nna.descriptor": "cnn", "source.kind": "camera",
                                 "source.frame_buffers": 2, "source.on_overflow": "drop_frame"})
    est = estimate(cfg, (720, 1280))
    chip = est["chip_sram"]
    assert chip["total"] > cfg.nna.submodules * chip["nna_per_submodule"]
    assert chip["total"] == sum(chip["by_block"].values()) == sum(chip["by_kind"].values())
    text = format_estimate(est)
    assert f"chip SRAM: {chip['total']:,} bits ({chip['total'] / 1e6:.2f} Mbit" in text
    energy = est["energy"]
    assert energy["power_at_fps"] == est["throughput"]["fps_delivered"] == 55.459
    assert (f"energy: {energy['per_frame_uj']['total'] / 1e3:.3f} mJ a frame" in text
            and f"power {energy['power_mw'] / 1e3:.3f} W at 55.459 fps (the work bound" in text)
