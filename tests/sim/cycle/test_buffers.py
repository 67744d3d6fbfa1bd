"""Row windows with real capacity (sim/cycle/buffers.py): both engines track how many rows the
NNA line buffers and the SVA's descriptor rows hold, report the peak beside the capacity, and
refuse a run that overflows one. The mutants below break a room rule or shrink a buffer; each
must stop the run with an error naming the buffer (bit-exactness alone cannot see them: the
words come from the functional kernels)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import stereosim.sim.cycle.readable.blocks.nna as nna_block
import stereosim.sim.cycle.readable.blocks.sva as sva_block
from stereosim.core.config import load_config
from stereosim.sim.cycle.buffers import BufferOverflow, window_peaks
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable

CNN = {"nna.descriptor": "cnn", "sva.disparities": 16}  # the NNA (9 cycles) is the bottleneck
# the SVA (II 2) is the bottleneck; the 5x5 box pinned for the k + 2 = 7 rows derived below
CENSUS = {"nna.descriptor": "census", "sva.disparities": 16, "sva.box_size": 5}


def _pair(h, w, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + 3), dtype=np.uint8)
    return base[:, 3:].copy(), base[:, :w].copy()


def _plan(over, shape=(16, 40)):
    return build_plan(load_config(overrides=over), shape)


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_windows_fill_to_their_capacity_and_no_further(run):
    left, right = _pair(16, 40)
    rep = run(_plan(CNN), left, right).report["buffers"]
    # the NNA is slow: its line buffer fills to its 10 rows and the source waits
    assert rep["nna_left"]["nna.line_buffer"] == {
        "capacity_rows": 10, "peak_rows": 10, "capacity_bits": 10 * 40 * 8,
        "peak_bits": 10 * 40 * 8}
    rep = run(_plan(CENSUS), left, right).report["buffers"]
    # the SVA is slow: its window of k + 2 = 7 rows (y - 1 - r .. y + r and one arriving)
    # fills
    assert rep["sva"]["sva.descriptor_rows"]["peak_rows"] == 7
    assert rep["sva"]["sva.descriptor_rows"]["capacity_rows"] == 7


def test_the_source_waits_when_the_line_buffer_is_full():
    """With the room rule the memory source is held back: its FIFO fills (the review found a
    peak of 1 when the buffer swallowed the frame)."""
    left, right = _pair(16, 40)
    rep = run_compiled(_plan(CNN), left, right).report
    assert rep["fifos"]["src_left_to_nna"]["max_occupancy"] == 16  # the FIFO's depth


def test_window_peaks_by_hand():
    # rows 0..4 enter at cycles 0, 10, 20, 30, 40; output rows done at 25 and 45; offset -1
    entered = np.array([0, 10, 20, 30, 40, -1])
    done = np.array([25, 45, -1, -1, -1, -1])
    # at 30 one output row is done: oldest = max(0, 1 - 1) = 0, held = 3 - 0 + 1 = 4
    assert window_peaks(entered, done, -1) == (5, 40)  # at 40: still 1 done, rows 0..4
    assert window_peaks(entered, done, 0) == (4, 40)  # oldest row 1
    assert window_peaks(np.array([-1]), done, 0) == (0, -1)


# ---- mutants: each must be caught ---------------------------------------------------------------


def _mutant_rule(monkeypatch, module, name, fake):
    monkeypatch.setattr(module, name, fake)


MUTANTS = {
    "nna room rule removed": (CNN, nna_block, "nna_rows_started_before_input",
                              lambda r, rows, half, top, out_rows, in_rows: 0,
                              "nna_left.nna.line_buffer"),
    "nna room rule one row late": (
        CNN, nna_block, "nna_rows_started_before_input",
        lambda r, rows, half, top, out_rows, in_rows, f=nna_block.nna_rows_started_before_input:
        f(r, rows + 1, half, top, out_rows, in_rows), "nna_left.nna.line_buffer"),
    "sva room rule removed": (CENSUS, sva_block, "sva_rows_done_before_input",
                              lambda y_in, la, h: 0, "sva.sva.descriptor_rows"),
    "sva room rule one row late": (
        CENSUS, sva_block, "sva_rows_done_before_input",
        lambda y_in, la, h, f=sva_block.sva_rows_done_before_input: f(y_in, la + 1, h),
        "sva.sva.descriptor_rows"),
}


@pytest.mark.parametrize("mutant", sorted(MUTANTS))
def test_a_broken_room_rule_is_caught(mutant, monkeypatch):
    over, module, name, fake, buffer = MUTANTS[mutant]
    left, right = _pair(16, 40)
    plan = _plan(over)
    run_readable(plan, left, right)  # the original passes
    monkeypatch.setattr(module, name, fake)
    with pytest.raises(BufferOverflow, match=f"buffer {buffer} held"):
        run_readable(plan, left, right)


def _shrunk(plan, block, buffer):
    """The plan with one window's capacity one row below what the room rule fills."""
    def shrink(b):
        if b.name != block:
            return b
        bufs = tuple(dataclasses.replace(x, rows=x.rows - 1) if x.name == buffer else x
                     for x in b.buffers)
        return dataclasses.replace(b, buffers=bufs)

    return dataclasses.replace(plan, blocks=tuple(shrink(b) for b in plan.blocks))


@pytest.mark.parametrize("run", [run_readable, run_compiled])
@pytest.mark.parametrize("over, block, buffer", [
    (CNN, "nna_left", "nna.line_buffer"),
    (CNN, "nna_right", "nna.line_buffer"),
    (CENSUS, "sva", "sva.descriptor_rows"),
    ({**CNN, "nna.stereo_submodules": 4}, "nna_left1", "nna.line_buffer"),
])
def test_a_buffer_smaller_than_the_frame_needs_is_caught(run, over, block, buffer):
    left, right = _pair(16, 40)
    plan = _shrunk(_plan(over), block, buffer)
    with pytest.raises(BufferOverflow, match=f"buffer {block}.{buffer} held"):
        run(plan, left, right)


# ---- the SVA's pipeline stages: words in flight against their registers --------------------------


def test_a_broken_issue_rule_overflows_a_stage(monkeypatch):
    """Issuing a word every tick instead of every II (2) puts two words into the SGM stage,
    whose registers hold one (latency 2, II 2), and 2 (D - 1) + 1 into the LR window of D."""
    left, right = _pair(16, 40)
    plan = _plan(CENSUS)
    run_readable(plan, left, right)
    monkeypatch.setattr(sva_block, "sva_issue_tick", lambda ready, last, ii: max(ready, last + 1))
    with pytest.raises(BufferOverflow, match="buffer sva.pipeline.sgm held 2 words, above the 1"):
        run_readable(plan, left, right)


def _stage_shrunk(plan, stage, slots):
    sva = plan.block("sva")
    stages = tuple(dataclasses.replace(st, slots=slots) if st.name == stage else st
                   for st in sva.stages)
    blocks = tuple(dataclasses.replace(b, stages=stages) if b.name == "sva" else b
                   for b in plan.blocks)
    return dataclasses.replace(plan, blocks=blocks)


@pytest.mark.parametrize("run", [run_readable, run_compiled])
def test_every_stage_below_the_words_it_holds_is_caught(run):
    """Each stage's registers one word short of the most it held (9 mutants per engine)."""
    left, right = _pair(16, 40)
    plan = _plan(CENSUS)
    peaks = run(plan, left, right).report["buffers"]["sva"]
    caught = []
    for st in plan.block("sva").stages:
        peak = peaks[f"pipeline.{st.name}"]["peak_words"]
        if peak == 0:
            assert st.latency == 0  # a stage without registers holds nothing
            continue
        with pytest.raises(BufferOverflow, match=f"buffer sva.pipeline.{st.name} held {peak}"):
            run(_stage_shrunk(plan, st.name, peak - 1), left, right)
        caught.append(st.name)
    assert len(caught) == 9
    assert peaks["pipeline.lr_check"]["peak_words"] == 16  # the LR window fills: D words
