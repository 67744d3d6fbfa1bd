"""The readable kernel's clocked blocks, on the clock domains of
:class:`sim.cycle.rules.ClockDomain`; the two-phase scheduler is :mod:`sim.cycle.readable.kernel`.

This is the reference engine that defines what a cycle means in stereosim; a compiled engine is
checked against it cycle for cycle. docs/clock-kernel.md states the rules with timing diagrams.

* **Time** is an integer number of femtoseconds. A :class:`ClockDomain` has edges at
  ``phase_fs + k * period_fs`` for ``k = 0, 1, 2, ...``; ``k`` is the domain's cycle index.
* **A step** is one instant at which at least one domain has an edge. The scheduler advances to
  the earliest next edge of all domains; every domain with an edge at that instant ticks in that
  step (simultaneous edges are simultaneous, not ordered).
* **Two phases.** In a step every block of every ticking domain first ``evaluate()``\\ s, reading
  only committed state (its own committed attributes, FIFO contents as committed by earlier
  steps) and staging writes (the next values of its attributes, FIFO pushes and pops); then
  everything commits (a block's ``commit()`` applies what it staged). Evaluation order therefore
  cannot change a result; ``Simulator(order_seed=...)`` shuffles it to prove so.
* **Activity.** In each of its cycles a block reports exactly one of ``busy``, ``starved``
  (waits for data from an input FIFO), ``blocked`` (waits for space in an output FIFO) or
  ``idle``. A step makes **progress** if a FIFO pushed or popped or a block was busy; a run raises
  :class:`DeadlockError` once ``watchdog_cycles`` periods of the slowest clock passed without
  progress and
  :class:`BudgetExceeded` when a domain would run past its cycle budget.
"""

from __future__ import annotations

from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.contract import ACTIVITIES, activity_counts
from stereosim.sim.cycle.fifo.readable import KernelError
from stereosim.sim.cycle.rules import ClockDomain


class Block:
    """Base class of a clocked block.

    Subclasses implement :meth:`evaluate` (read committed state, stage writes, report exactly one
    activity with :meth:`busy`, :meth:`starved`, :meth:`blocked` or :meth:`idle`) and
    :meth:`commit` (apply the staged writes), and name what they trace in :meth:`signals` and
    :meth:`signal_values`. The parent hands FIFOs to the block's constructor; a block never
    wires itself.
    """

    def __init__(self, name: str, domain: ClockDomain):
        if not isinstance(name, str) or not name:
            raise ConfigError(f"block name must be a non-empty string; got {name!r}")
        if not isinstance(domain, ClockDomain):
            raise ConfigError(f"block '{name}': domain must be a ClockDomain; got {domain!r}")
        self.name = name
        self.domain = domain
        self.status: str | None = None
        self.waiting_on: tuple[str, str] | None = None
        self._counts = dict.fromkeys(ACTIVITIES, 0)
        self._status: str | None = None
        self._waiting: tuple[str, str] | None = None

    # ---- to implement ------------------------------------------------------------------------

    def evaluate(self, now_cycle: int) -> None:
        """One cycle (``now_cycle`` = the domain's edge index): read committed state, stage
        writes, report one activity."""
        raise NotImplementedError(f"block '{self.name}' must implement evaluate()")

    def commit(self) -> None:
        """Apply the state staged by this cycle's :meth:`evaluate` (phase 2)."""

    def signals(self) -> list[tuple[str, int]]:
        """Traced signals as ``(name, width_bits)``; default: none."""
        return []

    def signal_values(self) -> dict:
        """Committed values of :meth:`signals`."""
        return {}

    # ---- helpers for subclasses --------------------------------------------------------------

    def busy(self) -> None:
        """This cycle did useful work (moved data or advanced internal state)."""
        self._report("busy", None)

    def idle(self) -> None:
        """Nothing to do this cycle, and not waiting on a FIFO."""
        self._report("idle", None)

    def starved(self, fifo) -> None:
        """Waiting for data from the input ``fifo`` (a Fifo or its name)."""
        self._report("starved", (getattr(fifo, "name", fifo), "empty"))

    def blocked(self, fifo) -> None:
        """Waiting for space in the output ``fifo`` (a Fifo or its name)."""
        self._report("blocked", (getattr(fifo, "name", fifo), "full"))

    def stage_stats(self) -> dict:
        """Per internal stage of a pipelined block: its activity counts and what it held
        (``{}``: the block has no stages of its own)."""
        return {}

    @property
    def activity(self) -> dict[str, int]:
        """Cycles spent busy / starved / blocked / idle so far (sorted keys)."""
        return activity_counts(**self._counts)

    # ---- kernel side -------------------------------------------------------------------------

    def _report(self, status: str, waiting) -> None:
        if self._status is not None:
            raise KernelError(
                f"block '{self.name}' reported both {self._status} and {status} in one cycle; "
                "report exactly one activity per cycle"
            )
        self._status = status
        self._waiting = waiting

    def _tick(self, now_cycle: int) -> bool:
        """Run evaluate() and account its activity; True if the block was busy."""
        self._status = None
        self.evaluate(now_cycle)
        status = self._status
        if status is None:
            raise KernelError(
                f"block '{self.name}' reported no activity in cycle {now_cycle}; call "
                "self.busy(), self.starved(fifo), self.blocked(fifo) or self.idle() in evaluate()"
            )
        self._counts[status] += 1
        self.status = status
        self.waiting_on = self._waiting
        return status == "busy"
