"""What the SVA's stages imply for the rows it must hold and the width of its output word.

Facts of the stage, used by the chip plan (``sim.cycle.plan``), the functional pipeline
(:mod:`sva.pipeline.pipeline`), the clocked SVA block and the analytic estimate alike.
"""

from __future__ import annotations

import math

from stereosim.core.config import SvaConfig
from stereosim.core.errors import ConfigError, UserError


def check_disparity_range(cfg: SvaConfig, width: int, error: type[UserError] = ConfigError
                          ) -> None:
    """Refuse a disparity range D that is not below the image ``width`` (``error``, one line):
    every disparity d in [0, D) must leave a column of the right view to compare with. The
    rule of the chip plan, the SVA's entry points and the tools that size a frame."""
    if cfg.disparities >= width:
        raise error(
            f"sva.disparities={cfg.disparities} is not smaller than the image width {width}: "
            "use a smaller disparity range (--disparities) or a wider image"
        )


def box_radius(cfg: SvaConfig) -> int:
    """Rows (and columns) of cost the box filter reads on each side: k // 2."""
    return cfg.box_size // 2


def median_radius(cfg: SvaConfig) -> int:
    """Rows of output words the median filter reads on each side (0 when off)."""
    return cfg.median // 2 if cfg.median > 1 else 0


def row_lookahead(cfg: SvaConfig) -> int:
    """Input rows below output row y that its words depend on: the box filter's r plus the
    median's m (the SGM paths and the LR check's diagonal read rows above). The hybrid's noise
    band is r + m + 1 rows (:mod:`sva.hamming.noise`); the cycle model's timing reads the box's
    r and the median's skew separately (:mod:`sim.cycle.rules`)."""
    return box_radius(cfg) + median_radius(cfg)


def lane_groups(cfg: SvaConfig) -> int:
    """G = ceil(D / lanes): the cycles one pixel's disparities take through a stage."""
    return -(-cfg.disparities // min(cfg.lanes, cfg.disparities))


def bits_for(max_value: int) -> int:
    """Bits of an unsigned register holding 0 .. max_value."""
    return max(1, math.ceil(math.log2(max_value + 1)))


def disparity_bits(cfg: SvaConfig) -> int:
    """Bits of an integer disparity 0 .. D - 1."""
    return bits_for(cfg.disparities - 1)


def output_word_bits(cfg: SvaConfig) -> int:
    """Bits of an SVA output word: a valid flag, the integer disparity and the sub-pixel
    fraction."""
    return 1 + disparity_bits(cfg) + cfg.subpixel_bits
