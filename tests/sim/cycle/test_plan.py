"""The chip plan: what it refuses, what it sizes, and what follows from one plan (every engine
and the estimate refuse the same chips, the merge FIFO's own key, the tile's line-buffer SRAM,
both cameras named when they overflow together, one dispatcher)."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import encode_png
from stereosim.sim.api import run
from stereosim.sim.cli import main
from stereosim.sim.cycle.contract import CameraOverflow
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.figures import chip_sram, sram_bits
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.simulate import simulate
from stereosim.sva.pipeline.pipeline import SvaStream

SMALL = {"sva.disparities": 16}


def _pair(h=21, w=57, shift=3, seed=2):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, shift:].copy(), base[:, :w].copy()


# ---- a line buffer smaller than the window: refused by everything, at configuration time -----


SHORT = {**SMALL, "nna.descriptor": "cnn", "nna.line_buffer_rows": 8}
WANT = "nna.line_buffer_rows=8 cannot hold the 9-row descriptor window: use at least 9"


@pytest.mark.parametrize("mode, engine", [("functional", "auto"), ("cycle", "auto"),
                                          ("cycle", "fast"), ("cycle", "readable")])
def test_short_line_buffer_is_refused_by_every_mode_and_engine(mode, engine):
    left, right = _pair()
    with pytest.raises(ConfigError) as err:
        run(left, right, mode=mode, overrides={**SHORT, "sim.engine": engine})
    assert str(err.value) == WANT


def test_short_line_buffer_is_refused_by_the_estimate(capsys):
    with pytest.raises(ConfigError) as err:
        estimate(load_config(overrides=SHORT), (21, 57))
    assert str(err.value) == WANT
    code = main(["estimate", "--size", "57x21", "--set", "nna.descriptor=cnn",
                 "--set", "nna.line_buffer_rows=8", "--disparities", "16"])
    _, stderr = capsys.readouterr()
    assert code == 2
    assert stderr.strip() == f"stereosim: error: {WANT}"


def test_d_not_below_the_width_is_one_rule_with_one_line(capsys):
    """The plan, the estimate's command and the SVA's own entry point refuse D >= W with the
    same line (sva.geometry.check_disparity_range)."""
    want = ("sva.disparities=64 is not smaller than the image width 57: use a smaller disparity "
            "range (--disparities) or a wider image")
    cfg = load_config(overrides={"sva.disparities": 64})
    with pytest.raises(ConfigError) as err:
        build_plan(cfg, (21, 57))
    assert str(err.value) == want
    assert main(["estimate", "--size", "57x21", "--disparities", "64"]) == 2
    assert capsys.readouterr().err.strip() == f"stereosim: error: {want}"
    desc = np.zeros((21, 57), np.uint32)
    with pytest.raises(InputError) as err:
        SvaStream(desc, desc, np.zeros((21, 57), np.uint8), cfg.sva, 32)
    assert str(err.value) == want


def test_a_line_buffer_of_exactly_the_window_is_built():
    plan = build_plan(load_config(overrides={**SHORT, "nna.line_buffer_rows": 9}), (21, 57))
    assert {b.rows for b in plan.blocks_of("nna")} == {9}


# ---- sizes the plan derives ----------------------------------------------------------------


def test_the_merge_fifos_have_their_own_key():
    cfg = load_config(overrides={**SMALL, "nna.stereo_submodules": 4,
                                 "fifo.nna_to_sva_depth": 5, "fifo.nna_to_merge_depth": 3})
    plan = build_plan(cfg, (30, 80))
    merge_in = [f for f in plan.fifos if plan.block(f.consumer).kind == "merge"]
    to_sva = [f for f in plan.fifos if plan.block(f.consumer).kind == "sva"]
    assert len(merge_in) == 2 * plan.parts == 4 and len(to_sva) == 2
    assert {(f.key, f.depth) for f in merge_in} == {("fifo.nna_to_merge_depth", 3)}
    assert {(f.key, f.depth) for f in to_sva} == {("fifo.nna_to_sva_depth", 5)}


@pytest.mark.parametrize("split", ["columns", "rows"])
def test_a_tile_line_buffer_is_sized_for_the_widest_tile_input(split):
    shape = (40, 120)
    cfg = load_config(overrides={**SMALL, "nna.stereo_submodules": 4, "nna.split": split})
    plan = build_plan(cfg, shape)
    rows = cfg.nna.line_buffer_rows
    widest = max(t.in_shape[1] for t in plan.tiles)
    assert sram_bits(plan)["nna.line_buffer"] == rows * widest * 8
    for b in plan.blocks_of("nna"):
        (buf,) = [x for x in b.buffers if x.name == "nna.line_buffer"]
        assert buf.bits == rows * b.tile.in_shape[1] * 8
    if split == "columns":
        assert widest < shape[1]  # a column tile does not hold whole frame rows
    whole = build_plan(load_config(overrides=SMALL), shape)
    assert sram_bits(whole)["nna.line_buffer"] == rows * shape[1] * 8


@pytest.mark.parametrize("descriptor, stereo", [("cnn", 2), ("cnn", 6), ("census", 4)])
def test_the_chip_sram_counts_every_submodule_once_and_every_buffer_and_fifo(descriptor, stereo):
    """The chip total: each of the NNA's submodules (stereo, lent or idle) holds the widest
    tile's buffers, plus the SVA's buffers and every FIFO's depth x width, summed by hand from
    the plan's blocks here."""
    shape = (40, 120)
    cfg = load_config(overrides={**SMALL, "nna.descriptor": descriptor,
                                 "nna.stereo_submodules": stereo})
    plan = build_plan(cfg, shape)
    per_sub = max(sum(b.bits for b in blk.buffers) for blk in plan.blocks_of("nna"))
    sva = sum(b.bits for b in plan.block("sva").buffers)
    fifos = sum(f.depth * f.width_bits for f in plan.fifos)
    got = chip_sram(plan)
    assert got["nna_per_submodule"] == per_sub
    assert got["total"] == cfg.nna.submodules * per_sub + sva + fifos
    assert sum(got["by_kind"].values()) == got["total"] == sum(got["by_block"].values())
    assert got["by_block"]["nna_stereo"] == stereo * per_sub
    assert got["by_block"]["nna_idle"] == (cfg.nna.submodules - stereo) * per_sub


# ---- both cameras overflowing in one cycle ----------------------------------------------------


FAST_CAMERA = {**SMALL, "source.kind": "camera", "clocks.camera_mhz": 1000,
               "nna.descriptor": "cnn", "fifo.source_to_nna_depth": 2}


@pytest.mark.parametrize("engine", ["fast", "readable"])
def test_both_cameras_are_named_when_they_overflow_in_the_same_cycle(engine):
    left, right = _pair()
    with pytest.raises(CameraOverflow) as err:
        run(left, right, mode="cycle", overrides={**FAST_CAMERA, "sim.engine": engine})
    msg = str(err.value)
    assert "\n" not in msg
    first, second = msg.index("camera 'camera_left'"), msg.index("camera 'camera_right'")
    assert first < second  # in the plan's order, not the order blocks happened to run
    assert msg.count("overflowed FIFO") == 2


def test_the_overflow_message_does_not_depend_on_evaluation_order():
    left, right = _pair()
    plan = build_plan(load_config(overrides={**FAST_CAMERA, "sim.engine": "readable"}),
                      left.shape)
    messages = set()
    for seed in range(4):
        with pytest.raises(CameraOverflow) as err:
            simulate(plan, left, right, order_seed=seed)
        messages.add(str(err.value))
    assert len(messages) == 1


# ---- one dispatcher ---------------------------------------------------------------------------


def test_auto_runs_the_readable_kernel_only_when_asked_for_what_it_alone_does():
    left, right = _pair()
    plan = build_plan(load_config(overrides=SMALL), left.shape)
    fast = simulate(plan, left, right)
    assert fast.report["engine"] == "fast" and "engine_reason" not in fast.report
    slow = simulate(plan, left, right, order_seed=3)
    assert slow.report["engine"] == "readable"
    assert "order_seed" in slow.report["engine_reason"]
    assert np.array_equal(fast.words, slow.words)
    stalled = simulate(plan, left, right, sink_stall=lambda c: c % 3 != 0)
    assert stalled.report["engine"] == "readable"
    assert "sink stall given as a function" in stalled.report["engine_reason"]


def test_engine_fast_refuses_what_only_the_readable_kernel_does():
    left, right = _pair()
    plan = build_plan(load_config(overrides={**SMALL, "sim.engine": "fast"}), left.shape)
    with pytest.raises(ConfigError, match="sim.engine=fast: a shuffled evaluation order"):
        simulate(plan, left, right, order_seed=1)
    with pytest.raises(ConfigError, match="sim.engine=fast: a sink stall given as a function"):
        simulate(plan, left, right, sink_stall=lambda c: False)


@pytest.mark.parametrize("name", ["schedule", "steps", "compiled", "numba"])
def test_engine_names_that_alias_are_unknown(name):
    with pytest.raises(ConfigError, match="sim.engine"):
        load_config(overrides={"sim.engine": name})


# ---- traces of a split frame from the command line --------------------------------------------


def test_a_split_frame_is_traced_from_the_command_line(tmp_path, capsys):
    left, right = _pair(h=24, w=64)
    paths = []
    for name, img in (("l.png", left), ("r.png", right)):
        (tmp_path / name).write_bytes(encode_png(img))
        paths.append(str(tmp_path / name))
    vcd = tmp_path / "split.vcd"
    code = main(["run", "--left", paths[0], "--right", paths[1], "--disparities", "16",
                 "--mode", "cycle", "--set", "nna.stereo_submodules=4", "--vcd", str(vcd),
                 "--out", str(tmp_path / "out")])
    _, stderr = capsys.readouterr()
    assert code == 0, stderr
    text = vcd.read_text()
    plan = build_plan(load_config(overrides={**SMALL, "nna.stereo_submodules": 4}), left.shape)
    assert plan.parts == 2
    for b in plan.blocks:  # every block of the split chip has its scope in the VCD
        assert f"$scope module {b.scope.split('.')[-1]} $end" in text
    assert text.count("$scope module sub1 $end") == 2  # a second submodule per camera
    merge = [f.name for f in plan.fifos if plan.block(f.consumer).kind == "merge"]
    assert len(merge) == 4 and all(f"$scope module {name} $end" in text for name in merge)
