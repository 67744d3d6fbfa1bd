"""The chip plan drawn: its clock domains, blocks and FIFOs as a text listing and as a picture,
both read off a :class:`~sim.cycle.plan.ChipPlan` (nothing here knows the topology).

    stereosim config plan [--size WxH] [--set KEY=VALUE ...] [--png PATH]

:func:`plan_text` lists every domain (frequency, period, blocks), every block (kind, domain,
items, cycles per item, latency, buffers) and every FIFO as ``producer --name--> consumer`` with
its depth, width, configuration key and, for a crossing, the edges after which data and free
slots are seen, then the chip's SRAM (:func:`~sim.cycle.figures.chip_sram`: every instance counted
once, by block and by kind; one NNA submodule's labelled as such), the lent network and the
run's cycle budget per clock domain; :func:`plan_png` draws the blocks as boxes coloured by
domain in pipeline columns (a frame-buffered camera and its DRAM, source, NNA, merge, SVA, sink)
with the FIFOs as arrows (dashed where they cross domains), each FIFO's label on its arrow where
it overlaps no block and no other label, and the lent network's submodules below. The picture
stays under 1,500 px tall whatever the counts: a camera's submodules (and the lent ones) are a
box each up to :data:`MAX_DRAWN`, one stacked box marked "x N" beyond. docs/architecture.md
opens with both, for the default chip.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

from stereosim.core.errors import InputError
from stereosim.core.outputs import atomic_write_bytes
from stereosim.sim.cycle.figures import chip_sram, sram_bits
from stereosim.sim.cycle.lent import lent_lines, lent_report
from stereosim.sim.cycle.plan import BlockPlan, ChipPlan

DOMAIN_COLOURS = {"camera": "#f4d35e", "nna": "#9ad1d4", "sva": "#f7a072"}


def _fs(n: int) -> str:
    return f"{n:,}"


def _edges(n: int) -> str:
    return f"{n} edge" + ("s" if n != 1 else "")


def _block_line(plan: ChipPlan, b: BlockPlan) -> str:
    parts = [f"{b.kind}", f"{b.items:,} items"]
    if b.kind in ("nna", "sva"):
        parts.append(f"{b.ii} cycles/item")
    if b.kind == "nna":
        t = b.tile
        parts.append(f"window +-{b.half} rows, line buffer {b.rows} rows")
        if plan.parts > 1:
            parts.append(f"tile x {t.x0}..{t.x1 - 1}, y {t.y0}..{t.y1 - 1}")
    if b.kind == "sva":
        parts.append(f"look-ahead {b.lookahead} rows, {b.passes} passes, slot II "
                     f"{b.slot_ii}, median skew {b.skew} words, latency {b.latency}")
    if b.kind == "memory":
        parts.append(f"{b.bytes_per_s / 1e9:g} GB/s")
    if b.kind == "camera":
        parts.append(f"{b.line_clocks} clocks/line, {b.frame_clocks:,} clocks/frame")
    buffers = ", ".join(f"{buf.name} {buf.bits:,} b" for buf in b.buffers)
    if buffers:
        parts.append(f"SRAM: {buffers}")
    lines = [f"  {b.name:<14} [{b.domain}] " + "; ".join(parts)]
    if len(b.layers) > 1:  # the layer pipeline, one stage a layer
        for lay in b.layers:
            k, t = 2 * lay.half + 1, lay.tile
            lines.append(f"    layer {lay.index}: {k}x{k}x{lay.channels_in}x{lay.channels_out}, "
                         f"{lay.macs_per_pixel} MACs/pixel on {lay.macs} MACs, {lay.ii} "
                         f"cycles/pixel; line buffer {lay.rows} rows; output x {t.x0}..{t.x1 - 1}"
                         f", y {t.y0}..{t.y1 - 1}")
    return "\n".join(lines)


def _sram_lines(plan: ChipPlan) -> list[str]:
    """The chip's SRAM (:func:`~sim.cycle.figures.chip_sram`: every instance counted once) by
    block and by kind, then one NNA submodule's, labelled as one instance."""
    sram = chip_sram(plan)
    per_sub = sram["nna_per_submodule"]
    names = {"nna_stereo": "NNA stereo", "nna_lent": "NNA lent", "nna_idle": "NNA idle",
             "sva": "SVA", "fifos": "FIFOs"}
    counts = sram["nna_instances"]
    blocks = []
    for key, bits in sram["by_block"].items():
        if key in counts:
            if counts[key]:
                blocks.append(f"{names[key]} {counts[key]} x {per_sub:,} = {bits:,}")
        else:
            blocks.append(f"{names[key]} {bits:,}")
    one = ", ".join(f"{k} {v:,}" for k, v in sram_bits(plan).items() if k.startswith("nna."))
    return [f"SRAM on the chip: {sram['total']:,} bits ({sram['total'] / 1e6:.2f} Mbit), "
            f"every instance counted once",
            "  by block: " + "; ".join(blocks),
            "  by kind: " + "; ".join(f"{k} {v:,}" for k, v in sram["by_kind"].items()),
            f"  one NNA submodule (each of the {sram['nna_submodules']}, sized for the widest "
            f"tile): {per_sub:,} bits ({one})"]


def plan_text(plan: ChipPlan) -> str:
    """The plan as a deterministic text listing (domains, blocks, FIFOs, SRAM, and the cycle
    budget: the cycles of each clock domain a run may take before it stops)."""
    cfg = plan.cfg
    h, w = plan.shape
    bits = (f"{plan.descriptor_bits} bits" if not plan.hybrid else
            " + ".join(f"{b} {k}" for k, b in plan.descriptor_parts) + " bits, cost "
            + " + ".join(f"{w} x {k}" for (k, _), w in zip(plan.descriptor_parts,
                                                           cfg.sva.cost_weights, strict=True))
            + (" (auto weights)" if cfg.sva.weight_mode == "auto" else ""))
    lines = [f"chip plan: {w}x{h}, {cfg.nna.descriptor} descriptor ({bits}), "
             f"D = {cfg.sva.disparities}, {plan.parts} NNA submodule"
             f"{'s' if plan.parts > 1 else ''} per camera"
             + (f" ({cfg.nna.split})" if plan.parts > 1 else "")
             + f", {cfg.source.kind} source",
             "clock domains:"]
    for d in plan.domains.values():
        members = ", ".join(b.name for b in plan.blocks if b.domain == d.name)
        lines.append(f"  {d.name:<7} {d.freq_hz / 1e6:9.3f} MHz  period {_fs(d.period_fs):>12} fs"
                     f"  {members}")
    lines.append("blocks:")
    lines += [_block_line(plan, b) for b in plan.blocks]
    lines.append("FIFOs (producer --name--> consumer: depth x width, key; when seen):")
    for f in plan.fifos:
        where = f"crosses {f.src}->{f.dst}" if f.crossing else f"in {f.dst}"
        seen = (f"{where}: data seen after {_edges(f.data_edges)}, free slots after "
                f"{_edges(f.space_edges)}")
        lines.append(f"  {f.producer} --{f.name}--> {f.consumer}: {f.depth} x {f.width_bits} "
                     f"bits, {f.key}; {seen}")
    lines += _sram_lines(plan)
    if plan.lent is not None:
        lines += lent_lines(lent_report(plan.lent, plan.dram, h * w))
    how = "sim.max_cycles" if plan.cfg.sim.max_cycles else "automatic, sim.max_cycles = 0"
    lines.append(f"cycle budget ({how}; a run stops after this many cycles of each clock): "
                 + ", ".join(f"{k} {v:,} cycles" for k, v in sorted(plan.budget.items())))
    return "\n".join(lines) + "\n"


MAX_DRAWN = 4  # submodules of a camera (or of the lent network) drawn a box each; more: one box
UNIT_IN = 0.75  # inches per plot unit, both axes
TOP_IN = 1.0  # inches above the blocks for the title and the legend
COLUMN_STEP = 4.0  # plot units between pipeline columns joined by FIFOs (a box is BOX_W wide)
NEAR_STEP = 2.4  # between the camera, its DRAM frame buffers and the memory source (no FIFO)
ROW_STEP = 1.6
BOX_W, BOX_H = 1.9, 0.75
STACK = 0.09  # offset of each shadow of a stacked box ("x N")
LENT_GAP = 0.1  # extra plot units between the stereo pair's rows and the lent network's
LENT_STEP = 1.15  # between the lent submodules (their arrows carry no label)
DRAM_COLOUR = "#d9d9d9"
# where along its arrow a FIFO's label may sit (0: the producer's edge, 1: the consumer's),
# in the order tried
LABEL_SPOTS = (0.5, 0.35, 0.65, 0.2, 0.8, 0.1, 0.9)


@dataclass(frozen=True)
class _Node:
    """A box of the picture: one block, a stack of submodules ("x N"), or DRAM."""

    name: str
    members: tuple[str, ...]  # the plan's blocks it stands for (none: DRAM)
    domain: str | None  # its clock domain (None: DRAM, outside the chip's clocks)
    x: float
    y: float
    detail: str
    count: int = 1


@dataclass(frozen=True)
class _Edge:
    """An arrow: the FIFOs it stands for (none: a DRAM access) and its label."""

    src: str
    dst: str
    fifos: tuple[str, ...] = ()
    label: str = ""
    crossing: bool = False
    vertical: bool = False  # from the bottom of src to the top of dst (the lent pipeline)
    both_ways: bool = False


@dataclass
class Picture:
    """What the plan picture drew, in display pixels (x0, y0, x1, y1): its boxes by drawn name
    with the plan blocks each stands for and its clock domain, its FIFO labels with the FIFOs
    each names, its text boxes (the lent network's note), and every text it shows."""

    boxes: dict[str, tuple[float, float, float, float]]
    members: dict[str, tuple[str, ...]]
    domains: dict[str, str | None]
    labels: dict[str, tuple[float, float, float, float]]
    label_fifos: dict[str, tuple[str, ...]]
    notes: dict[str, tuple[float, float, float, float]]
    texts: list[str]


def _span(names: list[str]) -> str:
    """Names that differ in one number, shortened: nna_left0 .. nna_left4 -> nna_left0..4,
    nna_left0_to_merge .. nna_left4_to_merge -> nna_left0..4_to_merge."""
    first, last = names[0], names[-1]
    if len(names) == 1:
        return first
    pre = 0
    while pre < min(len(first), len(last)) and first[pre] == last[pre]:
        pre += 1
    while pre and first[pre - 1].isdigit():  # keep a shared leading digit with its number
        pre -= 1
    suf = 0
    while (suf < min(len(first), len(last)) - pre
           and first[len(first) - 1 - suf] == last[len(last) - 1 - suf]):
        suf += 1
    while suf and first[len(first) - suf].isdigit():
        suf -= 1
    end = len(first) - suf
    return f"{first[:pre]}{first[pre:end]}..{last[pre:len(last) - suf]}{first[end:]}"


def _columns(plan: ChipPlan) -> dict[str, float]:
    """The x of each column present: a frame-buffered camera, its DRAM, the source, the NNA,
    the merge (split frames), the SVA, the sink."""
    order = (["camera", "dram"] if plan.frame_buffered else []) + ["source", "nna"]
    order += (["merge"] if plan.parts > 1 else []) + ["sva", "sink"]
    xs, x = {}, 0.0
    for col in order:
        xs[col] = x
        x += NEAR_STEP if col in ("camera", "dram") else COLUMN_STEP
    return xs


def _layout(plan: ChipPlan) -> tuple[list[_Node], list[_Edge], list[str]]:
    """The picture's boxes, arrows and the lent network's note, in plot units: the left
    camera's blocks above the right camera's, a camera's submodules stacked (one box "x N"
    beyond :data:`MAX_DRAWN`), the shared blocks centred; a frame-buffered camera, its DRAM
    and the memory source that reads it side by side; the lent submodules below, fed from
    DRAM, as a layer pipeline."""
    xs = _columns(plan)
    parts = plan.parts
    grouped = parts > MAX_DRAWN
    per_side = 1 if grouped else parts
    rows = 2 * per_side
    column = {"memory": "source", "camera": "camera" if plan.frame_buffered else "source"}
    nodes: dict[str, _Node] = {}
    drawn_as: dict[str, str] = {}  # plan block -> node
    subs: dict[int, list] = {0: [], 1: []}
    for b in plan.blocks:
        if b.kind == "nna":
            subs[b.side].append(b)
    for b in plan.blocks:
        x = xs[column.get(b.kind, b.kind)]
        if b.side is None:
            y = (rows - 1) / 2
        elif b.kind == "nna" and not grouped:
            y = b.side * per_side + plan.tiles.index(b.tile)
        else:
            y = b.side * per_side + (per_side - 1) / 2
        if b.kind == "nna" and grouped:
            group = subs[b.side]
            name = _span([g.name for g in group])
            drawn_as[b.name] = name
            if name in nodes:
                continue
            items = sorted({g.items for g in group})
            each = (f"{items[0]:,} items each" if len(items) == 1
                    else f"{items[0]:,}-{items[-1]:,} items")
            nodes[name] = _Node(name, tuple(g.name for g in group), b.domain, x, -y * ROW_STEP,
                                f"{each}, {b.ii} cyc", len(group))
            continue
        if b.kind == "camera":
            detail = (f"{plan.domains[b.domain].freq_hz / 1e6:g} MHz, {b.line_clocks}x"
                      f"{b.frame_clocks // b.line_clocks} clocks")
        elif b.kind == "memory":
            detail = f"{b.items:,} items, {b.bytes_per_s / 1e9:g} GB/s"
        else:
            detail = f"{b.items:,} items" + (f", {b.ii} cyc" if b.kind in ("nna", "sva")
                                             else "")
        drawn_as[b.name] = b.name
        nodes[b.name] = _Node(b.name, (b.name,), b.domain, x, -y * ROW_STEP, detail)
    edges: list[_Edge] = []
    if plan.frame_buffered:
        for mem in plan.blocks_of("memory"):
            dram = f"dram_{mem.feed.removeprefix('camera_')}"
            cam = nodes[mem.feed]
            nodes[dram] = _Node(dram, (), None, xs["dram"], cam.y,
                                f"{mem.frame_buffers} frame buffer"
                                + ("s" if mem.frame_buffers != 1 else ""))
            edges += [_Edge(mem.feed, dram), _Edge(dram, mem.name)]
    by_pair: dict[tuple[str, str], list] = {}
    for f in plan.fifos:
        by_pair.setdefault((drawn_as[f.producer], drawn_as[f.consumer]), []).append(f)
    for (src, dst), fifos in by_pair.items():
        f = fifos[0]
        label = (f"{_span([g.name for g in fifos])}\n{f.depth} x {f.width_bits} b"
                 + (" (CDC)" if f.crossing else "") + (f", x {len(fifos)}" if len(fifos) > 1
                                                       else ""))
        edges.append(_Edge(src, dst, tuple(g.name for g in fifos), label, f.crossing))
    notes = []
    if plan.lent is not None:
        notes = _lent_layout(plan, xs, rows, nodes, edges)
    return list(nodes.values()), edges, notes


def _lent_layout(plan: ChipPlan, xs: dict[str, float], rows: int, nodes: dict,
                 edges: list) -> list[str]:
    """The lent submodules (a box each, or one "x N" beyond :data:`MAX_DRAWN`) below the
    stereo pair's rows in the NNA column, each stage feeding the next, DRAM beside them; the
    note: the network, its frame rate and DRAM load (:func:`~sim.cycle.lent.lent_report`)."""
    lent = plan.lent
    h, w = plan.shape
    rep = lent_report(lent, plan.dram, h * w)
    used = lent.used
    grouped = used > MAX_DRAWN
    top = rows * ROW_STEP + LENT_GAP
    if grouped:
        layers = len(lent.layers)
        names = [f"lent{s}" for s in range(used)]
        name = _span(names)
        nodes[name] = _Node(name, (), "nna", xs["nna"], -top,
                            f"{layers} layers, <= {lent.frame_cycles:,} cyc",
                            used)
        stages = [name]
    else:
        stages = []
        for s in range(used):
            group = lent.group(s)
            first, last = group[0].index, group[-1].index
            which = f"layer {first}" if first == last else f"layers {first}-{last}"
            name = f"lent{s}"
            nodes[name] = _Node(name, (), "nna", xs["nna"], -(top + s * LENT_STEP),
                                f"{which}, {lent.submodule_cycles[s]:,} cyc")
            stages.append(name)
        edges += [_Edge(a, b, vertical=True) for a, b in zip(stages, stages[1:])]
    mid = (nodes[stages[0]].y + nodes[stages[-1]].y) / 2
    nodes["dram_lent"] = _Node("dram_lent", (), None, xs["source"], mid,
                               "input, spills, output")
    edges += [_Edge("dram_lent", s, both_ways=True) for s in stages]
    per_frame = rep["dram_bytes_per_frame"]["total"]
    idle = (plan.cfg.nna.submodules - plan.cfg.nna.stereo_submodules
            - plan.cfg.nna.lent_submodules)
    note = [f"lent network {Path(rep['file']).name}: {rep['input']['width']}x"
            f"{rep['input']['height']}x{rep['input']['channels']}, {len(rep['layers'])} layers",
            f"on {rep['submodules_used']} of {rep['submodules_lent']} lent submodules"
            f" ({idle} idle)",
            f"{rep['fps']:,.1f} fps ({rep['fps_max']:,.1f} at most, {rep['busy_percent']:.1f} % "
            f"busy)",
            f"DRAM {per_frame:,} bytes a frame, {rep['dram_gbps']:.3f} GB/s"]
    st = rep["stereo_pair"]
    if st["dram_channel"]:
        note.append(f"stereo read-bound fps {st['read_bound_fps']:,.1f} "
                    f"(without it {st['read_bound_fps_without_lent']:,.1f})")
    return ["\n".join(note)]


def _box(extent) -> tuple[float, float, float, float]:
    return (extent.x0, extent.y0, extent.x1, extent.y1)


def _union(a, b) -> tuple[float, float, float, float]:
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _draw(plan: ChipPlan):
    """The plan's figure and what it drew (:class:`Picture`). Each FIFO label sits on its
    arrow at the first of :data:`LABEL_SPOTS` where it overlaps no box and no label placed
    before it (else at the middle)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch, Patch

    plt.rcParams.update({"svg.hashsalt": "stereosim", "path.simplify": False})
    nodes, edges, notes = _layout(plan)
    at = {n.name: n for n in nodes}
    x_lo = min(n.x for n in nodes) - BOX_W / 2 - 0.4
    x_hi = max(n.x for n in nodes) + BOX_W / 2 + 0.4
    y_hi = max(n.y for n in nodes) + BOX_H / 2 + 0.3
    y_lo = min(n.y for n in nodes) - BOX_H / 2 - 0.3
    width_in, height_in = (x_hi - x_lo) * UNIT_IN, (y_hi - y_lo) * UNIT_IN
    fig = plt.figure(figsize=(width_in, height_in + TOP_IN), dpi=100)
    ax = fig.add_axes((0, 0, 1, height_in / (height_in + TOP_IN)))
    ax.set_xlim(x_lo, x_hi)
    ax.set_ylim(y_lo, y_hi)
    ax.axis("off")
    texts: list[str] = []
    patches = {}
    for n in nodes:
        colour = DOMAIN_COLOURS.get(n.domain, "#dddddd") if n.domain else DRAM_COLOUR
        shadows = [ax.add_patch(FancyBboxPatch(
            (n.x - BOX_W / 2 + k * STACK, n.y - BOX_H / 2 + k * STACK), BOX_W, BOX_H,
            boxstyle="round,pad=0.05", fc=colour, ec="black", zorder=1 - 0.1 * k))
            for k in ((2, 1) if n.count > 1 else ())]
        patches[n.name] = [*shadows, ax.add_patch(FancyBboxPatch(
            (n.x - BOX_W / 2, n.y - BOX_H / 2), BOX_W, BOX_H, boxstyle="round,pad=0.05",
            fc=colour, ec="black", zorder=1))]
        title = ("DRAM" if n.domain is None else n.name) + (f" (x {n.count})" if n.count > 1
                                                             else "")
        patches[n.name] += [
            ax.text(n.x, n.y + 0.13, title, ha="center", va="center", fontsize=9,
                    weight="bold", zorder=2),
            ax.text(n.x, n.y - 0.17, n.detail, ha="center", va="center", fontsize=7, zorder=2)]
        texts += [title, n.detail]
    legend = [Patch(fc=DOMAIN_COLOURS.get(d.name, "#dddddd"), ec="black",
                    label=f"{d.name} domain, {d.freq_hz / 1e6:g} MHz")
              for d in plan.domains.values()]
    if any(n.domain is None for n in nodes):
        legend.append(Patch(fc=DRAM_COLOUR, ec="black", label="DRAM (off chip)"))
    ax.legend(handles=legend, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=len(legend),
              fontsize=8, frameon=False)
    texts += [p.get_label() for p in legend]
    h, w = plan.shape
    n = plan.cfg.nna
    title = (f"stereosim chip plan: {w}x{h}, {n.descriptor}, D = {plan.cfg.sva.disparities}, "
             f"{plan.parts} NNA submodule{'s' if plan.parts > 1 else ''} per camera "
             f"({n.stereo_submodules} of {n.submodules} on the stereo pair"
             + (f", {n.lent_submodules} lent" if n.lent_submodules else "")
             + ")\n(dashed: FIFO crossing clock domains"
             + ("; x N: N submodules drawn as one" if any(m.count > 1 for m in nodes) else "")
             + ")")
    ax.set_title(title, fontsize=10, pad=28)
    texts.append(title)
    renderer = fig.canvas.get_renderer()
    boxes = {}
    for name, ps in patches.items():
        box = _box(ps[0].get_window_extent(renderer))
        for p in ps[1:]:
            box = _union(box, _box(p.get_window_extent(renderer)))
        boxes[name] = box
    note_boxes = {}
    if notes:
        lent0 = next(m for m in nodes if m.name.startswith("lent"))
        stages = [m for m in nodes if m.name.startswith("lent")]
        mid = (stages[0].y + stages[-1].y) / 2
        text = ax.text(lent0.x + BOX_W / 2 + 0.6, mid, notes[0], ha="left", va="center",
                       fontsize=8, zorder=3, bbox=dict(fc="#eef6f6", ec="0.5", pad=4))
        note_boxes["lent_network"] = _box(text.get_window_extent(renderer))
        texts.append(notes[0])
    labels: dict[str, tuple[float, float, float, float]] = {}
    label_fifos: dict[str, tuple[str, ...]] = {}
    for e in edges:
        a, b = at[e.src], at[e.dst]
        if e.vertical:
            start, end = (a.x, a.y - BOX_H / 2 - 0.05), (b.x, b.y + BOX_H / 2 + 0.05)
        else:
            shadow = 2 * STACK if a.count > 1 else 0.0  # leave from the stack's last box
            start, end = (a.x + BOX_W / 2 + shadow + 0.05, a.y), (b.x - BOX_W / 2 - 0.05, b.y)
        style = "<|-|>" if e.both_ways else "-|>"
        ax.annotate("", xy=end, xytext=start,
                    arrowprops=dict(arrowstyle=style, lw=1.2,
                                    color="black" if e.fifos else "0.35",
                                    linestyle="--" if e.crossing else "-"))
        if not e.fifos:
            continue
        chosen = None
        for t in LABEL_SPOTS:
            text = ax.text(start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1]),
                           e.label, ha="center", va="center", fontsize=6.5, zorder=3,
                           bbox=dict(fc="white", ec="none", alpha=0.85, pad=0.5))
            box = _box(text.get_window_extent(renderer))
            others = [*boxes.values(), *note_boxes.values(), *labels.values()]
            clear = not any(_overlap(box, o) for o in others)
            if clear or chosen is None:
                if chosen is not None:
                    chosen[0].remove()
                chosen = (text, box)
            else:
                text.remove()
            if clear:
                break
        name = e.label.split("\n")[0]
        labels[name] = chosen[1]
        label_fifos[name] = e.fifos
        texts.append(e.label)
    picture = Picture(boxes=boxes, members={m.name: m.members for m in nodes},
                      domains={m.name: m.domain for m in nodes}, labels=labels,
                      label_fifos=label_fifos, notes=note_boxes, texts=texts)
    return plt, fig, picture


def picture_layout(plan: ChipPlan) -> Picture:
    """What the plan picture draws and where (:class:`Picture`): what a test checks for
    overlaps, missing blocks, FIFOs and clock domains."""
    plt, fig, picture = _draw(plan)
    plt.close(fig)
    return picture


def plan_png(plan: ChipPlan) -> bytes:
    """The plan drawn: blocks coloured by clock domain, FIFOs as labelled arrows, each label
    on its arrow where it overlaps no block and no other label; a frame-buffered camera, its
    DRAM frame buffers and the memory source that reads them as three boxes; a camera's
    submodules a box each up to :data:`MAX_DRAWN`, beyond it one stacked box marked "x N" (so
    a side takes at most :data:`MAX_DRAWN` rows and the picture's height stays bounded
    whatever ``nna.stereo_submodules``: under 1,500 px); the lent network's submodules below
    them (the same rule), with its frame rate and DRAM load."""
    plt, fig, _ = _draw(plan)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def write_plan_png(plan: ChipPlan, path: str | Path) -> None:
    """:func:`plan_png` written atomically to ``path`` (its folder must exist)."""
    p = Path(path)
    if not p.parent.is_dir():
        raise InputError(f"folder {p.parent} of {p} does not exist: create it first")
    atomic_write_bytes(p, plan_png(plan))
