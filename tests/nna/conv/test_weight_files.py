"""A weight file is what it holds now: every layer of a multi-layer artifact fits the NNA (its
kernel at most 63 x 63, as a one-layer file's), and the network ``nna.cnn.weights`` names is
read again when the file behind the path changed -- rewritten, replaced, deleted, or another
file under the same relative path after a change of working directory."""

from __future__ import annotations

import os
import shutil
import time

import numpy as np
import pytest

from stereosim.core.errors import ConfigError
from stereosim.core.io import encode_png
from stereosim.nna.conv.conv import MAX_KERNEL_SIZE
from stereosim.nna.conv.weights import load_network
from stereosim.quant.artifact import QuantizedModel, save_quantized
from stereosim.sim.api import run
from stereosim.sim.cli import main

SMALL = ((3, 1, 8), (3, 8, 32))  # (K, C_in, C_out) of each layer: a 3x3 pair, 32 bits


def _artifact(path, shapes, seed=0):
    """Write a quantised artifact of random layers ``shapes`` ((K, C_in, C_out), ...) with small
    weights (every accumulator far inside int32); returns its path as text."""
    rng = np.random.default_rng(seed)
    weights, biases, mult, shift = [], [], [], []
    for i, (k, c_in, c_out) in enumerate(shapes):
        weights.append(rng.integers(-3, 4, (c_out, c_in, k, k)).astype(np.int8))
        biases.append(rng.integers(-50, 50, c_out).astype(np.int32))
        if i < len(shapes) - 1:
            mult.append(rng.integers(1, 256, c_out).astype(np.int32))
            shift.append(np.full(c_out, 10, np.int32))
    n = len(shapes)
    save_quantized(path, QuantizedModel(
        weights=tuple(weights), biases=tuple(biases), mult=tuple(mult), shift=tuple(shift),
        input_offset=128, input_scale=1.0, z_bits=8,
        weight_scales=tuple(np.ones(w.shape[0]) for w in weights), act_scales=np.ones(n),
        distances=("rms",) * n, sign_agreement=1.0, acc_rms=0.0))
    return str(path)


def _pair(h=24, w=40, shift=3, seed=5):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift)).astype(np.float64)
    base = ((base + np.roll(base, 1, 0) + np.roll(base, 1, 1)) / 3).astype(np.uint8)
    return np.ascontiguousarray(base[:, shift:]), np.ascontiguousarray(base[:, :w])


def _disparity(weights: str) -> np.ndarray:
    left, right = _pair()
    return run(left, right, mode="functional",
               overrides={"nna.descriptor": "cnn", "nna.cnn.weights": weights,
                          "sva.disparities": 16}).disparity_fixed


def _settle(path):
    """Date ``path`` 10 s back, as a file written a while ago (one the reader may keep)."""
    past = time.time_ns() - 10_000_000_000
    os.utime(path, ns=(past, past))


# ---- every layer's kernel fits the line buffer ---------------------------------------------

@pytest.mark.parametrize("shapes, layer", [
    (((3, 1, 4), (65, 4, 32)), 1),
    (((3, 1, 4), (3, 4, 4), (67, 4, 32)), 2),
])
def test_a_kernel_over_63_in_any_layer_is_refused(tmp_path, shapes, layer):
    path = _artifact(tmp_path / "wide.npz", shapes)
    k = shapes[layer][0]
    with pytest.raises(ConfigError, match=f"layer {layer}'s kernel size {k}x{k} is larger than "
                                          f"the {MAX_KERNEL_SIZE}x{MAX_KERNEL_SIZE} window"):
        load_network(path)


def test_a_63_wide_kernel_after_layer_0_is_taken(tmp_path):
    path = _artifact(tmp_path / "k63.npz", ((3, 1, 4), (MAX_KERNEL_SIZE, 4, 32)))
    assert load_network(path).weights[1].shape[2:] == (MAX_KERNEL_SIZE, MAX_KERNEL_SIZE)


def test_the_run_command_refuses_a_second_layer_of_65_in_one_line(tmp_path, capfd):
    _artifact(tmp_path / "k65.npz", ((3, 1, 4), (65, 4, 32)))
    left, right = _pair()
    (tmp_path / "l.png").write_bytes(encode_png(left))
    (tmp_path / "r.png").write_bytes(encode_png(right))
    out = tmp_path / "out"
    code = main(["run", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
                 "--set", "nna.descriptor=cnn", "--set", f"nna.cnn.weights={tmp_path / 'k65.npz'}",
                 "--set", "sva.disparities=16", "--out", str(out)])
    err = capfd.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("stereosim: compiling")]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("stereosim: error: weight file "), err
    assert "layer 1's kernel size 65x65" in lines[0]
    assert not out.exists()


# ---- the file behind the path, at the time of the call -------------------------------------

@pytest.fixture(scope="module")
def networks(tmp_path_factory):
    """Two artifacts of the same shapes and different weights, at paths never reused, and the
    disparities of the tiny pair under each (which differ: the tests need that)."""
    root = tmp_path_factory.mktemp("networks")
    a, b = _artifact(root / "a.npz", SMALL, seed=1), _artifact(root / "b.npz", SMALL, seed=2)
    want = {"a": _disparity(a), "b": _disparity(b)}
    assert not np.array_equal(want["a"], want["b"])
    return {"a": a, "b": b, "want": want}


@pytest.mark.parametrize("how", ["replaced", "in place"])
def test_a_rewritten_file_is_read_again(tmp_path, networks, how):
    """Replaced (a new inode, as save_quantized writes) or written over in place (the same inode;
    same size, since the shapes are the same)."""
    path = tmp_path / "net.npz"
    shutil.copyfile(networks["a"], path)
    _settle(path)
    assert np.array_equal(_disparity(str(path)), networks["want"]["a"])
    if how == "replaced":
        _artifact(path, SMALL, seed=2)
    else:
        with open(path, "r+b") as f:
            f.write(open(networks["b"], "rb").read())
    assert np.array_equal(_disparity(str(path)), networks["want"]["b"])


def test_a_rewrite_within_the_timestamp_tick_is_read_again(tmp_path, networks):
    """A file rewritten in place with the same size and the same mtime (two writes within one
    tick of the file system's clock) still gives the new network: a file modified just before
    it was read is not kept."""
    path = tmp_path / "net.npz"
    shutil.copyfile(networks["a"], path)
    stamp = time.time_ns()
    os.utime(path, ns=(stamp, stamp))
    assert np.array_equal(_disparity(str(path)), networks["want"]["a"])
    with open(path, "r+b") as f:
        f.write(open(networks["b"], "rb").read())
    os.utime(path, ns=(stamp, stamp))
    assert np.array_equal(_disparity(str(path)), networks["want"]["b"])


def test_a_deleted_file_is_not_found(tmp_path, networks):
    path = tmp_path / "net.npz"
    shutil.copyfile(networks["a"], path)
    _settle(path)
    assert np.array_equal(_disparity(str(path)), networks["want"]["a"])
    path.unlink()
    with pytest.raises(ConfigError, match="not found"):
        _disparity(str(path))


def test_a_relative_path_is_read_from_the_working_directory_of_the_call(
        tmp_path, networks, monkeypatch):
    for name in "ab":
        (tmp_path / name).mkdir()
        shutil.copyfile(networks[name], tmp_path / name / "net.npz")
        _settle(tmp_path / name / "net.npz")
    for name in "abab":
        monkeypatch.chdir(tmp_path / name)
        assert np.array_equal(_disparity("net.npz"), networks["want"][name])


def test_the_reports_all_submodules_rate_follows_a_rewritten_file(tmp_path):
    """architecture.nna_submodules.with_all (a second plan, kept per configuration) is worked
    out again for a file rewritten with heavier layers, not served from the first file's."""
    path = _artifact(tmp_path / "w.npz", SMALL)
    _settle(path)

    def with_all():
        return run(*_pair(), mode="functional", overrides={
            "nna.descriptor": "cnn", "nna.cnn.weights": path, "sva.disparities": 16}
        ).report["architecture"]["nna_submodules"]["with_all"]["nna_fps"]

    light = with_all()
    _artifact(tmp_path / "w.npz", ((9, 1, 8), (9, 8, 32)))
    _settle(path)
    assert with_all() < light / 10  # 81x the MACs of each layer


def test_a_later_layers_line_buffer_over_64_rows_is_refused(tmp_path):
    """Layer 1's buffer holds its window and layer 0's slack: a 3x3 then a 63x63 layer with
    nna.line_buffer_rows = 64 would need 63 + 61 = 124 rows; 10 rows of layer 0 leave it 70, also
    too many; 4 rows leave it 64, which is taken."""
    from stereosim.core.config import load_config
    from stereosim.sim.cycle.plan import build_plan

    path = _artifact(tmp_path / "w.npz", ((3, 1, 4), (63, 4, 32)))
    for rows, need in ((64, 124), (10, 70)):
        cfg = load_config(overrides={"nna.descriptor": "cnn", "nna.cnn.weights": path,
                                     "nna.line_buffer_rows": rows, "sva.disparities": 16})
        with pytest.raises(ConfigError, match=f"layer 1's line buffer would need {need} rows"):
            build_plan(cfg, (80, 96))
    cfg = load_config(overrides={"nna.descriptor": "cnn", "nna.cnn.weights": path,
                                 "nna.line_buffer_rows": 4, "sva.disparities": 16})
    build_plan(cfg, (80, 96))
