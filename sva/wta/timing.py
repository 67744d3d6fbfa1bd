"""The winner-take-all's timing rule: the plan's ``wta`` stage -- the minimum over a lane
group's L lanes and, G > 1, one level folding it into the earlier groups', then the uniqueness
test and the sub-pixel step -- as the RTL builds it (sva_wta.sv)."""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import StagePlan, lg, tree_cycles
from stereosim.sva.geometry import lane_groups


def wta_stage(cfg: ChipConfig) -> StagePlan:
    """The WTA stage: II = G; latency = G + tree(lg(L) + [G > 1]) + [uniqueness] +
    (sub-pixel: F + 1)."""
    s = cfg.sva
    g = lane_groups(s)
    lanes = min(s.lanes, s.disparities)
    sub = 0 if s.subpixel == "off" else s.subpixel_bits + 1
    uniq = 1 if s.uniqueness else 0
    tree = tree_cycles(lg(lanes) + (1 if g > 1 else 0), s.compare_levels)
    return StagePlan(
        "wta", g, g + tree + uniq + sub,
        f"II = G = {g}; latency = G + tree(lg({lanes}) + [G > 1]: the lanes' min, the fold "
        f"into the earlier groups') + uniqueness {uniq} + sub-pixel ({s.subpixel}: F + 1 = "
        f"{sub}) = {g + tree + uniq + sub}")


def wta_registers(cfg: ChipConfig, word_bits: int) -> tuple[int, str]:
    """The WTA stage's pipeline registers: what a word carries: (bits, description)."""
    s = cfg.sva
    return (word_bits + s.sum_bits,
            f"the {word_bits}-bit word and its {s.sum_bits}-bit cost")
