"""The left-right check's timing rule: the plan's ``lr_check`` stage. The right pixel x_r takes
the best of S(x_r + d, d) over d, a diagonal through the next D left pixels, so a left pixel's
check waits until the D - 1 pixels after it have been aggregated: (D - 1) IIs of the pipeline
(sva_lr.sv shifts its window one pixel per II)."""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import BufferPlan, StagePlan
from stereosim.sva.geometry import disparity_bits, lane_groups


def lr_stage(cfg: ChipConfig, pipeline_ii: int, word_bits: int) -> StagePlan:
    """The LR check stage: II = G; latency = (D - 1) x ``pipeline_ii`` + 1; its window's
    registers."""
    s = cfg.sva
    d, g = s.disparities, lane_groups(s)
    return StagePlan(
        "lr_check", g, (d - 1) * pipeline_ii + 1,
        f"II = G = {g}; latency = (D - 1) x II + 1 = {d - 1} x {pipeline_ii} + 1 (the diagonal "
        "through the next D - 1 pixels)",
        (BufferPlan("sva.lr_window", d * (s.sum_bits + disparity_bits(s)) + d * word_bits,
                    "the running best (cost, d) of D right pixels and the D left words "
                    "waiting for them (registers: shifted one pixel per II)"),),
    )


def lr_registers(cfg: ChipConfig, word_bits: int) -> tuple[int, str, int]:
    """The LR check's window: what it holds: (bits a pixel, description, D pixels)."""
    s = cfg.sva
    return (s.sum_bits + disparity_bits(s) + word_bits, "per pixel of its window: a right "
            "pixel's running best (cost, d) and a left word waiting", s.disparities)
