"""The box filter's timing rule: the plan's ``box_filter`` stage -- the column sums slid by an
add and a subtract (tree(2)), then the row sum of k of them and its cap (tree(lg(k) + 1)), as
the RTL builds them (sva_box.sv) -- and the column-sum banks whose ports bound its II."""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import BufferPlan, StagePlan, lg, tree_cycles
from stereosim.sva.geometry import bits_for, lane_groups


def box_stage(cfg: ChipConfig, width: int, cost_max: int) -> StagePlan:
    """The box filter for frames ``width`` pixels wide and matching costs up to ``cost_max``:
    II = max(G, the column sums' port cycles), latency = G + tree(2) + tree(lg(k) + 1)."""
    s = cfg.sva
    d, v, g, ports = s.disparities, s.compare_levels, lane_groups(s), s.sram_ports
    lanes = min(s.lanes, d)
    sums_buf = BufferPlan("sva.column_sums", width * d * bits_for(s.box_size * cost_max),
                          "the vertical box sums, W x D (a lane group read and written per "
                          "group)", reads=g, writes=g, ports=ports,
                          word_bits=lanes * bits_for(s.box_size * cost_max), pixel_reads=g,
                          pixel_writes=g)
    ii = max(g, sums_buf.port_cycles)
    slide, row_sum = tree_cycles(2, v), tree_cycles(lg(s.box_size) + 1, v)
    return StagePlan(
        "box_filter", ii, g + slide + row_sum,
        f"II = max(G = {g}, column sums' ports {ports}: {sums_buf.port_cycles}) = "
        f"{ii}; latency = G + tree(2: the column sum's add and subtract) + "
        f"tree(lg({s.box_size}) + 1: the row sum, its cap) = {g} + {slide} + {row_sum}",
        (sums_buf,),
    )


def box_registers(cfg: ChipConfig, cost_max: int) -> tuple[int, str]:
    """The box filter's pipeline registers: what a word carries: (bits, description)."""
    s = cfg.sva
    box_bits = bits_for(s.box_size * s.box_size * cost_max)
    return s.disparities * box_bits, f"D = {s.disparities} box sums of {box_bits} bits"
