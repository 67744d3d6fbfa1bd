"""The chip plan drawn: its clock domains, blocks and FIFOs as a text listing and as a picture,
both read off a :class:`~sim.cycle.plan.ChipPlan` (nothing here knows the topology).

    stereosim config plan [--size WxH] [--set KEY=VALUE ...] [--png PATH]

:func:`plan_text` lists every domain (frequency, period, blocks), every block (kind, domain,
items, cycles per item, latency, buffers) and every FIFO as ``producer --name--> consumer`` with
its depth, width, configuration key and, for a crossing, the edges after which data and free
slots are seen; :func:`plan_png` draws the blocks as boxes coloured by domain in pipeline
columns (source, NNA, merge, SVA, sink) with the FIFOs as arrows (dashed where they cross
domains). docs/architecture.md opens with both, for the default chip.
"""

from __future__ import annotations

import io
from pathlib import Path

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
    return f"  {b.name:<14} [{b.domain}] " + "; ".join(parts)


def plan_text(plan: ChipPlan) -> str:
    """The plan as a deterministic text listing (domains, blocks, FIFOs, budget)."""
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
    lines.append(f"SRAM per instance: {total:,} bits over {len(sram_bits(plan))} buffers; "
                 "budget: " + ", ".join(f"{k} {v:,}" for k, v in sorted(plan.budget.items())))
    return "\n".join(lines) + "\n"


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
        pos[b.name] = (x * 3.2, -y * 1.6)
    return pos


def plan_png(plan: ChipPlan) -> bytes:
    """The plan drawn: blocks coloured by clock domain, FIFOs as labelled arrows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch, Patch

    plt.rcParams.update({"svg.hashsalt": "stereosim", "path.simplify": False})
    pos = _positions(plan)
    n_rows = 2 * plan.parts
    fig, ax = plt.subplots(figsize=(13, 1.9 + 1.25 * n_rows), dpi=100)
    bw, bh = 1.7, 0.75
    for b in plan.blocks:
        x, y = pos[b.name]
        ax.add_patch(FancyBboxPatch((x - bw / 2, y - bh / 2), bw, bh,
                                    boxstyle="round,pad=0.05",
                                    fc=DOMAIN_COLOURS.get(b.domain, "#dddddd"), ec="black"))
        detail = f"{b.items:,} items" + (f", {b.cycles} cyc" if b.kind in ("nna", "sva") else "")
        ax.text(x, y + 0.12, b.name, ha="center", va="center", fontsize=9, weight="bold")
        ax.text(x, y - 0.17, detail, ha="center", va="center", fontsize=7)
    for f in plan.fifos:
        (x0, y0), (x1, y1) = pos[f.producer], pos[f.consumer]
        ax.annotate("", xy=(x1 - bw / 2 - 0.05, y1), xytext=(x0 + bw / 2 + 0.05, y0),
                    arrowprops=dict(arrowstyle="-|>", lw=1.2, color="black",
                                    linestyle="--" if f.crossing else "-"))
        label = f"{f.name}\n{f.depth} x {f.width_bits} b" + (" (CDC)" if f.crossing else "")
        ax.text((x0 + x1) / 2, (y0 + y1) / 2 + 0.08, label, ha="center", va="bottom",
                fontsize=6.5, bbox=dict(fc="white", ec="none", alpha=0.8, pad=0.5))
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
    ax.set_xlim(-1.2, 4 * 3.2 + 1.2)
    ax.set_ylim(-(n_rows - 1) * 1.6 - 0.9, 1.0)
    ax.axis("off")
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
