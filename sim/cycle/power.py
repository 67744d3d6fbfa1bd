"""Power from the run's own activity (the cycle report's ``power`` section, :func:`power_report`).

The blocks are :func:`~sim.cycle.area.chip_area`'s at ``power.node``: every NNA submodule of
``nna.submodules`` (stereo, lent or idle), the NNA's merge blocks, each SVA stage and each FIFO.
Per block, over the run of F frames (``stats``: the engine's statistics), and per frame = the
run's / F:

- **dynamic** (pJ a frame): the energy report's items (:func:`~sim.cycle.energy.energy_items`,
  unchanged, at the report's table), each given to the block that does it: the NNA's items to
  the stereo submodules in proportion to their tiles' output pixels; an SVA item to the stage
  whose datapath it names or whose buffer it reads; a FIFO's bits to that FIFO; the lent
  network's to the lent submodules in equal shares. Items of no chip block -- DRAM, the
  table's own clock figure, an SVA item of no stage -- are their own entries (``dram``,
  ``clock``, ``sva``) with no clock or leakage;
- **clock** (pJ a frame) = flip-flops x ``ff_clock_fj`` x clocked cycles x 1e-3 / F, the
  flip-flops chip_area's (a block without a logic figure has none: 0), ``ff_clock_fj`` the
  node's (:func:`core.tech.nodes.node`), the clocked cycles by ``power.clock_gating`` from the
  block's cycles in its domain (``stats["blocks"]``, ``stats["stages"]["sva"]``):
  ``off``: every cycle of the domain over the run (``stats["cycles"][domain]``); ``idle``: that
  less the idle cycles; ``stalled``: the busy cycles only (idle, blocked and starved gated).
  An idle submodule is idle in every cycle of the NNA domain; a lent one busy in every cycle
  (the lent network's cycles are not simulated). A FIFO has no flip-flop figure (chip_area);
- **leakage** (pJ a frame) = chip_area's ``leakage_mw`` x ``end_time_fs`` x 1e-6 / F (mW x fs
  = 1e-6 pJ): for the run's whole duration, first instant to the last word;
- a **power-gated** block (``power.gate_unused`` and an idle NNA submodule: neither the stereo
  pair nor the lent network uses it) costs nothing: no clock, no leakage. It is off for the
  whole run and never woken, so no wake-up latency enters the run;
- **total** = dynamic + clock + leakage; the chip's totals are the sums over the blocks.

Power over the run: ``average_power_mw`` = the chip's total a frame x F / the run's duration;
``leakage_power_mw`` = the sum of the ungated blocks' leakage; ``peak_power_mw`` -- peak over one
frame, not finer -- the highest of the frames' averages, frame k's = the dynamic energy a frame
/ its interval (its last output word's instant less the previous frame's, the first frame's
from t = 0) + the run's average clock and leakage power (the counts are the same every frame;
the engines count cycle states over the run, not per frame).
"""

from __future__ import annotations

import numpy as np

from stereosim.core.tech.nodes import node
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sim.cycle.rules import FS_PER_S

PEAK_WINDOW = ("peak over one frame: the highest frame average (the dynamic energy a frame over "
               "the frame's interval, plus the run's average clock and leakage power)")


def clocked_cycles(counts: dict, domain_cycles: int, gating: str) -> int:
    """The cycles a block's registers are clocked under ``power.clock_gating`` (the schema
    holds its choices): every cycle of its domain (``off``), all but the idle ones (``idle``),
    the busy ones only (``stalled``)."""
    if gating == "stalled":
        return int(counts["busy"])
    if gating == "idle":
        return int(domain_cycles) - int(counts["idle"])
    return int(domain_cycles)


def block_energy_pj(flip_flops: float, ff_clock_fj: float, clocked: int, leakage_mw: float,
                    end_time_fs: int, frames: int) -> tuple[float, float]:
    """(clock, leakage) pJ a frame: flip_flops x ff_clock_fj x clocked x 1e-3 / frames and
    leakage_mw x end_time_fs x 1e-6 / frames."""
    return (flip_flops * ff_clock_fj * clocked * 1e-3 / frames,
            leakage_mw * end_time_fs * 1e-6 / frames)


def _activity(plan: ChipPlan, stats: dict) -> dict[str, tuple[str, dict | None]]:
    """Each chip_area block's (domain, its cycle counts), None for a whole-run state (an idle or
    lent submodule, a FIFO)."""
    out: dict[str, tuple[str, dict | None]] = {}
    cycles_nna = int(stats["cycles"]["nna"])
    nna = plan.blocks_of("nna")
    for i in range(plan.cfg.nna.submodules):
        if i < len(nna):
            out[f"nna.sub{i}"] = ("nna", stats["blocks"][nna[i].name])
        elif i < plan.cfg.nna.stereo_submodules + plan.cfg.nna.lent_submodules:
            out[f"nna.sub{i}"] = ("nna", {"busy": cycles_nna, "idle": 0})
        else:
            out[f"nna.sub{i}"] = ("nna", {"busy": 0, "idle": cycles_nna})
    for b in plan.blocks_of("merge"):
        out[b.name] = (b.domain, stats["blocks"][b.name])
    for st in plan.block("sva").stages:
        out[f"sva.{st.name}"] = ("sva", stats["stages"]["sva"][st.name])
    for f in plan.fifos:
        out[f"fifo.{f.name}"] = (f.dst, None)
    return out


def dynamic_by_block(plan: ChipPlan, items: list[dict]) -> dict[str, float]:
    """The energy items' pJ a frame per block (module docstring: who does which item)."""
    nna = plan.blocks_of("nna")
    pixels = [b.tile.shape[0] * b.tile.shape[1] for b in nna]
    stereo = plan.cfg.nna.stereo_submodules
    lent = [f"nna.sub{i}" for i in range(stereo, stereo + plan.cfg.nna.lent_submodules)]
    stage_of = {buf.name: st.name for st in plan.block("sva").stages for buf in st.buffers}
    stages = {st.name for st in plan.block("sva").stages}
    out: dict[str, float] = {}

    def add(name: str, pj: float) -> None:
        out[name] = out.get(name, 0.0) + pj

    for it in items:
        pj = it["count"] * it["pj_each"]
        block, what = it["block"], it["what"]
        head = what.split(" ")[0]
        if block == "nna":
            for i, p in enumerate(pixels):
                add(f"nna.sub{i}", pj * p / sum(pixels))
        elif block == "lent" and lent:
            for name in lent:
                add(name, pj / len(lent))
        elif block == "sva" and head in stage_of:
            add(f"sva.{stage_of[head]}", pj)
        elif block == "sva" and what.endswith(" datapath") and head in stages:
            add(f"sva.{head}", pj)
        elif block == "fifos":
            add(f"fifo.{what.split(':')[0]}", pj)
        else:
            add(block, pj)
    return out


def power_report(plan: ChipPlan, stats: dict, energy: dict, frame_times, area: dict) -> dict:
    """The ``power`` section of a cycle report (module docstring: every formula): the node and
    the gating, per block its dynamic, clock, leakage and total pJ a frame, the chip's totals,
    the energy a frame, the average, leakage and peak power (mW) over the run. ``energy``: the
    report's ``energy`` section (its items); ``frame_times``: the engine's (first and last
    instants in fs per frame, :func:`~sim.cycle.report.stream_report`); ``area``: the chip's
    (:func:`~sim.cycle.area.chip_area` at ``power.node``, worked out once per run)."""
    cfg = plan.cfg.power
    n = node(cfg.node)
    frames = plan.frames
    end_fs = int(stats["end_time_fs"])
    activity = _activity(plan, stats)
    dynamic = dynamic_by_block(plan, energy["items"])
    blocks: dict[str, dict] = {}
    for b in area["blocks"]:
        name = b["name"]
        domain, counts = activity[name]
        ffs = b["logic"]["flip_flops"] if b["logic"] else 0.0
        gated = cfg.gate_unused and b.get("use") == "idle"
        clocked = 0 if gated or counts is None else clocked_cycles(
            counts, stats["cycles"][domain], cfg.clock_gating)
        leak_mw = 0.0 if gated else b["leakage_mw"]
        clock_pj, leak_pj = block_energy_pj(ffs, n.ff_clock_fj, clocked, leak_mw, end_fs, frames)
        dyn = dynamic.pop(name, 0.0)
        blocks[name] = {"kind": b["kind"], **({"use": b["use"]} if "use" in b else {}),
                        "domain": domain, "power_gated": gated, "flip_flops": ffs,
                        "clocked_cycles": clocked, "leakage_mw": leak_mw,
                        "dynamic_pj": dyn, "clock_pj": clock_pj, "leakage_pj": leak_pj,
                        "total_pj": dyn + clock_pj + leak_pj}
    for name in sorted(dynamic):  # items of no chip block: DRAM, the table's clock, ...
        blocks[name] = {"kind": "other", "dynamic_pj": dynamic[name], "clock_pj": 0.0,
                        "leakage_pj": 0.0, "total_pj": dynamic[name]}
    per_frame = {k: sum(b[f"{k}_pj"] for b in blocks.values())
                 for k in ("dynamic", "clock", "leakage", "total")}
    run_s = end_fs / FS_PER_S
    static_mw = ((per_frame["clock"] + per_frame["leakage"]) * frames * 1e-9 / run_s
                 if run_s else None)
    last = np.asarray(frame_times[1], dtype=np.int64)
    last = np.sort(last[last >= 0])
    intervals = np.diff(np.concatenate(([0], last)))
    intervals = intervals[intervals > 0]
    peak = (per_frame["dynamic"] * 1e-9 / (float(intervals.min()) / FS_PER_S) + static_mw
            if len(intervals) and static_mw is not None else None)
    t = area["totals"]
    return {
        "node": cfg.node, "clock_gating": cfg.clock_gating, "gate_unused": cfg.gate_unused,
        "ff_clock_fj": n.ff_clock_fj, "frames": frames, "run_ms": end_fs / 1e12,
        "blocks": blocks,
        "per_frame_pj": per_frame,
        "energy_per_frame_uj": per_frame["total"] / 1e6,
        "average_power_mw": per_frame["total"] * frames * 1e-9 / run_s if run_s else None,
        "leakage_power_mw": sum(b.get("leakage_mw", 0.0) for b in blocks.values()),
        "peak_power_mw": peak, "peak_window": PEAK_WINDOW,
        **({"leakage_note": "SRAM leakage not counted: " + t["sram_reason"]}
           if "sram_reason" in t else {}),
        "not_clocked": sorted(b["name"] for b in area["blocks"] if not b["logic"]),
    }
