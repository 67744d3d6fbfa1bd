"""The matching cost's timing rule: the plan's ``hamming`` stage (its II and latency from the
popcount trees the RTL builds, sva_hamming.sv), the descriptor row banks it reads and the hybrid's
noise unit. The formulas are in :mod:`sim.cycle.stages`' table; the chip plan collects the stage
(:func:`sim.cycle.stages.sva_stages`)."""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import BufferPlan, StagePlan, lg, tree_cycles
from stereosim.sva.geometry import bits_for, lane_groups
from stereosim.sva.hamming.noise import noise_unit_bits


def hamming_levels(parts: tuple[int, ...]) -> int:
    """Adder levels of the matching cost of a descriptor of ``parts`` (each part's bits): one
    part, its popcount tree lg(b); two (the hybrid), their popcount trees side by side, then
    each weighted (w in 0..3: the distance plus itself shifted, one level) and the two added
    (one level): lg(max b_k) + 2."""
    if len(parts) == 1:
        return lg(parts[0])
    return lg(max(parts)) + 2


def noise_buffers(cfg: ChipConfig, width: int) -> list[BufferPlan]:
    """The noise unit of the hybrid's automatic weights (:mod:`sva.hamming.noise`): the two
    rows of left pixels above the arriving one that its 3x3 window reads (written once per
    pixel of the band, each read once), and its registers -- S, N and the product T N, the two
    weight sets and the threshold and gradient registers."""
    regs = noise_unit_bits(cfg.sva, width)
    return [
        BufferPlan("sva.noise_rows", 2 * width * 8,
                   f"the two rows of left pixels above the arriving one, 2 x {width} x 8 bits "
                   "(the noise statistic's 3x3 window; only the frame's first rows)",
                   rows=0, reads=0, writes=0, banks=2, word_bits=8),
        BufferPlan("sva.noise_registers", regs + 2 * 2 * 2 + 2 * 10,
                   f"S, N and T N ({regs} bits), the two weight sets (2 x 2 x 2 bits), the "
                   "threshold and the gradient (10 bits each)"),
    ]


def hamming_stage(cfg: ChipConfig, width: int, parts: tuple[int, ...]) -> StagePlan:
    """The SVA's first stage for frames ``width`` pixels wide and descriptors of ``parts``:
    the descriptor rows it reads (both views, k + 2 rows each), the right window, the hybrid's
    noise unit with automatic weights, its II = max(G, the row banks' port cycles) and its
    latency G + tree(:func:`hamming_levels`)."""
    s = cfg.sva
    d, v, g, ports = s.disparities, s.compare_levels, lane_groups(s), s.sram_ports
    lanes = min(s.lanes, d)
    bits, levels = sum(parts), hamming_levels(parts)
    # a bank per row and view: the arriving row's bank is only written (a slot reads complete
    # rows), and a slot's reads (the row entering the column sums, the row leaving them) are
    # in different banks -- each bank does one access a slot, so one port serves it
    rows_buf = BufferPlan("sva.descriptor_rows", 2 * (s.box_size + 2) * width * bits,
                          "both views' descriptor rows the box filter slides over (k + 2 "
                          "each: rows y - 1 - r .. y + r, the one leaving the column sums "
                          "included, and the row arriving; a bank per row and view, each "
                          "read or written, never both, in a slot)",
                          rows=s.box_size + 2, reads=1, writes=0, ports=ports,
                          banks=2 * (s.box_size + 2), word_bits=bits, pixel_reads=2,
                          pixel_writes=2)
    ii = max(g, rows_buf.port_cycles)
    bufs = [rows_buf, BufferPlan("sva.right_window", d * bits,
                                 "the right descriptors x - D + 1 .. x (registers)")]
    if len(parts) > 1 and s.weight_mode == "auto":
        bufs += noise_buffers(cfg, width)
    tree = (f"lg({bits})" if len(parts) == 1 else
            f"lg(max({parts[0]}, {parts[1]})) + 2: two popcounts, weighted, added")
    return StagePlan(
        "hamming", ii, g + tree_cycles(levels, v),
        f"II = max(G = ceil({d}/{lanes}) = {g}, descriptor rows' ports {ports}: "
        f"{rows_buf.port_cycles}) = {ii}; latency = G + tree({tree}) = {g} + "
        f"{tree_cycles(levels, v)}", tuple(bufs))


def hamming_registers(cfg: ChipConfig, parts: tuple[int, ...], cost_max: int
                      ) -> tuple[int, str]:
    """The matching cost's pipeline registers: what a word carries: (bits, description)."""
    d, cost_bits = cfg.sva.disparities, bits_for(cost_max)
    kind = "Hamming" if len(parts) == 1 else "weighted"
    return d * cost_bits, f"D = {d} {kind} costs of {cost_bits} bits"
