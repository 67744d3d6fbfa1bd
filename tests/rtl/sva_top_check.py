"""The SVA as one block in RTL (sva/rtl/sva_top.sv) held at its boundary to the readable cycle
engine (sim/cycle/readable/blocks/sva.py; the compiled engine equals it cycle for cycle,
tests/sim/test_equivalence.py): a 6 x 24 census frame, D = 16 on 16 lanes, V = 8, box 3; paths
1, 2, 4, the LR check on/off and the 3 x 3 median on/off as run-time registers of one build;
the sink free or with random back-pressure (a 0/1 script, sim.cycle.rules.sink_pattern).

The model runs first, recorded at the SVA's boundary: the cycle each descriptor pair became
visible in both input FIFOs, each joint pop, each output push and its word, and in each SVA
cycle whether the output FIFO had room. The RTL is then offered each pair from the cycle it was
visible, with out_ready the model's room (tests/rtl/sva_top_bench.py), and

(a) every word equals the model's (which are sva/pipeline.py's functional model's) bit for bit;
(b) every joint pop and every output push happens in the model's cycle: the structure's
    sequencer (the column sums' k - 1 passes, each box row's r look-ahead slots, the slot and
    word spacing), its row-buffer read register and the median's skew are the plan's rules
    (sim.cycle.rules.sva_slot and the issue rules after it; finding 5 of docs/rtl.md,
    resolved).

The suite does not run it (one Verilator build of the whole SVA, about 30 s at -O0, and four
frames: ~40 s on 2 cores; its name keeps pytest from collecting it): benchmarks/rtl_sva_top.py
runs it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from stereosim.sim.config import load_config
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import build_chip

ROOT = Path(__file__).resolve().parents[2]
SHAPE = (6, 24)
SOURCES = ["sva/rtl/sva_hamming.sv", "sva/rtl/sva_box.sv", "sva/rtl/sva_sgm.sv",
           "sva/rtl/sva_wta.sv", "sva/rtl/sva_lr.sv", "sva/rtl/sva_median.sv",
           "sva/rtl/sva_top.sv"]
WB = 9  # 1 + bits_for(15) + 4 sub-pixel bits
MODES = {"off": 0, "parabola": 1, "equiangular": 2}
CASES = [(2, True, 0, 1, False), (1, False, 0, 2, True), (4, True, 0, 3, True),
         (2, True, 3, 4, False)]  # paths, LR, median, seed, back-pressure


def overrides(paths: int, lr: bool, median: int) -> dict:
    return {"nna.descriptor": "census", "sva.disparities": 16, "sva.lanes": 16,
            "sva.compare_levels": 8, "sva.box_size": 3, "sva.median": median, "sva.paths": paths,
            "sva.lr_check": lr}


def frame(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (SHAPE[0], SHAPE[1] + 3)).astype(np.uint8)
    return np.ascontiguousarray(base[:, 3:]), np.ascontiguousarray(base[:, :-3])


def sva_entry(plan):
    return next(b for b in (plan.blocks.values() if isinstance(plan.blocks, dict)
                            else plan.blocks) if b.name == "sva")


def model_run(cfg, left, right, script) -> tuple[dict, object]:
    """The readable engine on the pair, recorded at the SVA's boundary: per pair the cycle it
    became visible in each input FIFO and its beats, each pop, each push and word, and per SVA
    cycle whether the output FIFO had room."""
    plan = build_plan(cfg, left.shape, 1)
    chip = build_chip(left, right, plan, sink_stall=script)
    sva = chip.blocks["sva"]
    rec = {"vis_l": [], "vis_r": [], "beats_l": [], "beats_r": [], "pops": [], "pushes": [],
           "words": [], "room": []}
    for fifo, side in ((sva.in_left, "l"), (sva.in_right, "r")):
        def on_commit(now_fs, fifo=fifo, side=side, commit=fifo._commit):
            before = fifo._pushes
            moved = commit(now_fs)
            if fifo._pushes > before:
                rec["vis_" + side].append(int(fifo._items[-1][0]))
                rec["beats_" + side].append(fifo._items[-1][1])
            return moved
        fifo._commit = on_commit
    pop, push, evaluate = sva.in_left.pop, sva.out.push, sva.evaluate

    def on_pop():
        rec["pops"].append(int(sva.in_left._dst_cycle))
        return pop()

    def on_push(beat):
        rec["pushes"].append(int(sva.out._src_cycle))
        rec["words"].append(int(beat.word))
        push(beat)

    def on_evaluate(cycle):
        rec["room"].append(int(sva.out.can_push()))
        return evaluate(cycle)

    sva.in_left.pop, sva.out.push, sva.evaluate = on_pop, on_push, on_evaluate
    chip.run()
    return rec, plan


def rtl_case(cfg, entry, rec, out_path) -> dict:
    """The bench's case: run-time registers, the pairs and their visible cycles, the room."""
    s = cfg.sva
    regs = {"width": SHAPE[1], "height": SHAPE[0], "k": s.box_size, "p1": s.p1, "p2": s.p2,
            "adaptive": int(s.p2_adaptive), "slope": s.p2_slope, "paths": s.paths,
            "uniq": s.uniqueness, "mode": MODES[s.subpixel], "lr_on": int(s.lr_check),
            "max_diff": s.lr_max_diff, "med_on": int(s.median > 1), "ii": entry.cycles,
            "sii": entry.slot_cycles}
    return {"regs": regs,
            "visible": [max(a, b) for a, b in zip(rec["vis_l"], rec["vis_r"], strict=True)],
            "dl": [int(b.descriptor) for b in rec["beats_l"]],
            "dr": [int(b.descriptor) for b in rec["beats_r"]],
            "pix": [int(b.pixel) for b in rec["beats_l"]], "ready": rec["room"],
            "words": len(rec["words"]), "limit": len(rec["room"]) + 400, "out": str(out_path)}


def sources() -> str:
    return "\n".join((ROOT / f).read_text() for f in SOURCES)


@pytest.mark.parametrize("paths,lr,median,seed,back_pressure", CASES)
def test_sva_top(rtl_run, tmp_path, paths, lr, median, seed, back_pressure):
    check(rtl_run, tmp_path, sources(), paths, lr, median, seed, back_pressure)


def test_mutant_caught(rtl_run, tmp_path):
    """The top's emitting slots one tick further apart than the II register says (since > ii),
    LR off: every word still right, but caught by its push cycles."""
    text = sources()
    mutant = text.replace("(!s_emit || since >= ii)", "(!s_emit || since > ii)")
    assert mutant != text
    with pytest.raises(AssertionError, match="off the model's cycle"):
        check(rtl_run, tmp_path, mutant, 2, False, 0, 1, False)


def check(rtl_run, tmp_path, text, paths, lr, median, seed, back_pressure):
    """One case: the model, the RTL of ``text``, the module docstring's (a) and (b)."""
    cfg = load_config(overrides=overrides(paths, lr, median))
    left, right = frame(seed)
    script = None
    if back_pressure:
        script = (np.random.default_rng(seed).random(61) < 0.35).astype(np.int64)
        script[0] = 1
    rec, plan = model_run(cfg, left, right, script)
    entry = sva_entry(plan)
    out = tmp_path / "rtl.json"
    rtl_run((text,), "sva_top", {}, "sva_top_bench", rtl_case(cfg, entry, rec, out))
    got = json.loads(out.read_text())
    assert got["overrun"] is None, (
        f"cycle {got['overrun']}: a box pixel reached the SGM before its recurrence let it in "
        f"(the pipeline's II {entry.cycles} too short for the structure)")
    # (a) the words
    rtl_words = [v - (1 << WB) if v >> (WB - 1) else v for v in got["words"]]
    assert len(rtl_words) == len(rec["words"]), (
        f"{len(rtl_words)} of {len(rec['words'])} words left the RTL")
    bad = [i for i, (a, b) in enumerate(zip(rtl_words, rec["words"], strict=True)) if a != b]
    assert not bad, (f"{len(bad)} words differ from the model's, first at {bad[:6]}: "
                     f"{[rtl_words[i] for i in bad[:6]]} != {[rec['words'][i] for i in bad[:6]]}")
    # (b) every boundary handshake in the model's cycle
    w = SHAPE[1]
    for what, rtl, model in (("pop", got["pops"], rec["pops"]),
                             ("push", got["pushes"], rec["pushes"])):
        assert len(rtl) == len(model), f"{len(rtl)} {what}s in the RTL, {len(model)} in the model"
        lag = np.array(rtl) - np.array(model)
        bad = np.flatnonzero(lag)
        assert not len(bad), (
            f"{len(bad)} of {len(lag)} {what}s off the model's cycle, the first of pixel "
            f"{divmod(int(bad[0]), w)} (row, col): RTL cycle {rtl[bad[0]]}, model "
            f"{model[bad[0]]}; lags min/max {lag.min()}/{lag.max()} (plan: latency "
            f"{entry.latency}, II {entry.cycles}, slot II {entry.slot_cycles}, passes "
            f"{entry.passes}, median skew {entry.skew})")
    measured = (f"first word at {got['pushes'][0]}, last at {got['pushes'][-1]}, as the "
                "model's")
    print(f"sva_top paths {paths} lr {lr} median {median} back-pressure {back_pressure}: "
          f"{measured}")
