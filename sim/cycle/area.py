"""The chip's area and static leakage by block at a process node (:func:`chip_area`).

Blocks: every NNA submodule of ``nna.submodules`` (one design instantiated that many times,
sized for the widest tile, :func:`~sim.cycle.figures.chip_sram`'s rule; each marked by its use:
stereo, lent or idle), the NNA's merge blocks, each SVA stage of the plan and each FIFO. A
block has

- **logic** in NAND2 gate-equivalents (GE), combinational and flip-flops apart, from the RTL
  twin's synthesis table (``sva/synth_table.json``, :mod:`sim.rtl_synth`): an SVA stage's row
  where the table holds this configuration (the D, lanes, V, descriptor and build parameters),
  else its **area rule** (the table's ``area_rules``: a fitted, checked formula in the lanes,
  D, widths, or the NNA layer's channels and multipliers, :func:`sim.rtl_synth.
  area_rule_figures`); an NNA submodule's weight store (the plan's ``nna.weights``, declared as
  registers: weight-stationary, and run-time inputs of the RTL) adds its bits as flip-flops;
  a block without RTL (the FIFOs' and merges' control, the SVA's row read, output register
  and sequencer) or outside its rule's fitted domain has ``"logic": null`` and a reason;
- **SRAM macros**: each SRAM buffer of the plan (ports ``1r1w`` or ``1rw``; the NNA's line
  buffers and census rows, which the plan declares with banks but no ports, as ``1r1w``: the
  RTL writes a word and reads a column in one cycle) as ``banks`` macros of bits / banks each
  in words of ``word_bits`` (:func:`core.tech.sram.sram_macro`); a FIFO as one 1r1w macro of
  depth x width. An SVA buffer the plan declares as registers (``ports == ""``) is in its
  stage's RTL flip-flops and not counted again;
- **area** in mm^2: GE x ``ge_area_um2`` + flip-flops x ``ff_area_ge`` x ``ge_area_um2`` + the
  macros', and **leakage** in mW: GE x ``ge_leakage_nw`` + flip-flops x ``ff_leakage_nw`` + the
  macros' (:func:`core.tech.nodes.node`).

A node without SRAM data (7 nm) gives ``"sram": null`` and a reason in every block with SRAM,
and SRAM and chip totals of null. ``python -m stereosim.sim.cycle.area --config FILE --node
45nm`` prints the table.
"""

from __future__ import annotations

import argparse
import json
import sys

from stereosim.core.config.loader import load_config
from stereosim.core.errors import ConfigError
from stereosim.core.tech.nodes import node
from stereosim.core.tech.sram import sram_macro
from stereosim.nna.descriptor import descriptor_parts
from stereosim.sim import rtl_synth as rs
from stereosim.sim.cycle.figures import sram_bits
from stereosim.sim.cycle.plan import ChipPlan, build_plan, frame_size

BASIS = ("logic: Yosys NAND2 equivalents of the RTL twin (sva/synth_table.json: a row of this "
         "configuration, else the block's checked area rule) x the node's gate-equivalent "
         "area, flip-flops x the node's flip-flop area; SRAM: core.tech.sram macros, each bank "
         "a macro; no wires, no placement, no clock tree, no pads or IO, no power grid")
# plan stages whose logic is in another stage's RTL, and stages with no RTL of their own
_IN_ROW = {"path_sum": "sgm"}
_NO_RTL = {"row_read": "no RTL of its own (the row buffers' read, part of sva_top)",
           "output": "no RTL of its own (the output register, part of sva_top)"}


def _logic(node_name: str, nand2: float, flops: float) -> dict:
    """Area (mm^2) and leakage (mW) of ``nand2`` GE of logic and ``flops`` flip-flops."""
    n = node(node_name)
    nand2, flops = round(nand2, 1), round(flops, 1)
    return {"nand2_logic": nand2, "flip_flops": flops,
            "area_mm2": (nand2 + flops * n.ff_area_ge) * n.ge_area_um2 * 1e-6,
            "leakage_mw": (nand2 * n.ge_leakage_nw + flops * n.ff_leakage_nw) * 1e-6}


def _sram(node_name: str, buffers: list[tuple[str, int, int, str, int]]) -> dict:
    """The macros of ``buffers`` (name, bits, word bits, ports, banks): each bank a macro of
    bits / banks; ``{"sram": None, "sram_reason": ...}`` where the node has no SRAM data."""
    macros = []
    for name, bits, word, ports, banks in buffers:
        per = -(-bits // banks)
        try:
            m = sram_macro(node_name, per, word, ports)
        except ConfigError as exc:
            return {"sram": None, "sram_reason": str(exc)}
        macros.append({"buffer": name, "bits": bits, "word_bits": word, "ports": ports,
                       "banks": banks, "macro_bits": per, "tiles_per_macro": m.tiles,
                       "area_mm2": banks * m.area_mm2, "leakage_mw": banks * m.leakage_uw * 1e-3})
    return {"sram": {"macros": macros, "area_mm2": sum(m["area_mm2"] for m in macros),
                     "leakage_mw": sum(m["leakage_mw"] for m in macros)}}


def _sram_buffers(buffers, sva: bool) -> list[tuple[str, int, int, str, int]]:
    """The SRAM among a block's buffers: declared ports, or (the NNA's) rows in banks."""
    out = []
    for b in buffers:
        if b.ports in ("1r1w", "1rw"):
            out.append((b.name, b.bits, b.word_bits, b.ports, b.banks))
        elif not sva and b.rows and b.word_bits:
            out.append((b.name, b.bits, b.word_bits, "1r1w", b.banks))
    return out


def _block(name: str, kind: str, used: bool, logic: dict | None, reason: str, sram: dict,
           **extra) -> dict:
    out = {"name": name, "kind": kind, "used": used, **extra, "logic": logic}
    if logic is None:
        out["logic_reason"] = reason
    out.update(sram)
    parts = [x for x in (logic, out.get("sram")) if x]
    out["area_mm2"] = sum(x["area_mm2"] for x in parts)
    out["leakage_mw"] = sum(x["leakage_mw"] for x in parts)
    return out


def nna_logic(plan: ChipPlan, table: dict | None = None) -> tuple[dict | None, str]:
    """One NNA submodule's logic (GE, flip-flops, what each part is) by the NNA area rule per
    layer plus its weight registers, or (None, the reason)."""
    spec = plan.spec.nna
    sub = next(iter(plan.blocks_of("nna")))
    if spec.cnn is None or len(spec.parts) > 1:
        return None, "the census unit has no RTL (the NNA RTL is the CNN's MAC array)"
    parts, nand2, flops = [], 0.0, 0.0
    for lay in sub.layers:
        if lay.channels_in != 1 or len(sub.layers) > 1:
            return None, ("outside nna's area rule: a network of several layers (fitted on one "
                          "9 x 9 x 1 x C layer)")
        params = {"LAYERS": 1, "K0": 2 * lay.half + 1, "C1": lay.channels_out,
                  "P0": lay.macs // lay.channels_out, "ROWS0": lay.rows, "W": 0}
        fig = rs.area_rule_figures("nna", params, table)
        if "reason" in fig:
            return None, fig["reason"]
        parts.append({"what": f"layer {lay.index}: {params['K0']}x{params['K0']}x1x"
                      f"{params['C1']}, {params['C1']} x {params['P0']} MACs (nna area rule; "
                      "line buffer as SRAM)", **{k: round(v, 1) for k, v in fig.items()}})
        nand2 += fig["nand2_logic"]
        flops += fig["flip_flops"]
    for b in sub.buffers:
        if b.name == "nna.weights":
            parts.append({"what": f"{b.name}: {b.bits} bits of registers (weight-stationary; "
                          "run-time inputs of the RTL)", "nand2_logic": 0.0,
                          "flip_flops": float(b.bits)})
            flops += b.bits
    return {"nand2_logic": nand2, "flip_flops": flops, "parts": parts}, ""


def sva_stage_logic(plan: ChipPlan, stage: str, table: dict | None = None
                    ) -> tuple[dict | None, str]:
    """An SVA stage's logic: the table's row of this configuration where it holds one (and
    its scaling held), else the stage's area rule; (None, the reason) otherwise."""
    table = rs.default_table() if table is None else table
    if stage in _NO_RTL:
        return None, _NO_RTL[stage]
    if stage in _IN_ROW:
        return None, f"in {_IN_ROW[stage]}'s RTL (counted there)"
    cfg = plan.cfg
    s = cfg.sva
    parts = tuple(b for _, b in descriptor_parts(cfg.nna))
    d, lanes, v = s.disparities, min(s.lanes, s.disparities), s.compare_levels
    st = rs.STAGE.get(stage)
    if st is None:
        return None, f"no RTL for {stage}"
    params = st.params(d, lanes, v, parts, s)
    if params is None:
        return None, f"{stage} is off in this configuration"
    failures = rs.scaling_failures(table)
    row = next((r for r in rs.rows_for(table, d, lanes, v, parts) if r["stage"] == stage
                and r["params"] == params and rs.row_valid(r, failures)), None)
    if row is not None:
        eq = rs.area_point(row["cells"])
        return {**eq, "source": f"synth table row ({row['how']})", "params": params}, ""
    fig = rs.area_rule_figures(stage, params, table)
    if "reason" in fig:
        return None, fig["reason"]
    return {**fig, "source": f"{stage}'s area rule", "params": params}, ""


def _nna_blocks(plan: ChipPlan, node_name: str, table: dict | None) -> list[dict]:
    n = plan.cfg.nna
    logic, reason = nna_logic(plan, table)
    sub = next(iter(plan.blocks_of("nna")))
    widest = sram_bits(plan)
    buffers = [b for b in sub.buffers if b.name in widest]
    sram = _sram(node_name, [(name, widest[name], word, ports, banks)
                             for name, _, word, ports, banks in _sram_buffers(buffers, False)])
    out = []
    for i in range(n.submodules):
        use = ("stereo" if i < n.stereo_submodules else
               "lent" if i < n.stereo_submodules + n.lent_submodules else "idle")
        lg = None if logic is None else {**_logic(node_name, logic["nand2_logic"],
                                                  logic["flip_flops"]),
                                         "source": "nna's area rule (its MAC array layer) + "
                                                   "its weight registers",
                                         "parts": logic["parts"]}
        out.append(_block(f"nna.sub{i}", "nna_submodule", use == "stereo", lg, reason, sram,
                          use=use))
    for b in plan.blocks_of("merge"):
        out.append(_block(b.name, "merge", True, None, "no RTL (the tiles' merge)", {}))
    return out


def chip_area(plan: ChipPlan, node_name: str, table: dict | None = None) -> dict:
    """The chip's area (mm^2) and static leakage (mW) by block at ``node_name`` (module
    docstring): ``blocks`` (each its logic, SRAM macros, area and leakage; ``used``: serves the
    stereo pair), ``totals`` (logic, SRAM and chip; SRAM and chip null where the node has no
    SRAM data) and ``not_costed`` (each block part without a figure and why)."""
    n = node(node_name)
    blocks = _nna_blocks(plan, node_name, table)
    sva = plan.block("sva")
    for st in sva.stages:
        logic, reason = sva_stage_logic(plan, st.name, table)
        lg = None if logic is None else {**_logic(node_name, logic["nand2_logic"],
                                                  logic["flip_flops"]),
                                         "source": logic["source"]}
        blocks.append(_block(f"sva.{st.name}", "sva_stage", True, lg, reason,
                             _sram(node_name, _sram_buffers(st.buffers, True))
                             if _sram_buffers(st.buffers, True) else {}))
    for f in plan.fifos:
        blocks.append(_block(f"fifo.{f.name}", "fifo", True, None,
                             "no RTL (the FIFO's pointers and synchronisers)",
                             _sram(node_name, [(f.name, f.sram_bits, f.width_bits, "1r1w", 1)]),
                             depth=f.depth, width_bits=f.width_bits))
    with_sram = [b for b in blocks if "sram" in b]
    sram_ok = all(b["sram"] is not None for b in with_sram)
    logic_mm2 = sum(b["logic"]["area_mm2"] for b in blocks if b["logic"])
    logic_mw = sum(b["logic"]["leakage_mw"] for b in blocks if b["logic"])
    sram_mm2 = sum(b["sram"]["area_mm2"] for b in with_sram) if sram_ok else None
    sram_mw = sum(b["sram"]["leakage_mw"] for b in with_sram) if sram_ok else None
    reasons = sorted({b["sram_reason"] for b in with_sram if b["sram"] is None})
    h, w = plan.shape
    return {
        "node": node_name, "node_description": n.description, "basis": BASIS,
        "frame": [w, h], "ge_area_um2": n.ge_area_um2, "ff_area_ge": n.ff_area_ge,
        "ge_leakage_nw": n.ge_leakage_nw, "ff_leakage_nw": n.ff_leakage_nw,
        "blocks": blocks,
        "totals": {"logic_mm2": logic_mm2, "sram_mm2": sram_mm2,
                   "chip_mm2": None if sram_mm2 is None else logic_mm2 + sram_mm2,
                   "logic_leakage_mw": logic_mw, "sram_leakage_mw": sram_mw,
                   "leakage_mw": None if sram_mw is None else logic_mw + sram_mw,
                   "nand2_logic": sum(b["logic"]["nand2_logic"] for b in blocks if b["logic"]),
                   "flip_flops": sum(b["logic"]["flip_flops"] for b in blocks if b["logic"]),
                   **({"sram_reason": reasons[0]} if reasons else {})},
        "not_costed": [{"block": b["name"], "logic": b["logic_reason"]} for b in blocks
                       if b["logic"] is None],
    }


def _mm2(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.4f}"


def format_area(area: dict) -> str:
    """The area as a text table: a line per block (identical idle submodules folded into one
    line with their count), then the totals."""
    out = [f"chip area at {area['node']} ({area['node_description']})",
           f"frame {area['frame'][0]}x{area['frame'][1]}; basis: {area['basis']}", "",
           f"{'block':28} {'use':7} {'GE logic':>11} {'flip-flops':>10} {'logic mm2':>10} "
           f"{'SRAM mm2':>9} {'total mm2':>9} {'leak mW':>8}"]
    rows: list[list] = []
    for b in area["blocks"]:
        lg, sr = b["logic"], b.get("sram")
        key = (b["kind"], b.get("use", ""), b["area_mm2"])
        if rows and rows[-1][0] == key and b["kind"] == "nna_submodule":
            rows[-1][1] += 1
            continue
        rows.append([key, 1, b, lg, sr])
    for _key, count, b, lg, sr in rows:
        name = b["name"] if count == 1 else f"{b['name']} (x{count}, each)"
        ge = format(lg["nand2_logic"], ",.0f") if lg else "-"
        ffs = format(lg["flip_flops"], ",.0f") if lg else "-"
        logic = _mm2(lg["area_mm2"]) if lg else "-"
        sram = (_mm2(sr["area_mm2"] if sr else None)) if "sram" in b else "-"
        out.append(f"{name:28} {b.get('use', ''):7} {ge:>11} {ffs:>10} {logic:>10} "
                   f"{sram:>9} {b['area_mm2']:>9.4f} {b['leakage_mw']:>8.3f}")
    t = area["totals"]
    out += ["", f"logic {_mm2(t['logic_mm2'])} mm2 ({t['nand2_logic']:,.0f} GE, "
            f"{t['flip_flops']:,.0f} flip-flops), SRAM {_mm2(t['sram_mm2'])} mm2, chip "
            f"{_mm2(t['chip_mm2'])} mm2; leakage logic {t['logic_leakage_mw']:.2f} mW, SRAM "
            + ("n/a" if t["sram_leakage_mw"] is None else f"{t['sram_leakage_mw']:.2f} mW")
            + ", chip " + ("n/a" if t["leakage_mw"] is None else f"{t['leakage_mw']:.2f} mW")]
    if "sram_reason" in t:
        out.append(f"SRAM: {t['sram_reason']}")
    seen = set()
    for b in area["blocks"]:
        if b["logic"] and b["kind"] not in seen:
            out.append(f"logic of {b['name']}: {b['logic']['source']}")
            if b["kind"] == "nna_submodule":
                seen.add(b["kind"])
    reasons: dict[str, list[str]] = {}
    for nc in area["not_costed"]:
        reasons.setdefault(nc["logic"], []).append(nc["block"])
    for why, names in reasons.items():
        out.append(f"no logic figure for {', '.join(names)}: {why}")
    return "\n".join(out)


def _total(b: dict) -> float | None:
    """A block's area, None where its SRAM has no figure at the node."""
    return None if "sram" in b and b["sram"] is None else b["area_mm2"]


def _group(blocks: list[dict]) -> str:
    """``blocks``' area: total, logic and SRAM apart ("n/a" where the node has no SRAM figure
    for one of them, "-" where none of them has that part)."""
    logics = [b["logic"]["area_mm2"] for b in blocks if b["logic"]]
    srams = [b["sram"] for b in blocks if "sram" in b]
    sram = None if any(s is None for s in srams) else sum(s["area_mm2"] for s in srams)
    total = None if sram is None else sum(logics) + sram
    logic = _mm2(sum(logics)) if logics else "-"
    return (f"{_mm2(total)} mm2 (logic {logic}, SRAM "
            f"{_mm2(sram) if srams else '-'})")


def _not_costed(area: dict) -> str:
    """The blocks without a logic figure: FIFOs and merges counted, SVA stages named."""
    kinds = {b["name"]: b["kind"] for b in area["blocks"]}
    names = [nc["block"] for nc in area["not_costed"]]
    out = []
    for kind, what in (("nna_submodule", "NNA submodules"), ("merge", "merges"),
                       ("fifo", "FIFOs")):
        n = sum(kinds[x] == kind for x in names)
        if n:
            out.append(f"{n} {what}")
    out += [x for x in names if kinds[x] == "sva_stage"]
    return ", ".join(out)


def area_rows(area: dict) -> list[tuple[str, str]]:
    """The area in a few (what, figures) rows, for ``estimate`` and a run's summary: the chip
    (logic and SRAM apart, and its leakage), the NNA submodules by use, the SVA stages (each
    with its area), the FIFOs, and the blocks whose logic is not costed."""
    t = area["totals"]
    leak = "n/a" if t["leakage_mw"] is None else f"{t['leakage_mw']:,.2f} mW"
    sram = f"{_mm2(t['sram_mm2'])} mm2"
    if t["sram_mm2"] is None:
        sram = f"not available ({t.get('sram_reason', 'no SRAM figure at this node')})"
    chip = "n/a" if t["chip_mm2"] is None else f"{_mm2(t['chip_mm2'])} mm2"
    rows = [("chip", f"{chip}: logic {_mm2(t['logic_mm2'])} mm2 ({t['nand2_logic']:,.0f} GE, "
             f"{t['flip_flops']:,.0f} flip-flops), SRAM {sram}; leakage {leak} (logic "
             f"{t['logic_leakage_mw']:,.2f} mW)")]
    blocks = area["blocks"]
    for use in ("stereo", "lent", "idle"):
        subs = [b for b in blocks if b["kind"] == "nna_submodule" and b.get("use") == use]
        if subs:
            rows.append((f"NNA submodules, {use}", f"{len(subs)}: {_group(subs)}"))
    stages = [b for b in blocks if b["kind"] == "sva_stage"]
    if stages:
        each = ", ".join(f"{b['name'].removeprefix('sva.')} {_mm2(_total(b))}"
                         for b in stages if b["logic"] or "sram" in b)
        rows.append(("SVA stages", f"{_group(stages)}: {each}"))
    fifos = [b for b in blocks if b["kind"] == "fifo"]
    if fifos:
        rows.append(("FIFOs", f"{len(fifos)}: {_group(fifos)}"))
    if area["not_costed"]:
        rows.append(("logic not costed", f"{_not_costed(area)} (no RTL, or outside a checked "
                     "area rule: docs/area.md)"))
    return rows


def area_lines(area: dict) -> list[str]:
    """:func:`area_rows` as lines ``area <what>: <figures>``, the first naming the node."""
    return [f"area at {area['node']}, {what}: {figs}" if i == 0 else f"area, {what}: {figs}"
            for i, (what, figs) in enumerate(area_rows(area))]


def main(argv: list[str] | None = None) -> int:
    """``python -m stereosim.sim.cycle.area [--config FILE] [--node 45nm] [--json]``."""
    ap = argparse.ArgumentParser(prog="python -m stereosim.sim.cycle.area",
                                 description="the chip's area and leakage by block")
    ap.add_argument("--config", default=None, help="a TOML configuration (default: defaults)")
    ap.add_argument("--node", default="45nm", help="technology node (130nm, 45nm, 7nm)")
    ap.add_argument("--json", action="store_true", help="print the dict as JSON")
    args = ap.parse_args(argv)
    cfg = load_config(args.config)
    area = chip_area(build_plan(cfg, frame_size(cfg)), args.node)
    print(json.dumps(area, indent=1) if args.json else format_area(area))
    return 0


if __name__ == "__main__":
    sys.exit(main())
