"""cocotb test module: the RTL box filter (sva/box/sva_box.sv) against stereosim.

A random cost volume per run is streamed through the stage as the SVA top would sequence it
(the frame's k column passes, then per row W + r slots: see the RTL's header), with random
input gaps and random lock-step stalls (``en`` low: nothing moves, the tick does not count).
Every emitted pixel's D sums must equal sva/box/aggregation.py's ``box_filter_ref`` on the volume
(replicate borders, saturation at 2^cost_bits - 1), and leave ``latency`` ticks after its slot
was taken; a slot offered without a gap is taken ``II`` ticks after the one before. Both
numbers are the plan's box_filter stage (sim.cycle.stages.sva_stages), read at run time.
After a slot that updates no column (a row's right border) the next is taken G ticks after
it: with two ports the plan's II, with one (sva.sram_ports = "1rw") less than the plan's 2 G
-- such a slot writes nothing to the column sums (a finding, test_sva_box_sgm.py).
"""


import cocotb
import numpy as np
from cocotb.triggers import ReadOnly, RisingEdge
from twin import Pins, each_run

from stereosim.core.config import load_config
from stereosim.sim.cycle.stages import sva_stages
from stereosim.sva.box.aggregation import box_filter_ref


def pack(values, width: int) -> int:
    return sum(int(v) << (i * width) for i, v in enumerate(values))


def schedule(cost: np.ndarray, k: int) -> list[dict]:
    """The slots of a frame: k passes adding rows clamp(-r) .. clamp(r) (the first fresh),
    then per row y the columns 0 .. W - 1 (the vertical window slides: + row min(y + r, H - 1)
    - row max(y - 1 - r, 0) for y > 0), each emitting pixel col - r once col >= r, and r
    slots re-entering column W - 1 (the right border)."""
    h, w, dn = cost.shape
    r = k // 2
    zero = np.zeros(dn, np.int64)
    slots = []
    for j in range(-r, r + 1):
        for c in range(w):
            slots.append({"col": c, "upd": 1, "fresh": int(j == -r), "fill": int(c == 0),
                          "emit": 0, "add": cost[min(max(j, 0), h - 1), c], "sub": zero,
                          "pixel": None})
    for y in range(h):
        y_in, y_out = min(y + r, h - 1), max(y - 1 - r, 0)
        for s in range(w + r):
            pixel = (y, s - r) if s >= r else None
            if s < w:
                add = cost[y_in, s] if y > 0 else zero
                sub = cost[y_out, s] if y > 0 else zero
                slots.append({"col": s, "upd": 1, "fresh": 0, "fill": int(s == 0),
                              "emit": int(pixel is not None), "add": add, "sub": sub,
                              "pixel": pixel})
            else:
                slots.append({"col": w - 1, "upd": 0, "fresh": 0, "fill": 0, "emit": 1,
                              "add": zero, "sub": zero, "pixel": pixel})
    return slots


@cocotb.test()
async def sums_and_cycles(dut):
    """Every run of the case (volumes, box sizes, D) on the one build, reset between."""
    await each_run(dut, one_run)


async def one_run(dut, p: dict) -> None:
    pins = Pins(dut, p.get("prefix", ""))
    cfg = load_config(overrides=p["overrides"])
    s = cfg.sva
    h, w, dn, k = p["h"], p["w"], s.disparities, s.box_size
    stage = next(st for st in sva_stages(cfg, w, (32,), 16, 32) if st.name == "box_filter")
    latency, ii, rule = stage.latency, stage.ii, f"the plan's box_filter latency ({stage.formula})"
    rng = np.random.default_rng(p["seed"])
    top = int(rng.integers(4, (1 << p["cost_w"])))
    cost = rng.integers(0, top + 1, (h, w, dn)).astype(np.uint8)
    want = box_filter_ref(cost, k, s.cost_bits)
    slots = schedule(cost, k)
    g = -(-dn // s.lanes)
    dut.rst.value = 1
    pins.en.value = 1
    pins.in_valid.value = 0
    pins.ngroups.value = g
    pins.k.value = k
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    taken, outs = [], []
    tick = cycle = 0
    nxt = 0
    pending_since = None
    back_to_back = []  # (gap in ticks, the previous slot updated) of slots offered since
    # the previous one was taken
    a_w = p["a_w"]
    emits = sum(sl["emit"] for sl in slots)
    while len(outs) < emits and cycle < 40 * len(slots) * (g + 4):
        en = rng.random() >= p["stall"]
        pins.en.value = int(en)
        if pending_since is None and nxt < len(slots) and rng.random() < p["offer"]:
            pending_since = tick
        if pending_since is not None:
            sl = slots[nxt]
            pins.in_valid.value = 1
            pins.col.value = sl["col"]
            for name in ("upd", "fresh", "fill", "emit"):
                getattr(pins, name).value = sl[name]
            pins.c_add.value = pack(sl["add"], p["cost_w"])
            pins.c_sub.value = pack(sl["sub"], p["cost_w"])
        else:
            pins.in_valid.value = 0
        await ReadOnly()
        if en and int(pins.out_valid.value):
            word = int(pins.agg.value)
            outs.append((tick, [(word >> (i * a_w)) & ((1 << a_w) - 1) for i in range(dn)]))
        if en and pending_since is not None and int(pins.in_ready.value):
            if taken and pending_since <= taken[-1][0] + 1:  # offered from the next tick
                back_to_back.append((tick - taken[-1][0], slots[taken[-1][1]]["upd"]))
            taken.append((tick, nxt))
            nxt += 1
            pending_since = None
        await RisingEdge(dut.clk)
        cycle += 1
        tick += int(en)
    emitted = [(t, slots[i]["pixel"]) for t, i in taken if slots[i]["emit"]]
    assert len(outs) == emits, f"{len(outs)} of {emits} pixels left the box filter"
    for (t_in, (y, x)), (t_out, got) in zip(emitted, outs, strict=True):
        assert got == [int(v) for v in want[y, x]], (
            f"pixel ({y}, {x}): box sums {got} != box_filter_ref {want[y, x].tolist()}")
        assert t_out - t_in == latency, (
            f"pixel ({y}, {x}): slot taken at tick {t_in}, out at {t_out}: {t_out - t_in} "
            f"ticks, {rule} is {latency}")
    after = [slots[i]["upd"] for _, i in taken[:-1]]
    gaps = np.diff([t for t, _ in taken])
    for upd, want_gap, what in ((1, ii, f"the plan's box_filter II is {ii} ({stage.formula})"),
                                (0, g, f"G = {g}: the slot wrote nothing")):
        seen = [gap for gap, was in zip(gaps, after, strict=True) if was == upd]
        offered = {gap for gap, was in back_to_back if was == upd}
        kind = "an updating slot" if upd else "a border slot (no update)"
        if not upd and k == 1:  # box 1: no border slots
            assert not seen, f"{len(seen)} border slots at box 1"
            continue
        assert min(seen) >= want_gap, f"a slot {min(seen)} ticks after {kind}, {what}"
        assert offered == {want_gap}, (
            f"slots offered back to back after {kind} were taken {sorted(offered)} ticks "
            f"apart, {what}")
