"""The NNA submodule, block by block: sim/cycle/compiled/nna.py against its readable twin
(sim/cycle/readable/blocks/nna.py: LineBuffer, MacArray, NnaSubmodule). Each test runs one
plan on both engines and holds the submodules' own results equal -- statistics, per-layer
statistics, line buffer peaks, the FIFOs they pop and push, their traced signals -- on a
configuration that stresses the submodule."""

import pytest

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census", "source.memory_gbps": 4.0}


def _submodules(plan):
    return [b.name for b in plan.blocks if b.kind == "nna"]


def _cnn(path, channels, **more):
    return {"sva.disparities": 16, "nna.descriptor": "cnn", "nna.cnn.weights": path,
            "nna.cnn.channels": channels, "source.memory_gbps": 4.0, **more}


@pytest.mark.parametrize("window,rows", [((11, 3), 3), ((11, 3), 4), ((5, 5), 5), ((3, 7), 8)])
def test_the_census_line_buffer_at_its_limit(bench, window, rows):
    """NNA submodule (census unit): a line buffer of exactly the census window's height (or one
    row more) must free a row before the next arrives, so the input waits on the window; the
    peak the engines report is the buffer's capacity."""
    over = {**CENSUS, "nna.census.window": list(window), "nna.line_buffer_rows": rows}
    plan, slow, fast = bench.run(over, (9, 24))
    for name in _submodules(plan):
        got = bench.agree(plan, slow, fast, name)
        (buffer,) = got["buffers"].values()
        assert buffer["peak_rows"] == buffer["capacity_rows"] == rows


@pytest.mark.parametrize("shapes,layer_macs,rows", [
    (((3, 1, 4), (3, 4, 8)), [4, 36], 3),
    (((3, 1, 4), (3, 4, 8)), [36, 8], 4),
    (((1, 1, 8), (5, 8, 4), (3, 4, 8)), None, 3),
    (((1, 1, 8), (5, 8, 4), (3, 4, 8)), [8, 200, 10], 3),
    (((5, 1, 4), (1, 4, 8), (3, 8, 2)), [25, 8, 144], 5),
])
def test_a_chain_of_layers(bench, network_file, shapes, layer_macs, rows):
    """NNA submodule (layer chain): two or three layers, each a line buffer and a MAC array,
    their MAC shares given (nna.layer_macs: a slow middle or last layer makes the layer
    before it wait for room in its line buffer -- blocked) or split in proportion
    (nna.macs); every layer's statistics and line buffer peak are the engines' alike."""
    path, _ = network_file(shapes)
    macs = {"nna.macs": 200} if layer_macs is None else {"nna.layer_macs": layer_macs,
                                                         "nna.macs": sum(layer_macs)}
    over = _cnn(path, shapes[-1][2], **macs, **{"nna.line_buffer_rows": rows})
    plan, slow, fast = bench.run(over, (8, 22))
    for name in _submodules(plan):
        got = bench.agree(plan, slow, fast, name)
        layers = got["layers"]
        assert len(layers) == len(got["buffers"]) == len(shapes)  # a line buffer a layer
        firsts = [layer["first_output_cycle"] for layer in layers]
        assert firsts == sorted(firsts) and len(set(firsts)) == len(firsts)
        if layer_macs is not None:
            assert any(layer["blocked"] > 0 for layer in layers[:-1])


def test_the_mac_array_blocked_by_a_slow_sva(bench):
    """NNA submodule (MAC array's output): a one-slot FIFO into an SVA that takes 32 cycles a
    pixel (D = 32 on one lane) holds every finished descriptor (blocked)."""
    over = {**CENSUS, "sva.disparities": 32, "sva.lanes": 1, "fifo.nna_to_sva_depth": 1}
    plan, slow, fast = bench.run(over, (4, 36))
    for name in _submodules(plan):
        got = bench.agree(plan, slow, fast, name)
        assert got["stats"]["blocked"] > 0
        out = [f for f in bench.fifos(plan, name) if plan.fifo(f).producer == name]
        assert got[f"fifo {out[0]} stats"]["cycles_full"] > 0


@pytest.mark.parametrize("split,parts", [("columns", 2), ("rows", 2), ("columns", 3)])
def test_tiles_of_a_split_frame(bench, network_file, split, parts):
    """NNA submodules of a split frame: each tile (column tile or row band) computes its region
    from its input region with the halo the window needs, from a joint push of the source."""
    path, _ = network_file([(3, 1, 4), (3, 4, 8)])
    over = _cnn(path, 8, **{"nna.macs": 40, "nna.line_buffer_rows": 3,
                            "nna.stereo_submodules": 2 * parts, "nna.split": split})
    plan, slow, fast = bench.run(over, (9, 30))
    names = _submodules(plan)
    assert len(names) == 2 * parts
    for name in names:
        bench.agree(plan, slow, fast, name)


def test_the_shipped_network_at_one_descriptor_a_cycle(bench):
    """NNA submodule (the shipped 9x9x32 network): 2592 MACs give one descriptor a cycle, so
    the line buffer of 9 rows -- the window's height, its limit -- sets the pace."""
    over = {"sva.disparities": 16, "nna.descriptor": "cnn", "nna.macs": 2592,
            "nna.line_buffer_rows": 9, "source.memory_gbps": 4.0}
    plan, slow, fast = bench.run(over, (12, 24))
    for name in _submodules(plan):
        got = bench.agree(plan, slow, fast, name)
        (buffer,) = got["buffers"].values()
        assert buffer["peak_rows"] == 9


def test_the_hybrid_descriptor(bench, network_file):
    """NNA submodule (hybrid: a network's bits beside a census within its reach): the census
    unit and the layer chain share the submodule's input rows."""
    path, _ = network_file([(3, 1, 4), (3, 4, 8)])
    over = _cnn(path, 8, **{"nna.descriptor": "hybrid", "nna.macs": 40,
                            "nna.line_buffer_rows": 3, "nna.census.window": [5, 3],
                            "sva.cost_weights": [1, 2]})
    plan, slow, fast = bench.run(over, (7, 24))
    for name in _submodules(plan):
        bench.agree(plan, slow, fast, name)
