"""cocotb test module: the RTL disparity selection (sva/wta/sva_wta.sv) against stereosim (and
the runner of lr_bench's and median_bench's runs in the same simulation).

Random pixels of D summed costs (uniform, narrow ranges full of ties, valleys that give sub-pixel
offsets of both signs) are offered with random gaps while the global ``en`` stalls the stage at
random; every word, d* and S1 must equal sva/wta/wta.py's reference (``wta_ref`` on the same costs),
leave ``latency`` ticks (cycles with en = 1) after the pixel was taken and the stage must take
a pixel every II ticks when offered one -- the plan's wta stage (sim.cycle.stages.sva_stages),
read from the plan for the run's configuration (uniqueness margin and sub-pixel mode are run-time
registers of the one build).
"""

import dataclasses
import json
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge

from stereosim.core.config import load_config
from stereosim.sim.cycle.stages import sva_stages
from stereosim.sva.geometry import output_word_bits
from stereosim.sva.wta.wta import SUBPIXEL_MODES, wta_ref


def plan_stage(cfg, name: str):
    """The plan's stage ``name`` for ``cfg`` (frames 64 wide, a 32-bit descriptor)."""
    stages = sva_stages(cfg, 64, (32,), output_word_bits(cfg.sva), 32)
    return next(st for st in stages if st.name == name)


def random_costs(rng, n: int, d: int, sw: int) -> np.ndarray:
    """n pixels of D costs below 2^sw: uniform, a narrow range (ties), or a valley."""
    top = (1 << sw) - 1
    out = np.empty((n, d), np.int64)
    for i in range(n):
        kind = rng.integers(0, 4)
        if kind == 0:
            out[i] = rng.integers(0, top + 1, d)
        elif kind == 1:
            out[i] = rng.integers(0, 4, d) + rng.integers(0, top - 3)
        else:
            c = rng.integers(0, d)
            base = rng.integers(0, top // 4)
            slope = rng.integers(1, max(2, top // (4 * d)))
            out[i] = base + slope * np.abs(np.arange(d) - c) + rng.integers(0, slope + 1, d)
            if kind == 3:  # a second valley: the uniqueness check's business
                c2 = (c + rng.integers(2, d)) % d
                out[i, c2] = out[i, c] + rng.integers(0, 3 * slope + 1)
    return np.minimum(out, top).astype(np.uint16)


@cocotb.test()
async def words_and_cycles(dut):
    """Every run of the case on the one build, reset between: a run's ``stage`` picks its
    bench -- ``wta`` (this module), ``lr`` (lr_bench), ``median`` (median_bench) -- and its
    ``prefix`` the instance's ports, so one simulation checks every stage of a wrapper."""
    import lr_bench
    import median_bench

    benches = {"wta": one_run, "lr": lr_bench.one_run, "median": median_bench.one_run}
    case = json.loads(os.environ["STEREOSIM_RTL_CASE"])
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    for run in case["runs"]:
        p = {**case, **run}
        await benches[p.get("stage", "wta")](dut, p)


async def one_run(dut, p: dict) -> None:
    pre = p.get("prefix", "")

    def sig(name):
        return getattr(dut, pre + name)

    cfg = load_config(overrides={**p["overrides"], "sva.uniqueness": p["uniq"],
                                 "sva.subpixel": SUBPIXEL_MODES[p["mode"]]})
    stage = plan_stage(cfg, "wta")
    if p.get("rule_mutant"):  # the rule one cycle late: the RTL must catch it by name
        stage = dataclasses.replace(stage, latency=stage.latency + 1)
    latency = stage.latency
    d, sw, f, wb = cfg.sva.disparities, p["sw"], cfg.sva.subpixel_bits, p["wb"]
    rng = np.random.default_rng(p["seed"])
    n = p["pixels"]
    costs = random_costs(rng, n, d, sw)
    want_q, want_d = wta_ref(costs[None], uniqueness=p["uniq"],
                             subpixel=SUBPIXEL_MODES[p["mode"]], frac_bits=f)
    sig("rst").value = 1
    sig("en").value = 1
    sig("in_valid").value = 0
    sig("uniq").value = p["uniq"]
    sig("mode").value = p["mode"]
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    sig("rst").value = 0
    taken, outs = [], []
    tick = cycle = 0
    nxt = 0
    while len(outs) < n and cycle < 60 * n * (stage.ii + latency):
        en = rng.random() >= p["stall"]
        offer = nxt < n and (p["offer"] == 1.0 or rng.random() < p["offer"])
        sig("en").value = int(en)
        sig("in_valid").value = int(offer)
        if offer:
            sig("s_in").value = sum(int(v) << (i * sw) for i, v in enumerate(costs[nxt]))
        await ReadOnly()
        if en:
            if offer and int(sig("in_ready").value):
                taken.append(tick)
                nxt += 1
            if int(sig("out_valid").value):
                word = int(sig("q").value)
                word = word - (1 << wb) if word >> (wb - 1) else word
                outs.append((tick, word, int(sig("dstar").value), int(sig("s1").value)))
        await RisingEdge(dut.clk)
        cycle += 1
        tick += int(en)
    assert len(outs) == n, f"{len(outs)} of {n} pixels left the stage"
    for i, (t, (t_out, word, dstar, s1)) in enumerate(zip(taken, outs, strict=True)):
        assert word == int(want_q[0, i]), (
            f"pixel {i}: word {word} != {int(want_q[0, i])} (costs {costs[i].tolist()}, "
            f"u {p['uniq']}, mode {p['mode']})")
        assert dstar == int(want_d[0, i]), f"pixel {i}: d* {dstar} != {int(want_d[0, i])}"
        assert s1 == int(costs[i].min()), f"pixel {i}: S1 {s1} != {int(costs[i].min())}"
        assert t_out - t == latency, (
            f"pixel {i}: taken in tick {t}, out in {t_out}: {t_out - t} ticks, the plan's wta "
            f"latency is {stage.latency} ({stage.formula})")
    words = [w for _, w, _, _ in outs]
    if p["uniq"] >= 15:  # the case exercises what it configures
        assert -1 in words, "no word rejected by the uniqueness check"
    if p["mode"]:
        assert any(w > 0 and w % (1 << f) for w in words), "no sub-pixel offset"
    gaps = np.diff(taken)
    assert gaps.min() >= stage.ii, (
        f"two pixels {gaps.min()} ticks apart, the plan's wta II is {stage.ii}")
    if p["offer"] == 1.0:  # offered every tick: taken exactly every II
        assert set(gaps.tolist()) == {stage.ii}, (
            f"gaps {sorted(set(gaps.tolist()))}, the plan's wta II is {stage.ii}")
