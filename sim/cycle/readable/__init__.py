"""The readable cycle engine: the specification of a cycle, edge by edge.

Clocked blocks (:mod:`.clock`), clocked FIFOs (:mod:`.fifo`) and the two-phase kernel that
steps them (:mod:`.kernel`), and the chip built from the plan on them (:mod:`.chip`, with its
blocks in :mod:`.blocks`, each built from its plan entry, and the typed beats its FIFOs carry in
:mod:`.beats`). It reads the chip plan and the shared rules and produces the contract's results
(:mod:`sim.cycle.contract`); it never imports the compiled engine (docs/clock-kernel.md).
"""
