"""A camera writing its frames into DRAM frame buffers, read by the memory sources:
each frame is taken or dropped when it starts, by the rule in sim/cycle/rules.py, the same in
both engines; a frame that finds no free buffer stops the run (policy error) or is skipped and
counted (drop_frame)."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import CameraOverflow
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable

H, W, N = 16, 40, 6
# CNN at 400 MHz: a 16x40 frame is 640 descriptors x 9 MAC cycles = 5,760 NNA cycles of work
CHIP = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16,
        "nna.descriptor": "cnn", "source.kind": "camera", "clocks.camera_mhz": 400,
        "source.camera_vblank": 4}


def _stream(seed=0):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (N, H, W + 2), dtype=np.uint8)
    return left[:, :, :W].copy(), left[:, :, 2:].copy()


def _plan(hblank, buffers, policy="drop_frame", **over):
    return build_plan(load_config(overrides={**CHIP, "source.camera_hblank": hblank,
                                             "source.frame_buffers": buffers,
                                             "source.on_overflow": policy, **over}), (H, W), N)


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_one_buffer_drops_every_other_frame_of_a_camera_faster_than_the_chip(run):
    """Frames every (16 + 4)(40 + 160) = 4,000 camera cycles, 10 us at 400 MHz, into one
    buffer; reading a frame takes the NNA longer than one frame period and less than two, so
    when frame f + 1 starts the reader is still on frame f: dropped; frame f + 2 finds the
    buffer free. The pair sustains half the camera's rate, and every frame it takes is exact."""
    plan = _plan(hblank=160, buffers=1)
    assert plan.block("camera_left").frame_clocks == 4000
    left, right = _stream()
    got = []
    res = run(plan, left, right, on_frame=lambda f, words: got.append(f))
    st = res.report["stream"]
    assert st["dropped_frames"] == [1, 3, 5] and st["frames_dropped"] == 3
    assert got == [0, 2, 4] and st["frames_completed"] == 3
    assert st["sustained_fps"] == 400e6 / 8000
    period = plan.domains["camera"].period_fs
    np.testing.assert_array_equal(res.frame_times[0, :3], np.array([0, 2, 4]) * 4000 * period)


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_two_buffers_absorb_the_rate_until_the_backlog_is_a_frame(run):
    """With two buffers the reader falls behind by 5,760 - 4,000 cycles a frame; the camera
    takes frames until the buffer it needs is still being read -- then the pair runs at the
    NNA's own rate (its work bound), 400 MHz / 5,760."""
    plan = _plan(hblank=160, buffers=2)
    res = run(plan, *_stream(1))
    st = res.report["stream"]
    assert st["dropped_frames"] == [5]
    assert st["sustained_fps"] == res.report["throughput"]["fps_bound_per_block"]["nna_left"] \
        == round(400e6 / 5760, 3)


def test_a_camera_slower_than_the_chip_drops_nothing_and_errors_name_the_frame():
    slow = run_compiled(_plan(hblank=260, buffers=1), *_stream(2)).report["stream"]
    assert slow["frames_dropped"] == 0 and slow["frames_completed"] == N
    for run in (run_readable, run_compiled):
        with pytest.raises(CameraOverflow, match="camera 'camera_left' found no free frame "
                           "buffer for frame 1, cycle 4000: the NNA still reads frame 0"):
            run(_plan(hblank=160, buffers=1, policy="error"), *_stream(3))


@pytest.mark.parametrize("over", [
    {"source.camera_hblank": 160, "source.frame_buffers": 1, "nna.stereo_submodules": 4},
    {"source.camera_hblank": 100, "source.frame_buffers": 2, "nna.stereo_submodules": 4,
     "nna.split": "rows", "fifo.nna_to_merge_depth": 8},
    {"source.camera_hblank": 60, "source.frame_buffers": 3, "clocks.camera_mhz": 150},
])
def test_the_engines_agree_with_frame_buffers(over, engines_agree):
    plan = build_plan(load_config(overrides={**CHIP, "source.on_overflow": "drop_frame",
                                             **over}), (H, W), N)
    engines_agree(plan, *_stream(4))


def test_dropping_needs_frame_buffers():
    with pytest.raises(ConfigError, match="drop_frame needs a camera with frame buffers"):
        _plan(hblank=160, buffers=0)
