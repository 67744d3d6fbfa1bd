"""cocotb runs (wta_bench runs them): the RTL median (sva/median/sva_median.sv) against stereosim.

A random frame of output words (-1 among them, narrow ranges full of ties) goes in raster order,
then the M W + M flush slots, with random bubbles and random stalls (en = 0); every median must
equal sva/median/median.py's reference (``median_ref``, replicate borders, -1 below every
disparity), in raster order, leave the plan's median latency (sim.cycle.stages.sva_stages, read from
the plan) after the slot that completes its window -- the word at (y + M, x + M), clamped to the
frame, i.e. slot j + M W + M for centre j -- and a slot offered back to back must be taken
one plan median II after the one before (1 with 1r1w row banks, 2 with 1rw: the run's
sva.sram_ports), none closer.
"""

import numpy as np
from cocotb.triggers import ReadOnly, RisingEdge
from twin import Pins

from stereosim.core.config import load_config
from stereosim.sim.cycle.stages import sva_stages
from stereosim.sva.geometry import output_word_bits
from stereosim.sva.median.median import median_ref


async def one_run(dut, p: dict) -> None:
    pins = Pins(dut, p.get("prefix", ""))

    cfg = load_config(overrides=p["overrides"])
    stages = sva_stages(cfg, 64, (32,), output_word_bits(cfg.sva), 32)
    stage = next(st for st in stages if st.name == "median")
    k, wb = cfg.sva.median, p["wb"]
    m = k // 2
    rng = np.random.default_rng(p["seed"])
    h, w = p["height"], p["width"]
    top = p["top"]
    q = rng.integers(-1, top + 1, (h, w))
    q[rng.random((h, w)) < 0.25] = -1
    narrow = rng.random(h) < 0.3  # rows of a few values: ties
    q[narrow] = rng.integers(-1, 3, (int(narrow.sum()), w))
    want = median_ref(q.astype(np.int32), k)
    slots = h * w + m * w + m
    pins.rst.value = 1
    pins.en.value = 1
    pins.in_valid.value = 0
    pins.width.value = w
    pins.height.value = h
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    pins.rst.value = 0
    fed, outs, back_to_back = [], [], []
    tick = cycle = 0
    offered_since = None  # the tick the slot now offered was first offered in
    while len(outs) < h * w and cycle < 20 * slots + 100:
        en = rng.random() >= p["stall"]
        if offered_since is None and len(fed) < slots and rng.random() >= p["gap"]:
            offered_since = tick
        pins.en.value = int(en)
        pins.in_valid.value = int(offered_since is not None)
        if offered_since is not None:
            j = len(fed)
            pins.word.value = int(q.flat[j]) & ((1 << wb) - 1) if j < h * w else 0
        await ReadOnly()
        if en:
            if offered_since is not None and int(pins.in_ready.value):
                if fed and offered_since <= fed[-1] + 1:  # offered from the next tick on
                    back_to_back.append(tick - fed[-1])
                fed.append(tick)
                offered_since = None
            if int(pins.out_valid.value):
                v = int(pins.med.value)
                outs.append((tick, v - (1 << wb) if v >> (wb - 1) else v))
        await RisingEdge(dut.clk)
        cycle += 1
        tick += int(en)
    assert len(outs) == h * w, f"{len(outs)} of {h * w} medians left the stage"
    skew = m * w + m
    for j, (t_out, got) in enumerate(outs):
        y, x = divmod(j, w)
        assert got == int(want[y, x]), f"centre ({y}, {x}): median {got} != {int(want[y, x])}"
        t_in = fed[j + skew]
        assert t_out - t_in == stage.latency, (
            f"centre ({y}, {x}): window complete in tick {t_in}, out in {t_out}: "
            f"{t_out - t_in} ticks, the plan's median latency is {stage.latency} "
            f"({stage.formula})")
    gaps = np.diff(fed)
    rule = f"the plan's median II is {stage.ii} ({stage.formula})"
    assert gaps.min() >= stage.ii, f"two slots {gaps.min()} ticks apart, {rule}"
    assert back_to_back and set(back_to_back) == {stage.ii}, (
        f"slots offered back to back were taken {sorted(set(back_to_back))} ticks apart, {rule}")
