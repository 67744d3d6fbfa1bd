"""The RTL NNA submodule (nna/submodule/nna_submodule.sv) co-simulated against stereosim: a 9x9 x 32
layer and a chain of two 3x3 layers on a 20 x 12 frame, the whole frame through one submodule
(tests/rtl/nna_bench.py). Every descriptor equals the functional model's
(nna/descriptor.py compute_descriptor) bit for bit, every pixel is popped and every descriptor
pushed in the cycle the readable cycle engine pops and pushes it (its NNA block,
sim/cycle/readable/blocks/nna.py), run on the same frame and configuration at test time.

Structure (build-time): the frame's size, each layer's kernel, channels, line-buffer rows and
P multipliers per output channel -- the layer's MAC share is C_out P, so ii = ceil(K^2 C_in /
P) = ceil(m / share). The networks (weights, biases, multiply-shift, the input offset) are
run-time inputs: the chain's build serves two networks here.

Findings (structure vs plan), which the configurations here stay clear of (asserted):

1. The row start. The plan's line buffer reads, per output pixel, the window's next column, one
   word from each of its 2 h + 1 row banks. A row's first window needs h + 1 distinct columns
   (column 0 replicated, then 1 .. h); read one a cycle, MAC cycle j of that output (taps
   kx-major, P a cycle) can run when min(kx of its last tap, 2 h) <= h + c, c the columns
   read. So its MAC cycle j runs in t_j = max(t_(j-1) + 1, min(kx_j, 2 h) - h) (t_(-1) = -1)
   and the row's first output leaves e = t_(ii-1) - (ii - 1) cycles after the plan's
   S_l(y) + ii - 1. e = 0 here (:func:`_window_keeps_up`); a 7x7 x 1 x 4 layer on 68 MACs
   (P 17, ii 3) has min(kx_j, 6) = 2, 4, 6 -> t = 0, 1, 3, e = 1: on the RTL every output
   row left one cycle later than the one before relative to the model (row y: y + 1 cycles
   late, the last descriptor 12 cycles late on 20 x 12), the words still bit-exact. The
   plan's rule holds for ii >= the cycles the reads take; otherwise a second read port, or
   reading the next row's first columns during the previous row, would be needed.
2. The MAC share. The plan's ii = ceil(m / share) lets any multiplier feed any channel's
   accumulator in any cycle. The structure here (P multipliers and an adder tree per output
   channel) gives it when the share is a multiple of C_out; otherwise
   ceil(K^2 C_in / floor(share / C_out)) cycles: mccnn4's 95 MACs for a 3x3 x 32 x 32 layer
   give 144 for the plan's 98, its 3 MACs for the 32-channel first layer none at all; the
   plan's figure needs a product-to-accumulator crossbar (or channel-serial accumulators).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from stereosim.core.config import load_config
from stereosim.nna.descriptor import compute_descriptor
from stereosim.quant.artifact import QuantizedModel, save_quantized
from stereosim.quant.intconv import network as int_network
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import build_chip

SOURCE = "nna/submodule/nna_submodule.sv"
SHAPE = (12, 20)  # (H, W): the whole frame, one tile, through one submodule
# a 16-disparity SVA on an equal clock: the NNA, at 3 or more cycles a descriptor, never
# waits for it
BASE = {"nna.descriptor": "cnn", "sva.disparities": 16, "clocks.sva_mhz": 460.0}


def _frame(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (SHAPE[0], SHAPE[1] + 3)).astype(np.uint8)
    return np.ascontiguousarray(base[:, 3:]), np.ascontiguousarray(base[:, :-3])


def _random_network(path, shapes, seed: int, offset: int) -> str:
    """A quantised artifact of a random integer network of layers (K, C_in, C_out) (weights
    -20..20, biases -500..499, mult 1..255, shift 10: activations spread over 0..127)."""
    rng = np.random.default_rng(seed)
    w, b, m, h = [], [], [], []
    for i, (k, c_in, c_out) in enumerate(shapes):
        w.append(rng.integers(-20, 21, (c_out, c_in, k, k)).astype(np.int8))
        b.append(rng.integers(-500, 500, c_out).astype(np.int32))
        if i < len(shapes) - 1:
            m.append(rng.integers(1, 256, c_out).astype(np.int32))
            h.append(np.full(c_out, 10, np.int32))
    net = int_network(tuple(w), tuple(b), tuple(m), tuple(h), offset)
    save_quantized(path, QuantizedModel(
        weights=net.weights, biases=net.biases, mult=net.mult, shift=net.shift,
        input_offset=net.input_offset, input_scale=1.0, z_bits=net.z_bits,
        weight_scales=tuple(np.ones(x.shape[0]) for x in net.weights),
        act_scales=np.ones(net.n_layers), distances=("rms",) * net.n_layers,
        sign_agreement=1.0, acc_rms=0.0))
    return str(path)


def _window_keeps_up(k: int, c_in: int, p: int) -> bool:
    """The RTL's window loads a row's first h + 1 columns one a cycle (column c in MAC cycle
    c) while the taps go column by column, P a cycle: it keeps up with the taps if, in every
    MAC cycle j of ii, min(kx of the cycle's last tap, 2 h) <= h + j."""
    h, ii = k // 2, -(-(k * k * c_in) // p)
    return all(min(((j + 1) * p - 1) // (k * c_in), 2 * h) <= h + j for j in range(ii))


def _model_run(plan, left, right) -> dict:
    """The readable engine on the pair: for the left NNA submodule, the cycle each pixel became
    visible in its input FIFO, each pop, each push and the pushed descriptors."""
    chip = build_chip(left, right, plan)
    nna = chip.blocks["nna_left"]
    inp, out = nna.inp, nna.out
    rec = {"visible": [], "pops": [], "pushes": [], "pushed": []}
    commit, pop, push = inp._commit, inp.pop, out.push

    def on_commit(now_fs):
        before = inp._pushes
        moved = commit(now_fs)
        if inp._pushes > before:
            rec["visible"].append(int(inp._items[-1][0]))
        return moved

    def on_pop():
        rec["pops"].append(int(inp._dst_cycle))
        return pop()

    def on_push(beat):
        rec["pushes"].append(int(out._src_cycle))
        rec["pushed"].append(int(beat.descriptor))
        push(beat)

    inp._commit, inp.pop, out.push = on_commit, on_pop, on_push
    chip.run()
    return rec


def _late_mac_rule(plan):
    """The plan with the last layer's MAC array one cycle slower per output (ii + 1): a
    mutant of the rule, which the unchanged RTL must catch."""
    def late(entry):
        if entry.kind != "nna":
            return entry
        *rest, last = entry.layers
        return dataclasses.replace(entry, layers=(*rest, dataclasses.replace(
            last, ii=last.ii + 1)))
    return dataclasses.replace(plan, blocks=tuple(late(b) for b in plan.blocks))


def _case(cfg, seed: int, name: str, mutant: bool = False) -> tuple[dict, dict]:
    """(the build's parameters, one run of the bench) for ``cfg`` on the frame of ``seed``;
    with ``mutant`` the cycles come from :func:`_late_mac_rule`'s plan."""
    left, right = _frame(seed)
    plan = build_plan(cfg, left.shape)
    layers = plan.block("nna_left").layers
    net = plan.spec.nna.cnn  # the network the run resolved
    params = {"LAYERS": len(layers), "W": SHAPE[1], "H": SHAPE[0]}
    for i, lay in enumerate(layers):
        assert lay.tile.shape == SHAPE and lay.macs % lay.channels_out == 0, lay
        assert _window_keeps_up(2 * lay.half + 1, lay.channels_in,
                                lay.macs // lay.channels_out), lay
        params.update({f"K{i}": 2 * lay.half + 1, f"C{i + 1}": lay.channels_out,
                       f"P{i}": lay.macs // lay.channels_out, f"ROWS{i}": lay.rows})
    model = _late_mac_rule(plan) if mutant else plan
    rec = _model_run(model, left, right)
    words = compute_descriptor(left, cfg.nna).astype(np.uint64).ravel().tolist()
    assert rec["pushed"] == words  # the cycle model's own descriptors are the functional ones
    run = {"name": name, "width": SHAPE[1], "pixels": left.ravel().tolist(),
           "offset": net.input_offset, "words": [int(x) for x in words],
           "visible": rec["visible"], "pops": rec["pops"], "pushes": rec["pushes"],
           "cycles": [lay.ii for lay in model.block("nna_left").layers],
           "layers": [{"weights": w.transpose(0, 3, 2, 1).ravel().tolist(),
                       "bias": b.tolist(),
                       "mult": net.mult[i].tolist() if i < net.n_layers - 1 else [],
                       "shift": net.shift[i].tolist() if i < net.n_layers - 1 else []}
                      for i, (w, b) in enumerate(zip(net.weights, net.biases))]}
    return params, run


def _runs(configs, mutant: bool = False) -> tuple[dict, list[dict]]:
    """One build's parameters (every config must give the same) and its runs."""
    cases = [_case(cfg, seed, name, mutant) for seed, (name, cfg) in enumerate(configs)]
    assert all(params == cases[0][0] for params, _ in cases)
    return cases[0][0], [run for _, run in cases]


def test_one_9x9_layer_of_32_channels(rtl_run):
    """The repo's default network (nna/conv/single9x9.npz) on 288 MACs (9 per channel: ii 9; its
    10-row line buffer makes rows 10 and 11 wait for room)."""
    params, runs = _runs([("single9x9", load_config(overrides={**BASE, "nna.macs": 288}))])
    assert params["P0"] == 9 and params["ROWS0"] == 10
    rtl_run(SOURCE, "nna_submodule", params, "nna_bench", {"runs": runs})


def _chain_configs(tmp_path, seeds) -> list:
    """(name, config) of the two-layer chain, one random network per (seed, input offset)."""
    out = []
    for seed, offset in seeds:
        path = _random_network(tmp_path / f"two{seed}.int8.npz", ((3, 1, 4), (3, 4, 8)), seed,
                               offset)
        out.append((f"two 3x3, net {seed}", load_config(overrides={
            **BASE, "nna.cnn.weights": path, "nna.cnn.channels": 8, "nna.macs": 64,
            "nna.layer_macs": [12, 48], "nna.line_buffer_rows": 4})))
    return out


def test_a_chain_of_two_3x3_layers(rtl_run, tmp_path):
    """3x3 x 1 x 4 requantised into 3x3 x 4 x 8 on 12 + 48 MACs (ii 3 and 6: layer 0 waits for
    room in layer 1's 4-row line buffer), two random networks."""
    params, runs = _runs(_chain_configs(tmp_path, ((1, 128), (2, 60))))
    assert [runs[0]["cycles"], params["P0"], params["P1"]] == [[3, 6], 3, 6]
    rtl_run(SOURCE, "nna_submodule", params, "nna_bench", {"runs": runs})


def test_a_one_cycle_mutant_of_the_mac_rule_is_caught_by_name(rtl_run, tmp_path):
    """The plan's last MAC array one cycle slower an output (ii 7 for the structure's 6): the
    unchanged RTL (the chain's build) catches it, by the name of the MAC array's rule."""
    params, runs = _runs(_chain_configs(tmp_path, ((1, 128),)), mutant=True)
    xml = rtl_run(SOURCE, "nna_submodule", params, "nna_bench", {"runs": runs}, fails=True)
    assert "the cycle model's MAC array" in xml and "first descriptor" in xml
