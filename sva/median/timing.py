"""The median's timing rule: the plan's ``median`` stage -- a sorting network over the m x m
window (Batcher's odd-even merge sort) -- and the output-row banks whose ports bound its II, as
the RTL builds them (sva_median.sv)."""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import BufferPlan, StagePlan, lg, tree_cycles


def sorting_depth(n: int) -> int:
    """Levels of Batcher's odd-even merge sort over n inputs: k (k + 1) / 2 with k = lg(n)."""
    k = lg(n)
    return k * (k + 1) // 2


def median_stage(cfg: ChipConfig, width: int, word_bits: int) -> StagePlan:
    """The median stage (``sva.median`` > 1): II = max(1, its row banks' port cycles); latency =
    tree(the sorting network's depth)."""
    s = cfg.sva
    # its output rows: a bank per row, a word's column read and the new word written
    rows = BufferPlan("sva.median_rows", s.median * width * word_bits,
                      "the median's output rows (a bank per row: its column read, the new "
                      "word written)", reads=1, writes=1, ports=s.sram_ports, banks=s.median,
                      word_bits=word_bits, pixel_reads=s.median, pixel_writes=1)
    ii = max(1, rows.port_cycles)
    depth = sorting_depth(s.median * s.median)
    tree = tree_cycles(depth, s.compare_levels)
    return StagePlan(
        "median", ii, tree,
        f"II = max(1, median rows' ports {s.sram_ports}: {rows.port_cycles}) = {ii}; "
        f"latency = tree({depth} levels of a {s.median}x{s.median} sorting network) = {tree}",
        (rows,),
    )


def median_registers(word_bits: int) -> tuple[int, str]:
    """The median's pipeline registers: what a word carries (bits, description)."""
    return word_bits, f"the {word_bits}-bit word"
