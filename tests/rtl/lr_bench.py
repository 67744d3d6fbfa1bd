"""cocotb runs (wta_bench runs them): the RTL left-right check (sva/lr/sva_lr.sv) against
stereosim.

A random summed-cost volume S (H, W, D) -- each pixel a valley of random depth, so that right and
left disparities agree on some pixels and not on others -- gives the words and winners of
sva/wta/wta.py's reference; its pixels go to the stage in raster order, a pixel every II ticks
within a row (II: the plan's pipeline II), each row's first any number g >= II of ticks after
the previous row's last (:func:`row_gaps`: II itself, gaps that are not whole IIs, gaps around
the end of the previous row's drain), with random stalls (en = 0). Every checked word must
equal sva/lr/lr_check.py's reference (``lr_check_ref`` with ``right_disparity_ref``) and leave the
plan's lr_check latency (sim.cycle.stages.sva_stages, read from the plan) after its pixel
arrived; with the instance named (``inst``), the window and the drain copy must never load the
output register in the same tick (its emit_main / emit_drain), and the drain must have emitted.
"""

import numpy as np
from cocotb.triggers import ReadOnly, RisingEdge
from twin import Pins

from stereosim.core.config import load_config
from stereosim.sim.cycle.stages import pipeline_ii, sva_stages
from stereosim.sva.geometry import output_word_bits
from stereosim.sva.lr.lr_check import lr_check_ref, right_disparity_ref
from stereosim.sva.wta.wta import wta_ref


def volume(rng, h: int, w: int, d: int, sw: int) -> np.ndarray:
    """S (H, W, D) below 2^sw: per pixel a valley at a disparity drifting along the row; every
    other row's costs coarse (multiples of 64), full of ties."""
    top = (1 << sw) - 1
    s = np.empty((h, w, d), np.int64)
    for y in range(h):
        c = rng.integers(0, d)
        for x in range(w):
            if rng.random() < 0.3:
                c = rng.integers(0, d)
            slope = rng.integers(1, 40)
            s[y, x] = rng.integers(0, 200) + slope * np.abs(np.arange(d) - c) \
                + rng.integers(0, 60, d)
        if y % 2:  # coarse costs: ties along the diagonals (the smallest d must win)
            s[y] = s[y] // 64 * 64
    return np.minimum(s, top).astype(np.uint16)


def row_gaps(rng, n: int, ii: int, d: int) -> list[int]:
    """``n`` gaps in ticks from a row's last pixel to the next row's first, each >= II, in
    random order: II itself, II + 1 (not a whole number of IIs where II > 1), and the rest
    random -- II + 1 .. 3 II, or around the previous row's drain ((D - 1) II +- 2 II)."""
    fixed = [ii, ii + 1][:n]
    rest = [int(rng.integers(ii + 1, 3 * ii + 1)) if rng.random() < 0.5 else
            int(rng.integers(max(ii, (d - 3) * ii), (d + 1) * ii + 1))
            for _ in range(n - len(fixed))]
    return [int(g) for g in rng.permutation(fixed + rest)]


async def one_run(dut, p: dict) -> None:
    pins = Pins(dut, p.get("prefix", ""))

    cfg = load_config(overrides=p["overrides"])
    stages = sva_stages(cfg, 64, (32,), output_word_bits(cfg.sva), 32)
    stage = next(st for st in stages if st.name == "lr_check")
    ii = pipeline_ii(stages)
    d, sw, wb, f = cfg.sva.disparities, p["sw"], p["wb"], cfg.sva.subpixel_bits
    rng = np.random.default_rng(p["seed"])
    h, w = p["height"], p["width"]
    s = volume(rng, h, w, d, sw)
    q, dint = wta_ref(s, uniqueness=0, subpixel="parabola", frac_bits=f)
    want = lr_check_ref(q, dint, right_disparity_ref(s), cfg.sva.lr_max_diff)
    # the tick each pixel is offered: II apart in a row, a row g >= II after the last
    gaps = row_gaps(rng, h - 1, ii, d)
    start, t = [], 3
    for y in range(h):
        for _ in range(w):
            start.append(t)
            t += ii
        t += gaps[y] - ii if y < h - 1 else 0
    pins.rst.value = 1
    pins.en.value = 1
    pins.in_valid.value = 0
    pins.width.value = w
    pins.ii.value = ii
    pins.max_diff.value = cfg.sva.lr_max_diff
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    pins.rst.value = 0
    outs = []
    inst = getattr(dut, p["inst"]) if "inst" in p else None
    drained = 0
    tick = cycle = 0
    nxt = 0
    while len(outs) < h * w and cycle < 4 * (start[-1] + stage.latency) + 100:
        en = rng.random() >= p["stall"]
        offer = nxt < h * w and start[nxt] == tick
        pins.en.value = int(en)
        pins.in_valid.value = int(offer)
        if offer:
            y, x = divmod(nxt, w)
            pins.s_in.value = sum(int(v) << (i * sw) for i, v in enumerate(s[y, x]))
            pins.q_in.value = int(q[y, x]) & ((1 << wb) - 1)
            pins.d_in.value = int(dint[y, x])
        await ReadOnly()
        if en and inst is not None:
            main, drain = int(inst.emit_main.value), int(inst.emit_drain.value)
            assert not (main and drain), (
                f"tick {tick}: the window and the drain copy load the output register together")
            drained += drain
        if en:
            nxt += int(offer)
            if int(pins.out_valid.value):
                v = int(pins.q_out.value)
                outs.append((tick, v - (1 << wb) if v >> (wb - 1) else v))
        await RisingEdge(dut.clk)
        cycle += 1
        tick += int(en)
    assert len(outs) == h * w, f"{len(outs)} of {h * w} words left the stage"
    rejected = 0
    for j, (t_out, got) in enumerate(outs):
        y, x = divmod(j, w)
        assert got == int(want[y, x]), (
            f"pixel ({y}, {x}): word {got} != {int(want[y, x])} (d* {int(dint[y, x])})")
        rejected += int(got == -1 and q[y, x] != -1)
        assert t_out - start[j] == stage.latency, (
            f"pixel ({y}, {x}): in at tick {start[j]}, out at {t_out}: {t_out - start[j]} "
            f"ticks, the plan's lr_check latency is {stage.latency} ({stage.formula})")
    assert 0 < rejected < h * w, f"{rejected} words rejected: the case checks nothing"
    assert inst is None or drained == h * (d - 1), (
        f"{drained} words left through the drain copy, not {h} rows x {d - 1}")
