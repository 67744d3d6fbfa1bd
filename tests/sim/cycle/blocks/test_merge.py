"""The merge of a split frame, block by block: sim/cycle/compiled/merge.py against its readable
twin (sim/cycle/readable/blocks/nna.py: Merge). Each test runs one plan on both engines and
holds the merges' own results equal -- statistics, the tile FIFOs they pop and the SVA FIFO
they push, their traced signals -- on a configuration that stresses the merge."""

import pytest

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census", "source.memory_gbps": 4.0}


def _merges(plan):
    return [b.name for b in plan.blocks if b.kind == "merge"]


@pytest.mark.parametrize("parts", [2, 3, 4, 5, 6])
@pytest.mark.parametrize("split", ["columns", "rows"])
def test_two_to_six_tiles(bench, parts, split):
    """Merge: 2 to 6 submodules a camera (column tiles or row bands) into one raster stream,
    each descriptor moved from its owner tile's FIFO once visible there; the tiles finish out of
    raster order, so the merge waits on one tile while others' FIFOs fill (starved)."""
    over = {**CENSUS, "nna.submodules": 12, "nna.stereo_submodules": 2 * parts,
            "nna.split": split}
    plan, slow, fast = bench.run(over, (max(6, parts), 40))
    names = _merges(plan)
    assert len(names) == 2
    for name in names:
        got = bench.agree(plan, slow, fast, name)
        assert len(bench.fifos(plan, name)) == parts + 1  # the tiles' FIFOs and the SVA's
        assert got["stats"]["busy"] == plan.shape[0] * plan.shape[1]  # a move a descriptor
        assert got["stats"]["starved"] > 0


@pytest.mark.parametrize("merge_depth,sva_depth", [(1, 1), (3, 1), (1, 4)])
@pytest.mark.parametrize("split", ["columns", "rows"])
def test_short_fifos_on_both_sides(bench, merge_depth, sva_depth, split):
    """Merge: one-to-three-slot tile FIFOs (fifo.nna_to_merge_depth) fill while the merge serves
    the other tiles, and a one-slot SVA FIFO (fifo.nna_to_sva_depth) in front of an SVA of 8
    cycles a pixel (D = 16 on two lanes) holds the merge back (blocked; a four-slot one does
    not)."""
    over = {**CENSUS, "sva.lanes": 2, "nna.stereo_submodules": 6, "nna.split": split,
            "fifo.nna_to_merge_depth": merge_depth, "fifo.nna_to_sva_depth": sva_depth}
    plan, slow, fast = bench.run(over, (4, 36))
    for name in _merges(plan):
        got = bench.agree(plan, slow, fast, name)
        assert (got["stats"]["blocked"] > 0) == (sva_depth == 1)
        tiles = [f for f in bench.fifos(plan, name) if plan.fifo(f).consumer == name]
        assert all(got[f"fifo {f} stats"]["max_occupancy"] <= merge_depth for f in tiles)
        assert any(got[f"fifo {f} stats"]["cycles_full"] > 0 for f in tiles)


def test_a_stream_of_frames(bench):
    """Merge over a stream: three frames back to back through three column tiles, the merge
    crossing from one frame's last descriptor to the next frame's first."""
    over = {**CENSUS, "nna.stereo_submodules": 6, "fifo.nna_to_merge_depth": 4}
    plan, slow, fast = bench.run(over, (5, 33), frames=3)
    for name in _merges(plan):
        got = bench.agree(plan, slow, fast, name)
        assert got["stats"]["busy"] == 3 * 5 * 33
