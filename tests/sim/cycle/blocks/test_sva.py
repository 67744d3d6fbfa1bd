"""The SVA, block by block: sim/cycle/compiled/sva.py against its readable twin
(sim/cycle/readable/blocks/sva.py: SvaBlock). Each test runs one plan on both engines and holds
the SVA's own results equal -- its statistics, each stage's statistics and peak words, its
descriptor rows, the two FIFOs it pops and the one it pushes, its traced signals (its stages'
included) -- on a configuration that stresses the SVA."""

import numpy as np
import pytest

BASE = {"nna.descriptor": "census", "source.memory_gbps": 4.0}
ALWAYS = {"row_read", "hamming", "box_filter", "sgm", "path_sum", "wta", "output"}


@pytest.mark.parametrize("over", [
    {"sva.disparities": 16, "sva.lanes": 1, "sva.median": 0, "sva.lr_check": False,
     "sva.paths": 1, "sva.box_size": 1},
    {"sva.disparities": 32, "sva.lanes": 4, "sva.sram_ports": "1rw", "sva.median": 3,
     "sva.lr_check": True, "sva.paths": 2, "sva.box_size": 3, "sva.compare_levels": 1},
    {"sva.disparities": 16, "sva.lanes": 128, "sva.median": 5, "sva.lr_check": True,
     "sva.paths": 4, "sva.box_size": 5, "sva.compare_levels": 8},
    {"sva.disparities": 32, "sva.lanes": 3, "sva.sram_ports": "1rw", "sva.median": 5,
     "sva.lr_check": False, "sva.paths": 3, "sva.box_size": 7, "sva.compare_levels": 2},
    {"sva.disparities": 16, "sva.lanes": 16, "sva.sram_ports": "1r1w", "sva.median": 0,
     "sva.lr_check": True, "sva.paths": 1, "sva.box_size": 3, "sva.compare_levels": 1},
])
def test_disparities_lanes_ports_paths_median_lr(bench, over):
    """SVA: D of 16 or 32 on 1 to 128 lanes (ceil(D / lanes) cycles a pixel a stage), one
    shared SRAM port or two, 1 to 4 SGM paths, box 1 to 7, median off, 3 or 5, the LR check on
    or off, 1 to 8 compare levels a cycle: the stages the configuration builds, each stage's
    statistics and peak words, and the issue and push of every word."""
    plan, slow, fast = bench.run({**BASE, **over}, (5, 36))
    got = bench.agree(plan, slow, fast, "sva")
    stages = set(ALWAYS)
    if over["sva.lr_check"]:
        stages.add("lr_check")
    if over["sva.median"]:
        stages.add("median")
    assert set(got["stages"]) == stages
    assert got["stages"]["row_read"]["busy"] == 5 * 36  # a pixel pair a cycle read


@pytest.mark.parametrize("stall", [(2, 0), (4, 3), (7, 1), "script"])
def test_a_stalled_sink_freezes_the_pipeline(bench, stall):
    """SVA (lock-step pipeline): a sink that pops only some cycles -- periodic or a random
    script -- fills the SVA's output FIFO, and each stall freezes every word in flight
    (blocked), on a fast SVA (128 lanes) that would otherwise never wait."""
    if stall == "script":
        stall = np.random.default_rng(3).random(97) < 0.3
        stall[0] = True
    over = {**BASE, "sva.disparities": 16, "sva.lanes": 128, "sva.median": 5,
            "sva.lr_check": True, "fifo.sva_to_sink_depth": 2}
    plan, slow, fast = bench.run(over, (6, 30), sink_stall=stall)
    got = bench.agree(plan, slow, fast, "sva")
    assert got["stats"]["blocked"] > 0
    assert got["fifo sva_to_sink stats"]["cycles_full"] > 0
    _, stalls = got["signal top.sva.pipeline.stall"]
    assert stalls  # the pipeline's stall signal moved


def test_a_stream_of_frames(bench):
    """SVA over a stream: three frames back to back, each frame's passes (the LR check's and
    the median's) starting when its rows arrive while the last frame's words drain."""
    over = {**BASE, "sva.disparities": 16, "sva.lanes": 8, "sva.median": 3,
            "sva.lr_check": True, "sva.paths": 2}
    plan, slow, fast = bench.run(over, (5, 30), frames=3)
    got = bench.agree(plan, slow, fast, "sva")
    assert got["fifo sva_to_sink stats"]["pushes"] == 3 * 5 * 30
