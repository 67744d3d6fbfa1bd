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
import random
from collections.abc import Callable
from dataclasses import dataclass

from sim.errors import ConfigError, UserError

FS_PER_S = 10**15
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
    """

    def __init__(self, message: str, *, time_fs: int, cycles: dict, fifos: dict, blocks: dict):
        super().__init__(message)
        self.time_fs = time_fs
        self.cycles = cycles
        self.fifos = fifos
        self.blocks = blocks


class DeadlockError(RunStopped):
    """No FIFO moved and no block was busy for ``watchdog_cycles`` periods of the slowest clock."""


class BudgetExceeded(RunStopped):
    """A clock domain would have run more cycles than the run's budget allows."""


def _check_int(what: str, value, lo: int, fix: str) -> int:
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
        if round(FS_PER_S / f) < 1:
            raise ConfigError(
                f"clock domain '{self.name}': freq_hz {f!r} gives a period below 1 fs; "
                "use at most 1e15 Hz"
            )
        _check_int(
            f"clock domain '{self.name}': phase_fs", self.phase_fs, 0, "the first edge's time in fs"
        )

    @property
    def period_fs(self) -> int:
        return round(FS_PER_S / self.freq_hz)

    def edge_fs(self, k: int) -> int:
        """The instant of edge ``k``."""
        return self.phase_fs + k * self.period_fs

    def first_edge_after(self, t_fs: int) -> int:
        """Index of the first edge strictly after the instant ``t_fs``."""
        if t_fs < self.phase_fs:
            return 0
        return (t_fs - self.phase_fs) // self.period_fs + 1


def watchdog_message(quiet_fs: int, p_max_fs: int) -> str:
    """The tail of the watchdog's :class:`DeadlockError` (shared by both cycle engines)."""
    return (f"no FIFO moved and no block was busy for {quiet_fs} fs ({quiet_fs // p_max_fs} "
            "periods of the slowest clock): deepen a FIFO or change what a block waits for")


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
        _check_int(f"register '{name}': width_bits", width_bits, 1, "its width in bits")
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

    @property
    def activity(self) -> dict[str, int]:
        """Cycles spent busy / starved / blocked / idle so far (sorted keys)."""
        return {k: self._counts[k] for k in sorted(ACTIVITIES)}

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


class Simulator:
    """Holds the domains, FIFOs and blocks of a model and runs them step by step.

    ``order_seed``: if given, the evaluation (and commit) order of the blocks is shuffled in every
    step with ``random.Random(order_seed)`` -- results must not change. ``trace``: a callable
    ``trace(time_fs, {domain: cycle_index}, {"block.signal": value})`` invoked after every step's
    commit with the domains that ticked and the signals whose committed value changed (every
    signal the first time it is seen).
    """

    def __init__(self, order_seed: int | None = None, trace: Callable | None = None):
        self._rng = random.Random(order_seed) if order_seed is not None else None
        self._trace = trace
        self._domains: dict[str, ClockDomain] = {}
        self._fifos: dict = {}
        self._blocks: dict[str, Block] = {}
        self._cycles: dict[str, int] = {}
        self._next_fs: dict[str, int] = {}
        self._blocks_of: dict[str, list[Block]] = {}
        self._fifos_of: dict[str, list] = {}
        self._last_values: dict[str, object] = {}
        self._started = False
        self.now_fs = 0
        self.steps = 0

    # ---- building ----------------------------------------------------------------------------

    def _check_open(self, what: str) -> None:
        if self._started:
            raise KernelError(f"cannot add {what} after the simulation has started")

    def _check_name(self, name: str) -> None:
        if name in self._blocks or name in self._fifos:
            raise ConfigError(
                f"name '{name}' is already used by a block or FIFO; give every block and FIFO "
                "a unique name"
            )

    def _check_domain(self, owner: str, domain: ClockDomain) -> None:
        if self._domains.get(domain.name) != domain:
            raise ConfigError(
                f"{owner} uses clock domain '{domain.name}', which is not added to this "
                "simulator; call add_domain() first"
            )

    def add_domain(self, domain: ClockDomain) -> ClockDomain:
        self._check_open(f"clock domain '{domain.name}'")
        if not isinstance(domain, ClockDomain):
            raise ConfigError(f"add_domain expects a ClockDomain; got {domain!r}")
        if domain.name in self._domains:
            raise ConfigError(f"clock domain '{domain.name}' is already added")
        self._domains[domain.name] = domain
        self._cycles[domain.name] = 0
        self._next_fs[domain.name] = domain.phase_fs
        self._blocks_of[domain.name] = []
        self._fifos_of[domain.name] = []
        return domain

    def add_fifo(self, fifo):
        from sim.fifo import Fifo

        if not isinstance(fifo, Fifo):
            raise ConfigError(f"add_fifo expects a Fifo; got {fifo!r}")
        self._check_open(f"FIFO '{fifo.name}'")
        self._check_name(fifo.name)
        self._check_domain(f"FIFO '{fifo.name}'", fifo.src)
        self._check_domain(f"FIFO '{fifo.name}'", fifo.dst)
        self._fifos[fifo.name] = fifo
        self._fifos_of[fifo.src.name].append(fifo)
        if fifo.dst != fifo.src:
            self._fifos_of[fifo.dst.name].append(fifo)
        return fifo

    def add_block(self, block: Block) -> Block:
        if not isinstance(block, Block):
            raise ConfigError(f"add_block expects a Block; got {block!r}")
        self._check_open(f"block '{block.name}'")
        self._check_name(block.name)
        self._check_domain(f"block '{block.name}'", block.domain)
        self._blocks[block.name] = block
        self._blocks_of[block.domain.name].append(block)
        return block

    # ---- state -------------------------------------------------------------------------------

    @property
    def cycles(self) -> dict[str, int]:
        """Cycles run so far per domain (= index of each domain's next edge)."""
        return dict(sorted(self._cycles.items()))

    def signal_values(self) -> dict[str, object]:
        """Every traced signal's committed value, as ``{"owner.signal": value}``."""
        out = {}
        for owner in (*self._blocks.values(), *self._fifos.values()):
            for sig, v in owner.signal_values().items():
                out[f"{owner.name}.{sig}"] = v
        return out

    def signals(self) -> list[tuple[str, int]]:
        """Every traced signal as ``("owner.signal", width_bits)``, blocks then FIFOs."""
        return [
            (f"{owner.name}.{sig}", width)
            for owner in (*self._blocks.values(), *self._fifos.values())
            for sig, width in owner.signals()
        ]

    def stats(self) -> dict:
        """Cycles per domain, end time, per-block activity and per-FIFO statistics (plain ints,
        sorted keys, so two equal runs give equal dicts)."""
        return {
            "blocks": {n: self._blocks[n].activity for n in sorted(self._blocks)},
            "cycles": self.cycles,
            "end_time_fs": self.now_fs,
            "fifos": {n: self._fifos[n].stats() for n in sorted(self._fifos)},
            "steps": self.steps,
        }

    def _state(self) -> tuple[dict, dict, str, str]:
        fifos = {f.name: {"occupancy": f.occupancy, "depth": f.depth} for f in self._fifos.values()}
        blocks = {
            b.name: {"status": b.status, "waiting_on": b.waiting_on} for b in self._blocks.values()
        }
        fifo_words = []
        for name, st in fifos.items():
            occ, depth = st["occupancy"], st["depth"]
            tag = " full" if occ >= depth else " empty" if occ == 0 else ""
            fifo_words.append(f"{name} {occ}/{depth}{tag}")
        block_words = []
        for name, st in blocks.items():
            if st["waiting_on"] is not None:
                fname, kind = st["waiting_on"]
                block_words.append(f"{name} {st['status']} on {fname} ({kind})")
            else:
                block_words.append(f"{name} {st['status'] or 'never clocked'}")
        return (
            fifos,
            blocks,
            "fifo " + (", ".join(fifo_words) or "none"),
            "blocks: " + (", ".join(block_words) or "none"),
        )

    def _stop(self, cls, head: str, tail: str):
        fifos, blocks, fifo_text, block_text = self._state()
        cyc = ", ".join(f"{d} {n}" for d, n in self._cycles.items())
        msg = f"{head} at t={self.now_fs} fs (cycles run: {cyc}): {fifo_text}; {block_text}; {tail}"
        return cls(msg, time_fs=self.now_fs, cycles=self.cycles, fifos=fifos, blocks=blocks)

    # ---- running -----------------------------------------------------------------------------

    def step(self) -> bool:
        """Advance to the next instant with a clock edge and run it (both phases).

        Returns True if the step made progress (a FIFO push or pop, or a busy block).
        """
        if not self._domains:
            raise ConfigError("the simulator has no clock domain; call add_domain() first")
        self._started = True
        next_fs = self._next_fs
        t = min(next_fs.values())
        ticking = [d for d, nt in next_fs.items() if nt == t]
        cycles = self._cycles
        self.now_fs = t
        if len(ticking) == 1:
            d = ticking[0]
            blocks = list(self._blocks_of[d])
            fifos = self._fifos_of[d]
        else:
            blocks = [b for d in ticking for b in self._blocks_of[d]]
            fifos = list({id(f): f for d in ticking for f in self._fifos_of[d]}.values())
        tick_set = set(ticking)
        for f in fifos:
            f._begin_step(tick_set, cycles)
        rng = self._rng
        if rng is not None:
            rng.shuffle(blocks)
        progress = False
        for b in blocks:
            if b._tick(cycles[b.domain.name]):
                progress = True
        if rng is not None:
            rng.shuffle(blocks)
        for b in blocks:
            b._commit_all()
        for f in fifos:
            if f._commit(t):
                progress = True
        if self._trace is not None:
            self._emit_trace(t, ticking, blocks, fifos)
        for d in ticking:
            cycles[d] += 1
            next_fs[d] = t + self._domains[d].period_fs
        self.steps += 1
        return progress

    def _emit_trace(self, t: int, ticking, blocks, fifos) -> None:
        last = self._last_values
        changed = {}
        owners = sorted([*blocks, *fifos], key=lambda o: o.name)
        for owner in owners:
            for sig, v in owner.signal_values().items():
                path = f"{owner.name}.{sig}"
                if path not in last or last[path] != v:
                    last[path] = v
                    changed[path] = v
        self._trace(t, {d: self._cycles[d] for d in sorted(ticking)}, changed)

    def run(
        self,
        until: Callable[[], bool],
        *,
        budget_cycles: dict[str, int] | int,
        watchdog_cycles: int | None = 1000,
    ) -> dict:
        """Step until ``until()`` is true (checked before the first step and after every step).

        ``budget_cycles``: the most cycles this run may execute, for every domain (int) or per
        domain name (dict; domains not named are unbounded). The run raises
        :class:`BudgetExceeded` instead of starting a step that would take a domain past it.
        ``watchdog_cycles``: raise :class:`DeadlockError` at the first step without progress
        that ends ``watchdog_cycles`` periods of the slowest clock domain after the last step
        with progress (or after one slowest period before the run's first step); ``None``
        disables it. In time, not in steps, so an engine that skips quiet stretches reaches the
        same verdict at the same instant. Returns :meth:`stats`.
        """
        budget = self._budget(budget_cycles)
        if watchdog_cycles is not None:
            _check_int(
                "watchdog_cycles", watchdog_cycles, 1,
                "periods of the slowest clock without progress before a deadlock"
            )
        start = dict(self._cycles)
        p_max = max((dom.period_fs for dom in self._domains.values()), default=1)
        # time of the last step with progress; before the first step: one slowest period back
        last_progress = (min(self._next_fs.values()) if self._domains else 0) - p_max
        while not until():
            t = min(self._next_fs.values()) if self._domains else 0
            for d, limit in budget.items():
                if self._next_fs[d] == t and self._cycles[d] - start[d] >= limit:
                    raise self._stop(
                        BudgetExceeded,
                        "cycle budget exceeded",
                        f"{d} ran its budget of {limit} cycles before the until condition held: "
                        "raise budget_cycles or check the until condition",
                    )
            if self.step():
                last_progress = t
            elif (watchdog_cycles is not None and t - last_progress >= watchdog_cycles * p_max
                  and not until()):
                raise self._stop(DeadlockError, "deadlock",
                                 watchdog_message(t - last_progress, p_max))
        return self.stats()

    def _budget(self, budget_cycles) -> dict[str, int]:
        if isinstance(budget_cycles, dict):
            out = {}
            for d, n in budget_cycles.items():
                if d not in self._domains:
                    known = ", ".join(self._domains) or "none"
                    raise ConfigError(
                        f"budget_cycles names unknown clock domain '{d}' (known: {known})"
                    )
                out[d] = _check_int(
                    f"budget_cycles['{d}']", n, 0, "the most cycles this run may take"
                )
            return out
        n = _check_int("budget_cycles", budget_cycles, 0, "the most cycles this run may take")
        return dict.fromkeys(self._domains, n)
