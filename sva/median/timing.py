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


def median_rows(cfg: ChipConfig, width: int, word_bits: int) -> BufferPlan:
    """The median's output rows: a bank per row, its column read and the new word written."""
    s = cfg.sva
    return BufferPlan("sva.median_rows", s.median * width * word_bits,
                      "the median's output rows (a bank per row: its column read, the new "
                      "word written)", reads=1, writes=1, ports=s.sram_ports,
                      banks=max(1, s.median), word_bits=word_bits,
                      pixel_reads=s.median if s.median > 1 else 0,
                      pixel_writes=1 if s.median > 1 else 0)


def median_ii(cfg: ChipConfig, width: int, word_bits: int) -> int:
    """The median's II: max(1, the row banks' port cycles)."""
    return max(1, median_rows(cfg, width, word_bits).port_cycles)


def median_stage(cfg: ChipConfig, width: int, word_bits: int) -> StagePlan:
    """The median stage: II = :func:`median_ii`; latency = tree(the sorting network's depth)."""
    s = cfg.sva
    rows = median_rows(cfg, width, word_bits)
    ii = median_ii(cfg, width, word_bits)
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
