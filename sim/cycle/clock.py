"""The readable clock kernel: clock domains, clocked blocks and the two-phase scheduler.

This is the reference engine that defines what a cycle means in stereosim; a compiled engine is
checked against it cycle for cycle. docs/clock-kernel.md states the rules with timing diagrams.

* **Time** is an integer number of femtoseconds. A :class:`ClockDomain` has edges at
  ``phase_fs + k * period_fs`` for ``k = 0, 1, 2, ...``; ``k`` is the domain's cycle index.
* **A step** is one instant at which at least one domain has an edge. The scheduler advances to
  the earliest next edge of all domains; every domain with an edge at that instant ticks in that
  step (simultaneous edges are simultaneous, not ordered).
* **Two phases.** In a step every block of every ticking domain first ``evaluate()``\\ s, reading
  only committed state (register values, FIFO contents as committed by earlier steps) and staging
  writes (register ``next`` values, FIFO pushes and pops); then everything commits. Evaluation
  order therefore cannot change a result; ``Simulator(order_seed=...)`` shuffles it to prove so.
* **Activity.** In each of its cycles a block reports exactly one of ``busy``, ``starved``
  (waits for data from an input FIFO), ``blocked`` (waits for space in an output FIFO) or
  ``idle``. A step makes **progress** if a FIFO pushed or popped or a block was busy; a run raises
  :class:`DeadlockError` once ``watchdog_cycles`` periods of the slowest clock passed without
  progress and
  :class:`BudgetExceeded` when a domain would run past its cycle budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from stereosim.sim.cycle.rules import period_fs
from stereosim.sim.errors import ConfigError, UserError

ACTIVITIES = ("busy", "starved", "blocked", "idle")


class KernelError(RuntimeError):
    """A block or the wiring broke a rule of the kernel (a bug in a model, not in user input):
    pushing into a full FIFO, two pushes in one cycle, popping an item that is not visible,
    touching a FIFO outside its domain's edge, reporting no or two activities in a cycle."""


class RunStopped(UserError):
    """A run stopped before its ``until`` condition held; carries the state of the chip.

    Attributes: ``time_fs`` (instant of the last executed step), ``cycles`` (cycles run per
    domain), ``fifos`` (name -> ``{"occupancy", "depth"}``), ``blocks`` (name -> ``{"status",
    "waiting_on"}`` where ``waiting_on`` is ``(fifo_name, "empty" | "full")`` or ``None``).
    A chip's run fills in more on the way up (None until then): ``row_times`` (the row
    instants reached, as :meth:`sim.cycle.chip.Chip.row_times`), ``trace`` (the
    :class:`~traces.log.TraceLog` of a traced run, up to the stop) with ``outputs_in_window``,
    ``engine`` (the cycle engine that ran) and, from :func:`stereosim.run`, ``report`` (the
    stopped run's report, its ``stopped`` section from :func:`sim.cycle.stops.stop_report`).
    """

    def __init__(self, message: str, *, time_fs: int, cycles: dict, fifos: dict, blocks: dict):
        super().__init__(message)
        self.time_fs = time_fs
        self.cycles = cycles
        self.fifos = fifos
        self.blocks = blocks
        self.row_times = None
        self.trace = None
        self.outputs_in_window = 0
        self.engine: str | None = None
        self.report: dict | None = None
        self.plan = None  # a stream's ChipPlan and FrameSupply, from stereosim.run_stream
        self.supply = None


class DeadlockError(RunStopped):
    """No FIFO moved and no block was busy for ``watchdog_cycles`` periods of the slowest clock."""


class BudgetExceeded(RunStopped):
    """A clock domain would have run more cycles than the run's budget allows."""


def check_int(what: str, value, lo: int, fix: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{what} must be an integer; got {value!r} ({fix})")
    if value < lo:
        raise ConfigError(f"{what} must be >= {lo}; got {value} ({fix})")
    return value


@dataclass(frozen=True, slots=True)
class ClockDomain:
    """A clock: edge ``k`` (its cycle index) is at ``phase_fs + k * period_fs`` femtoseconds,
    with ``period_fs = round(1e15 / freq_hz)``."""

    name: str
    freq_hz: float
    phase_fs: int = 0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"clock domain name must be a non-empty string; got {self.name!r}")
        f = self.freq_hz
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) or f <= 0:
            raise ConfigError(
                f"clock domain '{self.name}': freq_hz must be a positive number; got {f!r}"
            )
        if period_fs(f) < 1:
            raise ConfigError(
                f"clock domain '{self.name}': freq_hz {f!r} gives a period below 1 fs; "
                "use at most 1e15 Hz"
            )
        check_int(
            f"clock domain '{self.name}': phase_fs", self.phase_fs, 0, "the first edge's time in fs"
        )

    @property
    def period_fs(self) -> int:
        return period_fs(self.freq_hz)

    def edge_fs(self, k: int) -> int:
        """The instant of edge ``k``."""
        return self.phase_fs + k * self.period_fs

    def first_edge_after(self, t_fs: int) -> int:
        """Index of the first edge strictly after the instant ``t_fs``."""
        if t_fs < self.phase_fs:
            return 0
        return (t_fs - self.phase_fs) // self.period_fs + 1


# the full FIFOs a stop's line names (every FIFO's state is on the exception)
STOP_LINE_FIFOS = 6


def time_text(t_fs: int) -> str:
    """An instant as a stop's line gives it: microseconds to the picosecond."""
    return f"{t_fs / 1e9:.6f} us"


def stop_message(head: str, now_fs: int, cycles: dict[str, int], fifos: dict[str, dict],
                 blocks: dict[str, dict], tail: str) -> str:
    """The one-line message of a :class:`RunStopped` (both cycle engines build it here): the
    reason, the instant and the cycles run per domain (``cycles`` in domain order), the FIFOs
    that matter -- the full ones, each of which holds its producer back (``fifos``: name ->
    {"occupancy", "depth"}, in the chip's order; the first :data:`STOP_LINE_FIFOS`) -- the
    blocks waiting on something that is not a FIFO (the DRAM channel, the frame buffers), and
    ``tail``. Every FIFO's and block's state is on the exception, not in the line."""
    full = [f"{name} {st['occupancy']}/{st['depth']}" for name, st in fifos.items()
            if st["occupancy"] >= st["depth"]]
    shown = ", ".join(full[:STOP_LINE_FIFOS])
    if len(full) > STOP_LINE_FIFOS:
        shown += f" and {len(full) - STOP_LINE_FIFOS} more"
    words = [f"full FIFOs: {shown}" if full else "no FIFO is full"]
    words += [f"{name} {st['status']} on {st['waiting_on'][0]}" for name, st in blocks.items()
              if st["waiting_on"] is not None and st["waiting_on"][0] not in fifos]
    cyc = ", ".join(f"{d} {n}" for d, n in cycles.items())
    return f"{head} at {time_text(now_fs)} (cycles run: {cyc}): {'; '.join(words)}; {tail}"


def budget_message(domain: str, limit: int, remedy: str | None = None) -> str:
    """The tail of a :class:`BudgetExceeded` (both cycle engines). The chip's runs give
    ``remedy`` (:attr:`~sim.cycle.plan.ChipPlan.budget_remedy`); a bare kernel run says
    which argument to change."""
    if remedy is None:
        return (f"{domain} ran its budget of {limit} cycles before the until condition held: "
                "raise budget_cycles or check the until condition")
    return f"{domain} reached {limit} cycles before the run completed: {remedy}"


def activity_counts(busy: int, starved: int, blocked: int, idle: int) -> dict[str, int]:
    """A block's cycles by activity, as every engine reports them (sorted keys)."""
    return {"blocked": int(blocked), "busy": int(busy), "idle": int(idle),
            "starved": int(starved)}


def fifo_counts(*, pushes: int, pops: int, depth: int, width_bits: int, max_occupancy: int,
                max_producer_occupancy: int, histogram, cycles_full: int,
                cycles_empty: int) -> dict:
    """A FIFO's statistics, as every engine reports them (sorted keys; see
    :class:`sim.cycle.fifo.Fifo`)."""
    return {
        "bits_transferred": int(pops) * width_bits,
        "cycles_empty": int(cycles_empty),
        "cycles_full": int(cycles_full),
        "depth": int(depth),
        "max_occupancy": int(max_occupancy),
        "max_producer_occupancy": int(max_producer_occupancy),
        "occupancy_histogram": [int(v) for v in histogram],
        "pops": int(pops),
        "pushes": int(pushes),
        "width_bits": int(width_bits),
    }


def watchdog_message(quiet_fs: int, p_max_fs: int, remedy: str | None = None) -> str:
    """The tail of the watchdog's :class:`DeadlockError` (shared by both cycle engines). The
    chip's runs give ``remedy`` (:attr:`~sim.cycle.plan.ChipPlan.watchdog_remedy`: which limit
    fired and how to raise it)."""
    if remedy is None:
        remedy = "deepen a FIFO or change what a block waits for"
    return (f"no FIFO moved and no block was busy for {time_text(quiet_fs)} "
            f"({quiet_fs // p_max_fs} periods of the slowest clock): {remedy}")


def count_instants(edges: list[tuple[int, int, int]]) -> int:
    """Number of distinct instants among clock edges: ``edges`` lists per domain
    ``(phase_fs, period_fs, n)`` for its first ``n`` edges ``phase + k * period``, k < n.

    The kernel runs one step per instant, so this is :attr:`Simulator.steps` after every
    domain ran ``n`` cycles. Inclusion-exclusion over the sets of domains whose edges coincide:
    the common instants of a set solve ``t = phase_d (mod period_d)`` for each member (Chinese
    remainder theorem) and lie below every member's last edge.
    """
    edges = [(ph, per, n) for ph, per, n in edges if n > 0]
    total = 0
    for mask in range(1, 1 << len(edges)):
        members = [edges[i] for i in range(len(edges)) if mask >> i & 1]
        r, m = 0, 1  # t = r (mod m)
        feasible = True
        for ph, per, _ in members:
            g = math.gcd(m, per)
            if (ph - r) % g:
                feasible = False
                break
            # r + m * k = ph (mod per)  ->  k = (ph - r) / g * inv(m / g) (mod per / g)
            k = (ph - r) // g * pow(m // g, -1, per // g) % (per // g)
            r, m = r + m * k, m * per // g
            r %= m
        if not feasible:
            continue
        lo = max(ph for ph, _, _ in members)
        hi = min(ph + (n - 1) * per for ph, per, n in members)
        if hi < lo:
            continue
        first = r + -(-(lo - r) // m) * m  # the first solution >= lo
        count = 0 if first > hi else (hi - first) // m + 1
        total += count if len(members) % 2 else -count
    return total


class Register:
    """A clocked register: ``value`` is the committed value every block reads during evaluation,
    ``next`` the value staged for the coming commit (it holds ``value`` unless written).

    Values are unsigned integers of ``width_bits`` bits, checked at commit. Registers created by
    :meth:`Block.register` are committed by the kernel and traced automatically.
    """

    __slots__ = ("name", "next", "value", "width_bits")

    def __init__(self, name: str, width_bits: int, reset: int = 0):
        check_int(f"register '{name}': width_bits", width_bits, 1, "its width in bits")
        self.name = name
        self.width_bits = width_bits
        self.value = reset
        self.next = reset
        self._check(reset)

    def _check(self, v) -> None:
        if isinstance(v, bool) or not isinstance(v, int) or v < 0 or v >> self.width_bits:
            raise KernelError(f"register '{self.name}' ({self.width_bits} bits) cannot hold {v!r}")

    def commit(self) -> None:
        v = self.next
        if v != self.value:
            self._check(v)
            self.value = v


class Block:
    """Base class of a clocked block.

    Subclasses implement :meth:`evaluate` (read committed state, stage writes, report exactly one
    activity with :meth:`busy`, :meth:`starved`, :meth:`blocked` or :meth:`idle`) and, for state
    that is not kept in :class:`Register`\\ s, :meth:`commit`. The parent hands FIFOs to the
    block's constructor; a block never wires itself.
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
        self._registers: list[Register] = []
        self._counts = dict.fromkeys(ACTIVITIES, 0)
        self._status: str | None = None
        self._waiting: tuple[str, str] | None = None

    # ---- to implement ------------------------------------------------------------------------

    def evaluate(self, now_cycle: int) -> None:
        """One cycle (``now_cycle`` = the domain's edge index): read committed state, stage
        writes, report one activity."""
        raise NotImplementedError(f"block '{self.name}' must implement evaluate()")

    def commit(self) -> None:
        """Apply staged non-register state. Registers commit by themselves after this hook."""

    def signals(self) -> list[tuple[str, int]]:
        """Traced signals as ``(name, width_bits)``; default: the block's registers."""
        return [(r.name, r.width_bits) for r in self._registers]

    def signal_values(self) -> dict:
        """Committed values of :meth:`signals`."""
        return {r.name: r.value for r in self._registers}

    # ---- helpers for subclasses --------------------------------------------------------------

    def register(self, name: str, width_bits: int, reset: int = 0) -> Register:
        """A register owned by this block (committed and traced by the kernel)."""
        if any(r.name == name for r in self._registers):
            raise ConfigError(f"block '{self.name}' already has a register named '{name}'")
        reg = Register(name, width_bits, reset)
        self._registers.append(reg)
        return reg

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

    def _commit_all(self) -> None:
        self.commit()
        for reg in self._registers:
            reg.commit()
