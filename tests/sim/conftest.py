"""Fixtures of the cycle model's and the application's tests (tests/sim and below); the
suite-wide ones (``lent_toml``, ``run_cycle``) are in tests/conftest.py."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.quant.artifact import QuantizedModel, save_quantized
from stereosim.quant.intconv import network
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.readable.chip import run_readable


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
