"""Camera pairs sharing the chip frame by frame (``sva.pairs``): pair p's cameras run
pair 0's raster p/P of a frame period later, each pair writes into its own frame buffers, and
the chip reads the frames in the order they start. The rules by hand and against brute force,
then whole runs whose outcome follows from the rules, in both engines."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import CameraOverflow
from stereosim.sim.cycle.frames import functional_words
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable
from stereosim.sim.cycle.rules import (
    camera_busy_cycles,
    camera_cycle,
    camera_frame_start,
    camera_in_lines,
    camera_pixels_streamed,
)

H, W = 16, 40
# CNN at 400 MHz: a 16x40 frame is 640 descriptors x 9 MAC cycles = 5,760 NNA cycles of work
CHIP = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16,
        "nna.descriptor": "cnn", "source.kind": "camera", "clocks.camera_mhz": 400,
        "source.on_overflow": "drop_frame"}


def _stream(n, seed=0):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (n, H, W + 2), dtype=np.uint8)
    return left[:, :, :W].copy(), left[:, :, 2:].copy()


def _plan(n, **over):
    return build_plan(load_config(overrides={**CHIP, **over}), (H, W), n)


# ---- the rules -----------------------------------------------------------------------------


def test_the_pairs_frames_start_evenly_over_a_frame_period():
    assert [camera_frame_start(f, 1000, 1) for f in range(3)] == [0, 1000, 2000]
    assert [camera_frame_start(f, 1000, 2) for f in range(5)] == [0, 500, 1000, 1500, 2000]
    assert [camera_frame_start(f, 1000, 3) for f in range(4)] == [0, 333, 666, 1000]
    assert camera_cycle(3, 5, 2, 100, 1000, 2) == 1500 + 2 * 100 + 5
    # two pairs' frames of 10 lines of 100 clocks in a 1000-clock period, 500 apart: frames
    # 0 and 1 cover 0 .. 1499 without a gap; four frames, 0 .. 2499
    assert camera_busy_cycles(1 << 30, 2, 10, 100, 1000, 2) == 1500
    assert camera_busy_cycles(1 << 30, 4, 10, 100, 1000, 2) == 2500
    assert camera_busy_cycles(1 << 30, 4, 4, 100, 1000, 2) == 4 * 400  # no overlap
    assert camera_busy_cycles(700, 4, 4, 100, 1000, 2) == 400 + 200


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 4), st.integers(1, 5), st.integers(1, 4), st.integers(1, 6),
       st.integers(0, 5), st.integers(0, 3))
def test_camera_rules_equal_a_walk_over_every_pixel(pairs, frames, h, w, hblank, vblank):
    """Streamed pixels, the cycles in the lines and the busy union, each against the set of
    every pixel's camera cycle and every frame's line cycles."""
    line, frame = w + hblank, (h + vblank) * (w + hblank)
    pixel_cycles = sorted(camera_cycle(f, x, y, line, frame, pairs)
                          for f in range(frames) for y in range(h) for x in range(w))
    in_lines = set()
    for f in range(frames):
        s = camera_frame_start(f, frame, pairs)
        in_lines.update(range(s, s + h * line))
    end = camera_frame_start(frames - 1, frame, pairs) + frame + 2
    for c in range(-1, end):
        assert camera_pixels_streamed(c, frames, h, w, line, frame, pairs) == \
            sum(1 for p in pixel_cycles if p <= c)
        assert camera_in_lines(c, frames, h, line, frame, pairs) == (c in in_lines)
        assert camera_busy_cycles(c, frames, h, line, frame, pairs) == \
            sum(1 for t in in_lines if t < c)


# ---- whole runs -----------------------------------------------------------------------------


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_pairs_far_apart_each_get_the_latency_of_a_lone_pair(run):
    """Frames of (16 + 344) lines of 40 clocks, 14,400 cycles, the second pair 7,200 cycles
    after the first: the chip has read and computed each frame (5,760 NNA cycles, the reads
    paced by the NNA) before the other pair's next frame starts. So every frame's latency is
    the lone pair's, each pair sustains its camera's rate and the chip twice that; frame f
    starts at f x 7,200 cycles."""
    over = {"source.camera_hblank": 0, "source.camera_vblank": 344,
            "source.frame_buffers": 1}
    lone = run_compiled(_plan(1, **over), *_stream(1, 5)).report["stream"]
    plan = _plan(3, **over, **{"sva.pairs": 2})
    res = run(plan, *_stream(3, 5))
    st_ = res.report["stream"]
    assert st_["frames"] == 6 and st_["frames_dropped"] == 0
    assert set(st_["latency_ms_per_frame"]) == {lone["latency_ms"]["min"]}
    period = plan.domains["camera"].period_fs
    np.testing.assert_array_equal(res.frame_times[0], np.arange(6) * 7200 * period)
    np.testing.assert_array_equal(res.frame_times[2], np.arange(6))
    assert st_["sustained_fps"] == round(400e6 / 7200, 3)
    assert [p["sustained_fps"] for p in st_["pairs"]] == [round(400e6 / 14400, 3)] * 2
    assert [p["frames_completed"] for p in st_["pairs"]] == [3, 3]


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_two_pairs_with_a_buffer_each_are_a_pair_with_two_buffers_until_a_drop(run):
    """Two pairs of 8,000-cycle frames, 4,000 apart, one buffer each, against one pair of
    4,000-cycle frames into two buffers (lines of 200 cycles in both): the frames start at the same
    instants (4,000 f), and while the pairs' frames alternate, the buffer a pair's next frame needs
    holds the frame taken two before -- the lone pair's rule with two buffers. The chip falls behind
    by 5,760 - 4,000 cycles a frame; the first drop is the same frame, and with six frames it is
    the only one: the same frames, instants and words."""
    shared = _plan(3, **{"source.camera_hblank": 160, "source.camera_vblank": 24,
                         "source.frame_buffers": 1, "sva.pairs": 2})
    lone = _plan(6, **{"source.camera_hblank": 160, "source.camera_vblank": 4,
                       "source.frame_buffers": 2})
    assert shared.block("camera_left").frame_clocks == 8000
    assert lone.block("camera_left").frame_clocks == 4000
    left, right = _stream(3, 6)
    got_shared, got_lone = [], []
    a = run(shared, left, right, on_frame=lambda f, w: got_shared.append((f, w.copy())))
    b = run(lone, np.repeat(left, 2, axis=0), np.repeat(right, 2, axis=0),
            on_frame=lambda f, w: got_lone.append((f, w.copy())))
    assert a.report["stream"]["dropped_frames"] == b.report["stream"]["dropped_frames"] == [5]
    np.testing.assert_array_equal(a.frame_times, b.frame_times)
    assert [f for f, _ in got_shared] == [f for f, _ in got_lone] == [0, 1, 2, 3, 4]
    for (_, x), (_, y) in zip(got_shared, got_lone):
        np.testing.assert_array_equal(x, y)
    pairs = a.report["stream"]["pairs"]
    assert [p["dropped_frames"] for p in pairs] == [[], [5]]
    assert [p["frames_completed"] for p in pairs] == [3, 2]


def test_the_error_policy_names_the_pair():
    plan = _plan(3, **{"source.camera_hblank": 160, "source.camera_vblank": 24,
                       "source.frame_buffers": 1, "sva.pairs": 2,
                       "source.on_overflow": "error"})
    for run in (run_readable, run_compiled):
        with pytest.raises(CameraOverflow, match=r"found no free frame buffer for frame 5 of "
                           r"pair 1 \(its frame 2\), cycle 20000: the NNA still reads frame 3 "
                           r"from the buffer it needs \(1 buffer\(s\) per pair\)"):
            run(plan, *_stream(3, 7))


@pytest.mark.parametrize("over", [
    {"sva.pairs": 3, "source.frame_buffers": 1, "source.camera_hblank": 200},
    {"sva.pairs": 2, "source.frame_buffers": 2, "source.camera_hblank": 100,
     "nna.stereo_submodules": 4, "nna.split": "rows", "fifo.nna_to_merge_depth": 8},
    {"sva.pairs": 2, "source.frame_buffers": 1, "source.camera_hblank": 60,
     "dram.model": "tdm", "dram.gbps": 8.0, "dram.burst_bytes": 16},
])
def test_the_engines_agree_with_pairs(over, engines_agree):
    plan = _plan(3, **{"source.camera_vblank": 2, **over})
    left, right = _stream(3, 8)
    slow, words = engines_agree(plan, left, right)
    p = over["sva.pairs"]
    for f, a in words:  # camera frame f shows the stream's frame f // P
        np.testing.assert_array_equal(a, functional_words(plan.spec, plan.descriptor_bits,
                                                          left[f // p], right[f // p]))
    assert sum(p["frames"] for p in slow.report["stream"]["pairs"]) == 3 * over["sva.pairs"]


def test_pairs_need_cameras_into_frame_buffers():
    with pytest.raises(ConfigError, match="sva.pairs=2 shares the chip between camera pairs "
                       "frame by frame, which needs each pair's frames in DRAM frame buffers"):
        _plan(2, **{"sva.pairs": 2})
    with pytest.raises(ConfigError, match="sva.pairs=2"):
        build_plan(load_config(overrides={"sva.pairs": 2}), (H, W), 1)
    plan = _plan(2, **{"sva.pairs": 2, "source.frame_buffers": 1,
                       "dram.model": "tdm"})
    assert plan.frames == 4 and plan.dram.client("camera_write").count == 4
