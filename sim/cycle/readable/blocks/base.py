"""What every block of the readable chip shares: it is built from its entry in the chip plan.

A chip block takes the plan (:class:`~sim.cycle.plan.ChipPlan`: the frame shape, the stream's
frame count, the configuration), its own entry (:class:`~sim.cycle.plan.BlockPlan`: name, clock
domain, ports, tile, timing) and the FIFOs of its ports, which the parent (the chip,
:mod:`sim.cycle.readable.chip`) creates and hands it in the order of the entry's ``inputs`` and
``outputs``; a block never wires itself. Its traced signals are the plan's
(:func:`~sim.cycle.plan.build_plan`'s ``signals``): :meth:`~sim.cycle.readable.clock.Block.
signal_values` gives their committed values.
"""

from __future__ import annotations

from stereosim.sim.cycle.fifo.readable import Fifo, KernelError
from stereosim.sim.cycle.plan import STATUS_CODES, BlockPlan, ChipPlan
from stereosim.sim.cycle.readable.clock import Block


class ChipBlock(Block):
    """A block of the chip: named and clocked as its plan entry ``entry`` says, running over the
    plan's stream of ``frames`` frames, with the FIFOs ``inputs`` and ``outputs`` on the ports the
    entry names (checked: a FIFO handed to the wrong port is a wiring bug)."""

    def __init__(self, plan: ChipPlan, entry: BlockPlan, inputs: list[Fifo] = (),
                 outputs: list[Fifo] = ()):
        super().__init__(entry.name, plan.domains[entry.domain].clock())
        for role, fifos, names in (("inputs", inputs, entry.inputs),
                                   ("outputs", outputs, entry.outputs)):
            if tuple(f.name for f in fifos) != names:
                raise KernelError(f"block '{entry.name}' was handed {role} "
                                  f"{[f.name for f in fifos]}; its plan entry names {list(names)}")
        self.entry = entry
        self.frames = plan.frames

    @property
    def status_code(self) -> int:
        """The activity of the block's last cycle, as traced (0, idle, before the first)."""
        return STATUS_CODES.get(self.status, 0)
