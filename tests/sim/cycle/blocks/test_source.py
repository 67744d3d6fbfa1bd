"""The frame sources, block by block: sim/cycle/compiled/source.py against its readable twin
(sim/cycle/readable/blocks/sources.py: MemorySource, CameraSource, FrameBuffers, the DRAM
channel's reads). Each test runs one plan on both engines and holds the source blocks' own
results equal -- statistics, the FIFOs they push into, their traced signals, or their state
when the run stops -- on a configuration that stresses the sources."""

import re

import numpy as np
import pytest

from stereosim.sim.cycle.contract import CameraOverflow, FrameBufferFull

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census"}
CAMERA = {**CENSUS, "source.kind": "camera", "clocks.camera_mhz": 120}


def _sources(plan):
    return [b.name for b in plan.blocks if b.kind in ("memory", "camera")]


@pytest.mark.parametrize("gbps", [0.05, 0.2])
@pytest.mark.parametrize("parts,split", [(1, "columns"), (2, "columns"), (3, "rows")])
def test_a_memory_source_at_its_bandwidth_limit(bench, gbps, parts, split):
    """Memory source: its token bucket (source.memory_gbps) sets the pace, below one pixel a
    cycle, while it feeds one, two or three tiles of a split frame in joint pushes (a pixel
    of a halo goes to two tiles' FIFOs in one cycle)."""
    over = {**CENSUS, "source.memory_gbps": gbps, "nna.stereo_submodules": 2 * parts,
            "nna.split": split}
    plan, slow, fast = bench.run(over, (6, 24))
    for name in _sources(plan):
        got = bench.agree(plan, slow, fast, name)
        pushes = sum(got[f"fifo {f} stats"]["pushes"] for f in bench.fifos(plan, name))
        assert pushes >= 6 * 24  # every pixel, the halo's more than once
        assert got["stats"]["busy"] > 6 * 24  # waiting for tokens: slower than a pixel a cycle


def test_a_memory_source_blocked_by_a_slow_nna(bench, network_file):
    """Memory source: a one-slot FIFO into an NNA of 9 cycles a descriptor (a 3x3x1x8 layer on
    8 MACs) holds the source back (blocked) at nearly every pixel."""
    path, _ = network_file([(3, 1, 8)])
    over = {"sva.disparities": 16, "nna.descriptor": "cnn", "nna.cnn.weights": path,
            "nna.cnn.channels": 8, "nna.macs": 8, "nna.line_buffer_rows": 3,
            "source.memory_gbps": 4.0, "fifo.source_to_nna_depth": 1}
    plan, slow, fast = bench.run(over, (5, 20))
    for name in _sources(plan):
        got = bench.agree(plan, slow, fast, name)
        assert got["stats"]["blocked"] > 0
        (fifo,) = bench.fifos(plan, name)
        assert got[f"fifo {fifo} stats"]["cycles_full"] > 0


@pytest.mark.parametrize("mhz,hblank,vblank", [(25, 7, 2), (120, 0, 0), (120, 12, 4)])
def test_a_camera_with_blanking(bench, mhz, hblank, vblank):
    """Camera source: a pixel every camera cycle of a line, none in the horizontal and
    vertical blanking (source.camera_hblank/vblank), on its own clock domain crossing into
    the NNA's."""
    over = {**CAMERA, "clocks.camera_mhz": mhz, "source.camera_hblank": hblank,
            "source.camera_vblank": vblank}
    plan, slow, fast = bench.run(over, (5, 21), frames=2)
    for name in _sources(plan):
        got = bench.agree(plan, slow, fast, name)
        # the pixels it sent, one traced change each, both frames
        start, changes = next(v for k, v in got.items() if k.endswith(".sent"))
        assert (changes[-1][1] if changes else start) == 2 * 5 * 21


def test_a_camera_overflows_its_fifo(bench, network_file):
    """Camera source: a camera cannot wait, so a short FIFO into a slow NNA overflows once the
    line buffer is full and the MAC array sets the pace; the run stops on both engines at the
    same instant with the cameras and their FIFOs in the same state."""
    path, _ = network_file([(3, 1, 8)])
    over = {**CAMERA, "nna.descriptor": "cnn", "nna.cnn.weights": path, "nna.cnn.channels": 8,
            "nna.macs": 4, "nna.line_buffer_rows": 3, "fifo.source_to_nna_depth": 4,
            "source.camera_hblank": 0, "source.camera_vblank": 0}
    plan, slow, fast = bench.stop(over, (5, 20))
    assert type(slow) is CameraOverflow
    for name in _sources(plan):
        bench.agree(plan, slow, fast, name)
    # past the rows the line buffer takes at a pixel a cycle: the MAC array's pace
    y = int(re.search(r"overflowed FIFO src_left_to_nna at pixel \(\d+, (\d+)\)",
                      str(slow))[1])
    assert y >= 3


@pytest.mark.parametrize("buffers,gbps,pairs,frames",
                         [(1, 0.05, 1, 3), (2, 0.02, 1, 4), (1, 0.05, 2, 3)])
def test_frame_buffers_drop_the_frames_they_cannot_take(bench, buffers, gbps, pairs, frames):
    """Camera into frame buffers read by the memory source: the memory source reads slower
    than the camera writes (source.memory_gbps), so with ``drop_frame`` frames that find no
    free buffer are skipped -- which frames, and when each is read, are the sources' own
    decisions (the frame instants' first and third rows); camera pairs share the chip."""
    over = {**CAMERA, "source.camera_hblank": 2, "source.camera_vblank": 1,
            "source.frame_buffers": buffers, "source.on_overflow": "drop_frame",
            "source.memory_gbps": gbps, "sva.pairs": pairs}
    plan, slow, fast = bench.run(over, (5, 20), frames=frames)
    for name in _sources(plan):
        bench.agree(plan, slow, fast, name)
    assert slow.report["stream"]["frames_dropped"] > 0
    assert slow.report["stream"]["dropped_frames"] == fast.report["stream"]["dropped_frames"]
    np.testing.assert_array_equal(slow.frame_times[[0, 2]], fast.frame_times[[0, 2]])


def test_a_frame_finds_no_free_buffer(bench):
    """Frame buffers with ``on_overflow = "error"``: the second frame finds its only buffer
    still being read; both engines stop at the same instant, the sources in the same state."""
    over = {**CAMERA, "source.camera_hblank": 2, "source.camera_vblank": 1,
            "source.frame_buffers": 1, "source.on_overflow": "error",
            "source.memory_gbps": 0.05}
    plan, slow, fast = bench.stop(over, (5, 20), frames=3)
    assert type(slow) is FrameBufferFull
    for name in _sources(plan):
        bench.agree(plan, slow, fast, name)


@pytest.mark.parametrize("prefetch,burst,latency", [(1, 8, 400), (2, 4, 0), (8, 64, 50)])
def test_a_memory_source_reads_through_the_dram_channel(bench, prefetch, burst, latency):
    """Memory source through the DRAM channel (dram.model = "tdm"): its read bursts take the
    channel's slots and arrive after its latency, with at most ``read_prefetch_bursts``
    requested ahead, so the source waits for the channel (starved)."""
    over = {**CENSUS, "dram.model": "tdm", "dram.gbps": 0.3, "dram.burst_bytes": burst,
            "dram.read_prefetch_bursts": prefetch, "dram.latency_ns": latency}
    plan, slow, fast = bench.run(over, (5, 24))
    for name in _sources(plan):
        got = bench.agree(plan, slow, fast, name)
        assert got["stats"]["starved"] > 0
