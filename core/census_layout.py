"""Which pixels the census compares: the layout rule, and so its bit count, in one place.

The configuration (:mod:`core.config`) needs the bit count to size the SVA's registers before any
stage exists, and :mod:`nna.census_unit.census` needs the offsets to compute the descriptor; both
read them
from here. No validation: :func:`nna.census_unit.census.census_offsets` checks the parameters.
"""

from __future__ import annotations


def axis_samples(size: int, stride: int) -> list[int]:
    """Sample positions along one axis of a window: ``-(size // 2) + i * stride`` while
    ``<= size // 2``."""
    half = size // 2
    return list(range(-half, half + 1, stride))


def comparison_offsets(w: int, h: int, kind: str, stride: int) -> list[tuple[int, int]]:
    """The ``(dx, dy)`` offsets a ``w`` x ``h`` census compares, in bit order: ``plain`` every
    sampled pixel but the centre (each against the centre), ``symmetric`` the sampled pixels
    before the centre in raster order (each against its mirror through the centre)."""
    offsets = []
    for dy in axis_samples(h, stride):
        for dx in axis_samples(w, stride):
            if kind == "plain":
                if (dx, dy) != (0, 0):
                    offsets.append((dx, dy))
            elif dy < 0 or (dy == 0 and dx < 0):
                offsets.append((dx, dy))
    return offsets
