"""The chip plan drawn: its clock domains, blocks and FIFOs as a text listing and as a picture,
both read off a :class:`~sim.cycle.plan.ChipPlan` (nothing here knows the topology).

    stereosim config plan [--size WxH] [--set KEY=VALUE ...] [--png PATH]

:func:`plan_text` lists every domain (frequency, period, blocks), every block (kind, domain,
items, cycles per item, latency, buffers) and every FIFO as ``producer --name--> consumer`` with
its depth, width, configuration key and, for a crossing, the edges after which data and free
slots are seen, then the SRAM and the run's cycle budget per clock domain; :func:`plan_png`
draws the blocks as boxes coloured by domain in pipeline columns (source, NNA, merge, SVA, sink)
with the FIFOs as arrows (dashed where they cross domains), each FIFO's label on its arrow where
it overlaps no block and no other label. docs/architecture.md opens with both, for the default
chip.
"""

from __future__ import annotations

import io
from pathlib import Path

from stereosim.sim.cycle.lent import lent_lines, lent_report
from stereosim.sim.cycle.plan import BlockPlan, ChipPlan, sram_bits
from stereosim.sim.errors import InputError
from stereosim.sim.outputs import atomic_write_bytes

COLUMNS = {"memory": 0, "camera": 0, "nna": 1, "merge": 2, "sva": 3, "sink": 4}
DOMAIN_COLOURS = {"camera": "#f4d35e", "nna": "#9ad1d4", "sva": "#f7a072"}


def _fs(n: int) -> str:
    return f"{n:,}"


def _edges(n: int) -> str:
    return f"{n} edge" + ("s" if n != 1 else "")


def _block_line(plan: ChipPlan, b: BlockPlan) -> str:
    parts = [f"{b.kind}", f"{b.items:,} items"]
    if b.kind in ("nna", "sva"):
        parts.append(f"{b.cycles} cycles/item")
    if b.kind == "nna":
        t = b.tile
        parts.append(f"window +-{b.half} rows, line buffer {b.rows} rows")
        if plan.parts > 1:
            parts.append(f"tile x {t.x0}..{t.x1 - 1}, y {t.y0}..{t.y1 - 1}")
    if b.kind == "sva":
        parts.append(f"look-ahead {b.lookahead} rows, latency {b.latency}")
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
                         f"{lay.macs_per_pixel} MACs/pixel on {lay.macs} MACs, {lay.cycles} "
                         f"cycles/pixel; line buffer {lay.rows} rows; output x {t.x0}..{t.x1 - 1}"
                         f", y {t.y0}..{t.y1 - 1}")
    return "\n".join(lines)


def plan_text(plan: ChipPlan) -> str:
    """The plan as a deterministic text listing (domains, blocks, FIFOs, SRAM, and the cycle
    budget: the cycles of each clock domain a run may take before it stops)."""
    cfg = plan.cfg
    h, w = plan.shape
    lines = [f"chip plan: {w}x{h}, {cfg.nna.descriptor} descriptor ({plan.descriptor_bits} "
             f"bits), D = {cfg.sva.disparities}, {plan.parts} NNA submodule"
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
    total = sum(sram_bits(plan).values())
    lines.append(f"SRAM per instance: {total:,} bits over {len(sram_bits(plan))} buffers")
    if plan.lent is not None:
        lines += lent_lines(lent_report(plan.lent, plan.dram, h * w))
    how = "sim.max_cycles" if plan.cfg.sim.max_cycles else "automatic, sim.max_cycles = 0"
    lines.append(f"cycle budget ({how}; a run stops after this many cycles of each clock): "
                 + ", ".join(f"{k} {v:,} cycles" for k, v in sorted(plan.budget.items())))
    return "\n".join(lines) + "\n"


COLUMN_STEP = 4.0  # plot units between pipeline columns (a box is BOX_W wide)
ROW_STEP = 1.6
BOX_W, BOX_H = 1.7, 0.75
# where along its arrow a FIFO's label may sit (0: the producer's edge, 1: the consumer's),
# in the order tried
LABEL_SPOTS = (0.5, 0.35, 0.65, 0.2, 0.8, 0.1, 0.9)


def _positions(plan: ChipPlan) -> dict[str, tuple[float, float]]:
    """(column, row) of every block: the left side's blocks above the right side's, the
    submodules of a side stacked, the shared blocks centred."""
    rows = 2 * plan.parts
    pos = {}
    for b in plan.blocks:
        x = COLUMNS[b.kind]
        if b.side is None:
            y = (rows - 1) / 2
        elif b.kind == "nna":
            y = b.side * plan.parts + plan.tiles.index(b.tile)
        else:
            y = b.side * plan.parts + (plan.parts - 1) / 2
        pos[b.name] = (x * COLUMN_STEP, -y * ROW_STEP)
    return pos


def _box(extent) -> tuple[float, float, float, float]:
    return (extent.x0, extent.y0, extent.x1, extent.y1)


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _draw(plan: ChipPlan):
    """The plan's figure, and the display boxes (x0, y0, x1, y1 in pixels) of its blocks and
    of its FIFO labels, by name. Each label sits on its arrow at the first of
    :data:`LABEL_SPOTS` where it overlaps no block and no label placed before it (else at the
    middle)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch, Patch

    plt.rcParams.update({"svg.hashsalt": "stereosim", "path.simplify": False})
    pos = _positions(plan)
    n_rows = 2 * plan.parts
    fig, ax = plt.subplots(figsize=(15, 1.9 + 1.25 * n_rows), dpi=100)
    bw, bh = BOX_W, BOX_H
    patches = {}
    for b in plan.blocks:
        x, y = pos[b.name]
        patches[b.name] = ax.add_patch(FancyBboxPatch(
            (x - bw / 2, y - bh / 2), bw, bh, boxstyle="round,pad=0.05",
            fc=DOMAIN_COLOURS.get(b.domain, "#dddddd"), ec="black"))
        detail = f"{b.items:,} items" + (f", {b.cycles} cyc" if b.kind in ("nna", "sva") else "")
        ax.text(x, y + 0.12, b.name, ha="center", va="center", fontsize=9, weight="bold")
        ax.text(x, y - 0.17, detail, ha="center", va="center", fontsize=7)
    legend = [Patch(fc=DOMAIN_COLOURS.get(d.name, "#dddddd"), ec="black",
                    label=f"{d.name} domain, {d.freq_hz / 1e6:g} MHz")
              for d in plan.domains.values()]
    ax.legend(handles=legend, loc="upper center", bbox_to_anchor=(0.5, 1.0), ncol=len(legend),
              fontsize=8, frameon=False)
    h, w = plan.shape
    ax.set_title(f"stereosim chip plan: {w}x{h}, {plan.cfg.nna.descriptor}, "
                 f"D = {plan.cfg.sva.disparities}, {plan.parts} NNA submodule"
                 f"{'s' if plan.parts > 1 else ''} per camera "
                 f"(dashed: FIFO crossing clock domains)", fontsize=10, pad=22)
    ax.set_xlim(-1.2, 4 * COLUMN_STEP + 1.2)
    ax.set_ylim(-(n_rows - 1) * ROW_STEP - 0.9, 1.0)
    ax.axis("off")
    renderer = fig.canvas.get_renderer()
    blocks = {name: _box(p.get_window_extent(renderer)) for name, p in patches.items()}
    labels: dict[str, tuple[float, float, float, float]] = {}
    for f in plan.fifos:
        (x0, y0), (x1, y1) = pos[f.producer], pos[f.consumer]
        start, end = (x0 + bw / 2 + 0.05, y0), (x1 - bw / 2 - 0.05, y1)
        ax.annotate("", xy=end, xytext=start,
                    arrowprops=dict(arrowstyle="-|>", lw=1.2, color="black",
                                    linestyle="--" if f.crossing else "-"))
        label = f"{f.name}\n{f.depth} x {f.width_bits} b" + (" (CDC)" if f.crossing else "")
        chosen = None
        for t in LABEL_SPOTS:
            text = ax.text(start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1]),
                           label, ha="center", va="center", fontsize=6.5, zorder=3,
                           bbox=dict(fc="white", ec="none", alpha=0.85, pad=0.5))
            box = _box(text.get_window_extent(renderer))
            clear = not any(_overlap(box, o) for o in [*blocks.values(), *labels.values()])
            if clear or chosen is None:
                if chosen is not None:
                    chosen[0].remove()
                chosen = (text, box)
            else:
                text.remove()
            if clear:
                break
        labels[f.name] = chosen[1]
    return plt, fig, blocks, labels


def picture_boxes(plan: ChipPlan) -> tuple[dict, dict]:
    """The display boxes of the picture's blocks and FIFO labels (see :func:`_draw`), by
    name: what a test checks for overlaps."""
    plt, fig, blocks, labels = _draw(plan)
    plt.close(fig)
    return blocks, labels


def plan_png(plan: ChipPlan) -> bytes:
    """The plan drawn: blocks coloured by clock domain, FIFOs as labelled arrows, each label
    on its arrow where it overlaps no block and no other label."""
    plt, fig, _, _ = _draw(plan)
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
