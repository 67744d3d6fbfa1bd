"""The FIFOs, one by one: sim/cycle/compiled/fifo.py (occupancy and statistics from the
producer's pushes and the consumer's pops, by the rule of sim/cycle/fifo/rule.py) against the
readable twin (sim/cycle/fifo/readable.py: Fifo). Each test runs one plan on both engines and
holds every FIFO's own results equal -- pushes, pops, occupancy histogram, largest occupancy on
each side, cycles full and empty, its traced occupancy, push, pop, full and empty, or its
occupancy when the run stops -- on a configuration that stresses the FIFOs."""

import pytest

from stereosim.sim.cycle.contract import BudgetExceeded

SHALLOW = {"sva.disparities": 16, "nna.descriptor": "census", "source.memory_gbps": 4.0,
           "nna.stereo_submodules": 4, "fifo.source_to_nna_depth": 1,
           "fifo.nna_to_merge_depth": 1, "fifo.nna_to_sva_depth": 1,
           "fifo.sva_to_sink_depth": 1}


@pytest.mark.parametrize("nna_mhz,sva_mhz", [(200, 700), (460, 150), (400, 400)])
@pytest.mark.parametrize("latency,sync", [(1, 1), (3, 2), (2, 3)])
def test_depth_one_across_clocks(bench, nna_mhz, sva_mhz, latency, sync):
    """Every FIFO of one slot -- source to NNA tiles, tiles to merge, merge to SVA, SVA to
    sink -- with a latency of 1 to 3 consumer cycles and 1 to 3 synchroniser stages, the NNA
    and SVA clocks apart either way or equal: each push waits for the pop before it to be
    seen, so every FIFO is full (as its producer sees it) and never holds two."""
    over = {**SHALLOW, "clocks.nna_mhz": nna_mhz, "clocks.sva_mhz": sva_mhz,
            "fifo.latency_cycles": latency, "fifo.sync_cycles": sync}
    plan, slow, fast = bench.run(over, (5, 24))
    assert len(plan.fifos) == 11
    for fifo in plan.fifos:
        got = bench.fifo_agree(plan, slow, fast, fifo.name)
        stats = got["stats"]
        assert stats["pushes"] == stats["pops"] > 0
        assert stats["max_occupancy"] == 1 and len(stats["occupancy_histogram"]) == 2
        assert stats["max_producer_occupancy"] == 1
    assert slow.stats["fifos"]["sva_to_sink"]["cycles_full"] > 0


@pytest.mark.parametrize("latency,sync,depth", [(5, 1, 2), (1, 4, 3), (4, 3, 4)])
def test_latency_and_synchronisers_against_depth(bench, latency, sync, depth):
    """FIFOs whose latency and synchronisers are long for their depth (2 to 4 slots; 1 to 5
    cycles of latency, 1 to 4 stages): an item is seen late and the room a pop frees reaches
    the producer late, so the FIFOs fill to their depth as their producers count them; the
    producer never counts fewer than the consumer."""
    over = {**SHALLOW, "clocks.nna_mhz": 333, "clocks.sva_mhz": 465,
            "fifo.latency_cycles": latency, "fifo.sync_cycles": sync,
            "fifo.source_to_nna_depth": depth, "fifo.nna_to_merge_depth": depth,
            "fifo.nna_to_sva_depth": depth, "fifo.sva_to_sink_depth": depth}
    plan, slow, fast = bench.run(over, (5, 24))
    filled = 0
    for fifo in plan.fifos:
        stats = bench.fifo_agree(plan, slow, fast, fifo.name)["stats"]
        assert stats["max_occupancy"] <= stats["max_producer_occupancy"] <= depth
        filled += stats["max_producer_occupancy"] == depth
    assert filled >= len(plan.fifos) // 2


@pytest.mark.parametrize("camera_mhz,sync", [(120, 1), (250, 3), (25, 2)])
def test_a_camera_crossing_into_the_nna(bench, camera_mhz, sync):
    """The FIFO from a camera to the NNA crosses from the camera's clock (slower or faster
    than the NNA's) through 1 to 3 synchroniser stages; the camera cannot wait, so the FIFO
    is deep enough, and the NNA starves between the camera's pixels."""
    over = {"sva.disparities": 16, "nna.descriptor": "census", "source.kind": "camera",
            "clocks.camera_mhz": camera_mhz, "source.camera_hblank": 3,
            "source.camera_vblank": 1, "fifo.sync_cycles": sync, "fifo.source_to_nna_depth": 8}
    plan, slow, fast = bench.run(over, (4, 24), frames=2)
    for fifo in plan.fifos:
        got = bench.fifo_agree(plan, slow, fast, fifo.name)
        assert got["stats"]["pushes"] == 2 * 4 * 24
    assert slow.stats["blocks"]["nna_left"]["starved"] > 0


@pytest.mark.parametrize("max_cycles", [60, 150, 600])
def test_every_fifo_when_a_run_stops(bench, max_cycles):
    """FIFOs mid-run: a run stopped by ``sim.max_cycles`` leaves every FIFO holding what it
    held at the last step, the same on both engines, and the same traced signals up to the
    stop."""
    over = {**SHALLOW, "fifo.source_to_nna_depth": 4, "fifo.nna_to_merge_depth": 6,
            "fifo.nna_to_sva_depth": 3, "fifo.sva_to_sink_depth": 2,
            "sim.max_cycles": max_cycles}
    plan, slow, fast = bench.stop(over, (6, 30), sink_stall=(3, 1))
    assert type(slow) is BudgetExceeded and slow.time_fs == fast.time_fs
    held = 0
    for fifo in plan.fifos:
        held += bench.fifo_agree(plan, slow, fast, fifo.name)["state"]["occupancy"]
    assert held > 0
