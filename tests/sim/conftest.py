"""Shared fixtures of the cycle-model tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stereosim.quant.artifact import QuantizedModel, save_quantized
from stereosim.quant.intconv import network
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.readable.chip import build_chip, run_readable


def random_network(shapes, seed):
    """A checked network of layers (K, C_in, C_out) with weights and requantisation that keep
    the activations spread over 0..127."""
    rng = np.random.default_rng(seed)
    weights, biases, mult, shift = [], [], [], []
    for i, (k, c_in, c_out) in enumerate(shapes):
        weights.append(rng.integers(-20, 21, (c_out, c_in, k, k)).astype(np.int8))
        biases.append(rng.integers(-500, 500, c_out).astype(np.int32))
        if i < len(shapes) - 1:
            mult.append(rng.integers(1, 256, c_out).astype(np.int32))
            shift.append(np.full(c_out, 10 + (i > 0) * 2, np.int32))
    return network(tuple(weights), tuple(biases), tuple(mult), tuple(shift), 128)


def network_artifact(path, net):
    """Write ``net`` as a quantised artifact (the scales are placeholders: the NNA reads only
    the integer network); returns its path."""
    n = net.n_layers
    save_quantized(path, QuantizedModel(
        weights=net.weights, biases=net.biases, mult=net.mult, shift=net.shift,
        input_offset=net.input_offset, input_scale=1.0, z_bits=net.z_bits,
        weight_scales=tuple(np.ones(w.shape[0]) for w in net.weights),
        act_scales=np.ones(n), distances=("rms",) * n, sign_agreement=1.0, acc_rms=0.0))
    return str(path)


def write_lent_toml(path, layers, width=16, height=16, channels=1, fps="max"):
    """Write a lent network file (nna.lent_network) of ``layers`` (K, C_in, C_out, stride)
    tuples; returns its path."""
    fps_text = '"max"' if fps == "max" else repr(float(fps))
    text = [f"fps = {fps_text}", "[input]", f"width = {width}", f"height = {height}",
            f"channels = {channels}"]
    for k, c_in, c_out, s in layers:
        text += ["[[layer]]", f"kernel = {k}", f"channels_in = {c_in}",
                 f"channels_out = {c_out}", f"stride = {s}"]
    Path(path).write_text("\n".join(text) + "\n")
    return str(path)


@pytest.fixture(scope="session")
def lent_toml():
    """:func:`write_lent_toml`: write a lent network file."""
    return write_lent_toml


@pytest.fixture(scope="session")
def network_file(tmp_path_factory):
    """A function (layer shapes ((K, C_in, C_out), ...), seed) -> (path of a quantised artifact
    of that random network, the network), written once per session."""
    root = tmp_path_factory.mktemp("networks")
    made = {}

    def make(shapes, seed=0):
        key = (tuple(map(tuple, shapes)), seed)
        if key not in made:
            net = random_network(key[0], seed)
            made[key] = (network_artifact(root / f"net{len(made)}.int8.npz", net), net)
        return made[key]

    return make


@pytest.fixture
def engines_agree():
    """A function running a plan on the readable kernel and the compiled engine and asserting
    they agree: statistics, report, frame instants, the frames completed and every frame's
    words. Returns the readable run and its [(frame, words)]."""

    def check(plan, left, right, **kw):
        got = {"slow": [], "fast": []}
        slow = run_readable(plan, left, right,
                            on_frame=lambda f, w: got["slow"].append((f, w.copy())), **kw)
        fast = run_compiled(plan, left, right,
                            on_frame=lambda f, w: got["fast"].append((f, w.copy())), **kw)
        assert slow.stats == fast.stats and slow.report == fast.report
        np.testing.assert_array_equal(slow.frame_times, fast.frame_times)
        assert [f for f, _ in got["slow"]] == [f for f, _ in got["fast"]]
        for (_, a), (_, b) in zip(got["slow"], got["fast"]):
            np.testing.assert_array_equal(a, b)
        return slow, got["slow"]

    return check


def _run_cycle(left, right, cfg, *, order_seed=None, sink_stall=None, trace=None,
               on_frame=None):
    """One frame (or a stream: see ``build_chip``) of ``cfg`` (or a plan) on the readable
    kernel: (the last frame's output words (H, W) int32, cycle report, the chip -- its blocks,
    FIFOs and simulator, for tests that look inside)."""
    chip = build_chip(left, right, cfg, order_seed=order_seed, sink_stall=sink_stall,
                      trace=trace, on_frame=on_frame)
    _, report = chip.run()
    return chip.sink.words.copy(), report, chip


@pytest.fixture(scope="session")
def run_cycle():
    """The readable kernel's run with its chip: ``run_cycle(left, right, cfg, *, order_seed,
    sink_stall, trace, on_frame) -> (words, report, chip)``."""
    return _run_cycle
