"""A network and its back end together: a weight file carries the SVA back end it was tuned
with (core.config.backend), the configuration takes it for the keys it leaves unset, a file
without one keeps the descriptor's with a note, and the report and summary name the network
and the back end it runs with."""

import shutil

import numpy as np
import pytest

from stereosim.core.config import DESCRIPTOR_DEFAULTS, load_config
from stereosim.core.config.backend import BACKEND_KEYS, carried_backend, write_backend
from stereosim.core.errors import ConfigError
from stereosim.core.npz import open_npz
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS
from stereosim.sim.api import run
from stereosim.sim.cli import PRESETS, main
from stereosim.sim.summary import summary_text

ROBUST = load_config(PRESETS / "robust-720p.toml").nna.cnn.weights
TUNED = {"p1": 96, "p2": 900, "p2_adaptive": False, "p2_slope": 128, "box_size": 5}
SMALL = {"sva.disparities": 16, "nna.descriptor": "cnn"}


def _pair(h=24, w=64, shift=3, seed=5):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, shift:].copy(), base[:, :w].copy()


@pytest.fixture
def bare(tmp_path):
    """A copy of the shipped network whose back end is taken out (as in a file written before
    files carried one)."""
    path = tmp_path / "bare.npz"
    arrays = {k: v for k, v in open_npz(SHIPPED_WEIGHTS, "weight file", "").items()
              if k != "backend"}
    np.savez(path, **arrays)
    return path


def test_a_file_carries_its_back_end_and_keeps_every_other_member(bare):
    before = dict(open_npz(str(bare), "weight file", ""))
    assert carried_backend(bare) is None
    write_backend(bare, TUNED)
    assert carried_backend(bare) == TUNED
    after = dict(open_npz(str(bare), "weight file", ""))
    assert set(after) == set(before) | {"backend"}
    for key, value in before.items():
        np.testing.assert_array_equal(after[key], value)


def test_the_unset_keys_take_the_files_back_end_and_a_set_key_wins(bare):
    write_backend(bare, TUNED)
    cfg = load_config(overrides={**SMALL, "nna.cnn.weights": str(bare)})
    assert {k: getattr(cfg.sva, k) for k in BACKEND_KEYS} == TUNED
    cfg = load_config(overrides={**SMALL, "nna.cnn.weights": str(bare), "sva.p1": 7})
    assert cfg.sva.p1 == 7 and cfg.sva.p2 == TUNED["p2"]
    # the register widths follow the file's box and P2, not the descriptor's
    wide = load_config(overrides={**SMALL, **{f"sva.{k}": v for k, v in TUNED.items()}})
    assert (cfg.sva.cost_bits, cfg.sva.path_bits) == (wide.sva.cost_bits, wide.sva.path_bits)


def test_swapping_to_the_robust_network_brings_its_back_end_as_the_preset_has_it():
    """Issue 46, item 4: --set nna.cnn.weights=<robust> alone runs with the robust preset's
    back end, not the single layer's."""
    swapped = load_config(overrides={"nna.cnn.weights": ROBUST})
    preset = load_config(PRESETS / "robust-720p.toml")
    assert {k: getattr(swapped.sva, k) for k in BACKEND_KEYS} == {
        k: getattr(preset.sva, k) for k in BACKEND_KEYS}
    assert swapped.sva.p1 != DESCRIPTOR_DEFAULTS["cnn"]["p1"]


def test_a_file_without_a_back_end_keeps_the_descriptors_and_says_so_once(bare, capsys):
    assert main(["config", "show", "--set", f"nna.cnn.weights={bare}"]) == 0
    err = capsys.readouterr().err
    (line,) = err.splitlines()
    assert line.startswith("stereosim: note: the network bare.npz carries no tuned back end")
    assert f"P1 {DESCRIPTOR_DEFAULTS['cnn']['p1']}" in line
    # no note when the user sets the back end, or the file carries one
    assert main(["config", "show", "--set", f"nna.cnn.weights={bare}", "--set", "sva.p1=9"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["config", "show", "--set", f"nna.cnn.weights={ROBUST}"]) == 0
    assert capsys.readouterr().err == ""


def test_config_backend_shows_and_stores_a_back_end(bare, capsys):
    assert main(["config", "backend", str(bare)]) == 0
    assert "carries no back end" in capsys.readouterr().out
    assert main(["config", "backend", str(bare), "--set", "sva.p1=120", "--set",
                 "sva.p2_adaptive=false"]) == 0
    assert carried_backend(bare) == {**DESCRIPTOR_DEFAULTS["cnn"], "p1": 120,
                                     "p2_adaptive": False}
    capsys.readouterr()
    before = bare.read_bytes()
    for bad in ("sva.median=3", "sva.p1=-1", "sva.p2=abc"):
        assert main(["config", "backend", str(bare), "--set", bad]) == 2
        assert capsys.readouterr().err.count("\n") == 1
    assert bare.read_bytes() == before  # a refused back end leaves the file as it was


def test_a_damaged_back_end_is_one_line_naming_the_file(tmp_path):
    path = tmp_path / "w.npz"
    arrays = dict(open_npz(SHIPPED_WEIGHTS, "weight file", ""))
    for text in ("p1 = [", "median = 3", "p1 = 1.5"):
        np.savez(path, **{**arrays, "backend": np.array(text)})
        with pytest.raises(ConfigError, match="w.npz"):
            load_config(overrides={"nna.cnn.weights": str(path)})


def test_the_summary_names_the_network_and_the_back_end_it_runs_with(tmp_path):
    robust = tmp_path / "robust.int8.npz"
    shutil.copy(ROBUST, robust)
    rep = run(*_pair(), mode="cycle", overrides={**SMALL, "nna.cnn.weights": str(robust),
                                                 "sva.p2": 1100}).report
    d = rep["descriptor"]
    assert d["network"]["name"] == "robust.int8"
    assert d["network"]["layers"] == ["5x5x1x32", "3x3x32x32", "3x3x32x32"]
    assert d["network"]["macs_per_pixel"] == 5 * 5 * 32 + 2 * 9 * 32 * 32
    assert d["backend"]["tuned_with"] == "the network's weight file"
    assert d["backend"]["changed"] == ["p2"] and d["backend"]["p2"] == 1100
    text = " ".join(summary_text(rep, 1.0, terminal=False).split())  # rows wrap at 100
    assert "cnn: robust.int8 (3 layers 5x5x1x32, 3x3x32x32, 3x3x32x32; 19,232 MACs a" in text
    carried = carried_backend(robust)
    assert (f"SVA back end P1 {carried['p1']}, P2 1100 (adaptive, slope "
            f"{carried['p2_slope']}), box {carried['box_size']}: the network's weight file, "
            "but for p2 (set by the configuration)") in text
    default = run(*_pair(), mode="functional", overrides=SMALL).report["descriptor"]
    assert default["network"]["name"] == "single9x9"
    assert default["backend"]["tuned_with"] == "the cnn descriptor's defaults"


def test_a_damaged_back_end_says_how_to_replace_it_and_config_backend_does(tmp_path, capsys):
    path = tmp_path / "w.npz"
    arrays = dict(open_npz(SHIPPED_WEIGHTS, "weight file", ""))
    np.savez(path, **{**arrays, "backend": np.arange(3)})
    assert main(["config", "backend", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "stereosim config backend FILE --set" in err
    assert main(["config", "backend", str(path), "--set", "sva.p1=99"]) == 0
    assert carried_backend(path) == {**DESCRIPTOR_DEFAULTS["cnn"], "p1": 99}
    np.testing.assert_array_equal(open_npz(str(path), "weight file", "")["weights"],
                                  arrays["weights"])
