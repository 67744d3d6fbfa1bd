"""SGM's timing rule: the plan's ``sgm`` stage (the path units: one lane's step of five levels,
the left path's pixel-to-pixel recurrence, the previous-row banks) and ``path_sum`` stage (the
paths added and capped), as the RTL builds them (sva_sgm.sv)."""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import BufferPlan, StagePlan, lg, tree_cycles
from stereosim.sva.geometry import lane_groups

# Levels of one lane's SGM step (sva.sgm.sgm): L(p-1, d) - m beside the min of its neighbours
# L(p-1, d -+ 1); + P1 beside min(P2 path); the min of the candidates; + the aggregated cost;
# the cap at path_bits. The RTL twin (sva_sgm.sv) builds them so.
SGM_STEP_LEVELS = 5


def left_path_ii(cfg: ChipConfig) -> int:
    """II of the left-to-right SGM path: G - 1 + tree(5) + tree(lg(L) + [G > 1]). A pixel's
    last lane group leaves the step's five levels (:data:`SGM_STEP_LEVELS`) tree(5) cycles
    after it entered, G - 1 after the first; then the min over the pixel's D costs (its lanes'
    tree and, G > 1, one level folding in the earlier groups') must be complete before the
    next pixel's first group enters."""
    s = cfg.sva
    g = lane_groups(s)
    lanes = min(s.lanes, s.disparities)
    v = s.compare_levels
    return g - 1 + tree_cycles(SGM_STEP_LEVELS, v) + tree_cycles(
        lg(lanes) + (1 if g > 1 else 0), v)


def sgm_stage(cfg: ChipConfig, width: int) -> StagePlan:
    """The path units for frames ``width`` pixels wide: II = max(the left path's recurrence,
    the previous-row banks' port cycles), latency = G + tree(5)."""
    s = cfg.sva
    d, v, g, ports = s.disparities, s.compare_levels, lane_groups(s), s.sram_ports
    lanes = min(s.lanes, d)
    top = 1 if s.paths > 1 else 0
    sgm_buf = BufferPlan("sva.sgm_previous_row", (s.paths - 1) * width * d * s.path_bits
                         + d * s.path_bits,
                         "the top paths' previous row (a bank per path, a lane group read and "
                         "written per group) and the left path's previous pixel",
                         reads=g * top, writes=g * top, ports=ports if top else "",
                         banks=max(1, s.paths - 1), word_bits=lanes * s.path_bits,
                         pixel_reads=g * (s.paths - 1), pixel_writes=g * (s.paths - 1))
    left_ii = left_path_ii(cfg)
    step = tree_cycles(SGM_STEP_LEVELS, v)
    ii = max(left_ii, sgm_buf.port_cycles)
    return StagePlan(
        "sgm", ii, g + step,
        f"{s.paths} path unit(s); II = max(left path G - 1 + tree({SGM_STEP_LEVELS}) + "
        f"tree(lg({lanes}) + [G > 1]) = {left_ii} (the step, then the min over the pixel's D "
        f"costs), previous row's ports {ports}: {sgm_buf.port_cycles}) = {ii}; latency = "
        f"G + tree({SGM_STEP_LEVELS} levels of the step) = {g} + {step}",
        (sgm_buf,),
    )


def sgm_registers(cfg: ChipConfig) -> tuple[int, str]:
    """The path units' pipeline registers: what a word carries: (bits, description)."""
    s = cfg.sva
    return (s.paths * s.disparities * s.path_bits,
            f"{s.paths} path(s) x D = {s.disparities} path costs of {s.path_bits} bits")


def path_sum_stage(cfg: ChipConfig) -> StagePlan:
    """The path sum: II = G, latency = tree(lg(paths) + 1) (the adds, the cap at sum_bits)."""
    s = cfg.sva
    g = lane_groups(s)
    sum_tree = tree_cycles(lg(s.paths) + 1, s.compare_levels)
    return StagePlan(
        "path_sum", g, sum_tree,
        f"II = G = {g}; latency = tree(lg({s.paths} paths) + 1: the adds, the cap at sum_bits) "
        f"= {sum_tree}")


def path_sum_registers(cfg: ChipConfig) -> tuple[int, str]:
    """The path sum's pipeline registers: what a word carries: (bits, description)."""
    s = cfg.sva
    return s.disparities * s.sum_bits, f"D = {s.disparities} sums S of {s.sum_bits} bits"
