"""The words a block's timing rule speaks: a stage of a pipeline (:class:`StagePlan`: its II,
latency and pipeline registers), a storage (:class:`BufferPlan`: bits, ports, banks) and the
trees of two-input operators whose depth sets a stage's cycles (:func:`lg`, :func:`tree_cycles`).

Each block's folder declares its stages with these (``sva/<stage>/timing.py``, the NNA's in
:mod:`sim.cycle.stages`); the chip plan (:mod:`sim.cycle.plan`) collects them, both cycle
engines and the estimate read them. They sit in the core because every block's rule, below the
cycle model, builds them."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class BufferPlan:
    """A storage of a block or stage: ``bits`` of SRAM, what it holds; ``rows`` > 0: a window
    of that many image rows whose fill both engines track (:mod:`sim.cycle.buffers`).

    SRAM ports: ``reads`` and ``writes`` per pixel of each bank (one word per access: a lane
    group of D-indexed buffers), through ``ports`` = ``"1r1w"`` (a read and a write port:
    max(reads, writes) cycles per pixel) or ``"1rw"`` (one shared port: reads + writes); ``""``
    for registers, which every cycle can read and write.

    Energy (:mod:`sim.cycle.energy`): ``banks`` arrays of bits / banks each; per output pixel
    ``pixel_reads`` and ``pixel_writes`` accesses of ``word_bits`` bits over all of them (0 for
    registers, whose energy is the logic's)."""

    name: str
    bits: int
    holds: str
    rows: int = 0
    reads: int = 0
    writes: int = 0
    ports: str = ""
    banks: int = 1
    word_bits: int = 0
    pixel_reads: int = 0
    pixel_writes: int = 0

    @property
    def port_cycles(self) -> int:
        """Cycles per pixel this buffer's ports need (0: not port-limited)."""
        if self.ports == "1rw":
            return self.reads + self.writes
        if self.ports == "1r1w":
            return max(self.reads, self.writes)
        return 0


@dataclass(frozen=True)
class StagePlan:
    """A stage of the SVA pipeline: ``ii`` cycles per pixel, ``latency`` cycles from a pixel
    entering it to leaving it, ``formula`` the arithmetic behind both (shown in reports).

    Its pipeline registers (its delay line) hold ``slots`` words of ``slot_bits`` bits each:
    ceil(latency / ii) -- a stage fed at its own II holds no more words than that -- or, for
    the LR check, the D words of its window. Both engines track how many words each stage holds
    (:mod:`sim.cycle.buffers` checks the peak against ``slots``)."""

    name: str
    ii: int
    latency: int
    formula: str
    buffers: tuple[BufferPlan, ...] = ()
    slots: int = 0
    slot_bits: int = 0
    holds: str = ""

    @property
    def register_bits(self) -> int:
        return self.slots * self.slot_bits


def lg(n: int) -> int:
    """ceil(log2 n) for n >= 1: the depth of a tree of two-input operators over n inputs."""
    return max(0, math.ceil(math.log2(n))) if n > 1 else 0


def tree_cycles(levels: int, per_cycle: int) -> int:
    """Cycles of a tree of ``levels`` levels when ``per_cycle`` levels settle in one cycle."""
    return -(-levels // per_cycle) if levels > 0 else 0


def with_slots(stage: StagePlan, slot_bits: int, holds: str, slots: int = -1) -> StagePlan:
    """``stage`` with its pipeline registers: ``slots`` words (default ceil(latency / II))
    of ``slot_bits`` bits."""
    if slots < 0:
        slots = -(-stage.latency // stage.ii) if stage.latency > 0 else 0
    return dataclasses.replace(stage, slots=slots, slot_bits=slot_bits, holds=holds)
