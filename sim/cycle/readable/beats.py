"""The beats the readable chip's FIFOs carry: one named tuple per kind of beat.

Every beat names its place in the stream -- ``frame`` (of the stream), ``x`` and ``y`` (the
image column and row) -- and then its payload. The hardware knows the place from its raster
counters (beats leave every block in raster order, frame after frame) and moves only the
payload: a FIFO's width in the plan (``FifoPlan.width_bits``) counts the fields in ``wire``.
The model carries the place so that a block stores what it received where it belongs, and a
beat out of order shows in the words. ``pushed_by``: the kinds of block (``BlockPlan.kind``)
whose output FIFOs carry the beat; docs/architecture.md's table of beats is generated from
these types (``python benchmarks/doc_figures.py --write beats``).
"""

from __future__ import annotations

from typing import NamedTuple


class PixelBeat(NamedTuple):
    """A camera pixel, from a source to the NNA submodules whose tiles take it."""

    frame: int
    x: int
    y: int
    pixel: int  # 8-bit intensity

    pushed_by = ("memory", "camera")
    wire = "pixel: 8 bits"


class DescriptorBeat(NamedTuple):
    """A pixel's descriptor, from an NNA submodule (through its camera's merge, with a split
    frame) to the SVA; the pixel rides along for the SVA's adaptive P2."""

    frame: int
    x: int
    y: int
    descriptor: int  # the descriptor's bits as an unsigned integer
    pixel: int  # 8-bit intensity of the same pixel

    pushed_by = ("nna", "merge")
    wire = "descriptor, and pixel with sva.p2_adaptive: ChipPlan.beat_bits"


class WordBeat(NamedTuple):
    """A pixel's output word, from the SVA to the sink."""

    frame: int
    x: int
    y: int
    word: int  # the disparity in fixed point (its sub-pixel bits); negative: invalid

    pushed_by = ("sva",)
    wire = "word: ChipPlan.word_bits"


BEATS = (PixelBeat, DescriptorBeat, WordBeat)  # in stream order
