"""The NNA runs any network the quantiser produces (nna.cnn.weights): the shipped mccnn4 and
mccnn4-slim artifacts load, their descriptors are the signs of quant.int_forward_ref's last layer,
and the cycle model's disparities equal the functional model's bit for bit."""

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from stereosim.core.config import load_config
from stereosim.core.datasets import find_scene, load_scene, shared_data_dir
from stereosim.core.errors import ConfigError
from stereosim.core.io import to_grey
from stereosim.nna import descriptor as descriptor_module
from stereosim.nna.descriptor import compute_descriptor, descriptor_bits, resolve_nna
from stereosim.nna.geometry import half_window, macs_per_descriptor, window_rows
from stereosim.nna.submodule.timing import cycles_per_descriptor, layer_cycles
from stereosim.nna.training.trainconfig import VARIANTS
from stereosim.quant.artifact import load_quantized
from stereosim.quant.intconv import int_forward, int_forward_ref, signs_ref
from stereosim.sim.api import run
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.spec import resolve_chip

MODELS = Path(__file__).resolve().parents[2] / "benchmarks" / "models"
NETWORKS = ("mccnn4", "mccnn4-slim", "mccnn4-mid", "mixed5x5-wide", "mixed5x5-wide-n6")
DATA = shared_data_dir()


def _cfg(name: str, **over):
    return load_config(overrides={"nna.descriptor": "cnn",
                                  "nna.cnn.weights": str(MODELS / f"{name}.int8.npz"), **over})


def _pair(h, w, seed, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift)).astype(np.float64)
    base = (base + np.roll(base, 1, 0) + np.roll(base, 1, 1)) / 3
    base = base.astype(np.uint8)
    return np.ascontiguousarray(base[:, shift:]), np.ascontiguousarray(base[:, :w])


@pytest.mark.parametrize("name", NETWORKS)
def test_the_artifact_is_the_network_the_nna_runs(name):
    """Its layers, reach (the sum of the half kernels: 4 for four 3x3 layers or a 5x5 and two
    3x3, like 9x9) and MACs per descriptor (sum of K*K*C_in*C_out) as the geometry reports
    them."""
    qm = load_quantized(MODELS / f"{name}.int8.npz")
    spec = resolve_nna(_cfg(name).nna)
    cnn = spec.cnn
    assert cnn.n_layers == qm.n_layers == len(VARIANTS[qm.variant])
    assert [w.shape for w in qm.weights] == [(o, i, k, k) for i, o, k in VARIANTS[qm.variant]]
    assert half_window(spec) == cnn.reach == sum(w.shape[2] // 2 for w in qm.weights) == 4
    assert window_rows(spec) == 9
    macs = sum(int(np.prod(w.shape)) for w in qm.weights)
    assert macs_per_descriptor(spec) == macs
    assert cycles_per_descriptor(spec) == max(layer_cycles(spec)) >= -(-macs // spec.cfg.macs)
    assert descriptor_bits(spec) == qm.weights[-1].shape[0] == 32 == spec.bits


@pytest.mark.parametrize("name", NETWORKS)
@pytest.mark.parametrize("shape", [(1, 1), (7, 5), (23, 41)])
def test_descriptors_are_the_signs_of_the_integer_network(name, shape):
    qm = load_quantized(MODELS / f"{name}.int8.npz")
    img = np.random.default_rng(shape[0]).integers(0, 256, shape, dtype=np.uint8)
    args = (qm.weights, qm.biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    ref = int_forward_ref(img, *args)
    assert_array_equal(int_forward(img, *args), ref)
    assert_array_equal(compute_descriptor(img, _cfg(name).nna), signs_ref(ref))
    assert_array_equal(compute_descriptor(img, resolve_nna(_cfg(name).nna)), signs_ref(ref))


@pytest.mark.parametrize("name", NETWORKS)
@pytest.mark.parametrize("over", [{}, {"nna.stereo_submodules": 4},
                                  {"nna.stereo_submodules": 4, "nna.split": "rows"}])
def test_cycle_model_equals_the_functional_model(name, over):
    """Cycle and functional disparities equal bit for bit, whole frames and split ones."""
    left, right = _pair(21, 47, seed=len(over))
    cfg = _cfg(name, **{"sva.disparities": 16, **over})
    cycle = run(left, right, mode="cycle", config=cfg)
    functional = run(left, right, mode="functional", config=cfg)
    assert_array_equal(cycle.disparity_fixed, functional.disparity_fixed)
    assert cycle.report["throughput"]["bottleneck"].startswith("nna")


def test_a_network_with_other_descriptor_bits_names_the_key_to_set():
    with pytest.raises(ConfigError, match="nna.cnn.channels = 32"):
        resolve_nna(_cfg("mccnn4", **{"nna.cnn.channels": 16}).nna)


def test_the_network_is_read_once_and_handed_down_in_the_plan(monkeypatch):
    """Resolving the chip reads the weight file once; the plan built from that spec keeps it
    (its layers, buffers and figures read the spec's network) and reads nothing again."""
    reads = []
    read = descriptor_module._read_cnn
    monkeypatch.setattr(descriptor_module, "_read_cnn", lambda weights: (
        reads.append(weights), read(weights))[1])
    cfg = _cfg("mccnn4", **{"sva.disparities": 16, "nna.stereo_submodules": 4})
    chip = resolve_chip(cfg)
    assert reads == [cfg.nna.cnn.weights]
    plan = build_plan(chip, (21, 47))
    assert reads == [cfg.nna.cnn.weights] and plan.spec is chip and plan.cfg == cfg
    assert plan.descriptor_parts == chip.nna.parts == (("cnn", 32),)
    assert [lay.channels_out for lay in plan.block("nna_left0").layers] == [
        int(w.shape[0]) for w in chip.nna.cnn.weights]


@pytest.mark.skipif(DATA is None, reason="shared Middlebury data not found (../shared/data)")
@pytest.mark.parametrize("name", NETWORKS)
def test_middlebury_descriptors_equal_the_definition(name):
    """On a real scene (MiddEval3 trainingQ Motorcycle, both views): the chip's descriptors are
    the signs of the int64 definition."""
    scene = load_scene(find_scene(DATA / "middlebury2014_trainingQ" / "Motorcycle"))
    qm = load_quantized(MODELS / f"{name}.int8.npz")
    args = (qm.weights, qm.biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    for view in ("left", "right"):
        img = to_grey(scene[view])
        assert_array_equal(compute_descriptor(img, _cfg(name).nna),
                           signs_ref(int_forward_ref(img, *args)))
