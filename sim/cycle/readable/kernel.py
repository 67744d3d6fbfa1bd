"""The readable scheduler: runs the blocks and FIFOs of a model edge by edge, in two phases.

The rules of time, steps, phases, activity and progress are those of :mod:`sim.cycle.readable.clock`
(docs/clock-kernel.md): at each instant with a clock edge every block of every ticking domain
evaluates from committed state, then everything commits.
"""

from __future__ import annotations

import random
from collections.abc import Callable

from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.contract import (
    BUDGET_HEAD,
    BudgetExceeded,
    DeadlockError,
    budget_message,
    stop_message,
    watchdog_message,
)
from stereosim.sim.cycle.fifo.readable import Fifo, KernelError
from stereosim.sim.cycle.readable.clock import Block
from stereosim.sim.cycle.rules import ClockDomain, check_int

# Steps between two calls of Simulator.run's on_progress (some tens per second).
PROGRESS_STEPS = 4096


class Simulator:
    """Holds the domains, FIFOs and blocks of a model and runs them step by step.

    ``order_seed``: if given, the evaluation (and commit) order of the blocks is shuffled in every
    step with ``random.Random(order_seed)`` -- results must not change. ``trace``: a callable
    ``trace(time_fs, {domain: cycle_index}, {"block.signal": value})`` invoked after every step's
    commit with the domains that ticked and the signals whose committed value changed (every
    signal the first time it is seen). ``trace_end_fs``: the hook is not called for steps at or
    after this instant (a trace window's end: nothing after it is recorded, and computing the
    signals of every later step would only cost time).
    """

    def __init__(self, order_seed: int | None = None, trace: Callable | None = None,
                 trace_end_fs: int | None = None):
        self._rng = random.Random(order_seed) if order_seed is not None else None
        self._trace = trace
        self._trace_end_fs = trace_end_fs
        self._domains: dict[str, ClockDomain] = {}
        self._fifos: dict = {}
        self._blocks: dict[str, Block] = {}
        self._cycles: dict[str, int] = {}
        self._next_fs: dict[str, int] = {}
        self._blocks_of: dict[str, list[Block]] = {}
        self._fifos_of: dict[str, list] = {}
        self._groups: dict[tuple[str, ...], tuple[list, list, frozenset]] = {}
        # the trace's last value of each owner's signals, and its owners by set of ticking domains
        self._last_values: dict[str, dict[str, object]] = {}
        self._trace_owners: dict[tuple, list] = {}
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
        """Cycles per domain, end time, per-block activity, per-FIFO statistics and the
        activity of the stages of blocks that have them (plain ints, sorted keys, so two equal
        runs give equal dicts)."""
        return {
            "blocks": {n: self._blocks[n].activity for n in sorted(self._blocks)},
            "cycles": self.cycles,
            "end_time_fs": self.now_fs,
            "fifos": {n: self._fifos[n].stats() for n in sorted(self._fifos)},
            "stages": {n: self._blocks[n].stage_stats() for n in sorted(self._blocks)
                       if self._blocks[n].stage_stats()},
            "steps": self.steps,
        }

    def _state(self) -> tuple[dict, dict]:
        fifos = {f.name: {"occupancy": f.occupancy, "depth": f.depth} for f in self._fifos.values()}
        blocks = {
            b.name: {"status": b.status, "waiting_on": b.waiting_on} for b in self._blocks.values()
        }
        return fifos, blocks

    def stop(self, cls, message: str):
        """A :class:`~sim.cycle.contract.RunStopped` of class ``cls`` with ``message`` and the
        state after the last executed step (for a stop the model decides, such as a camera's
        overflow)."""
        fifos, blocks = self._state()
        return cls(message, time_fs=self.now_fs, cycles=self.cycles, fifos=fifos,
                   blocks=blocks)

    def _stop(self, cls, head: str, tail: str):
        fifos, blocks = self._state()
        return self.stop(cls, stop_message(head, self.now_fs, dict(self._cycles), fifos, blocks,
                                           tail))

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
        blocks, fifos, tick_set = self._ticking_group(tuple(ticking))
        for f in fifos:
            f._begin_step(tick_set, cycles)
        rng = self._rng
        if rng is not None:
            blocks = list(blocks)
            rng.shuffle(blocks)
        progress = False
        for b in blocks:
            if b._tick(cycles[b.domain.name]):
                progress = True
        if rng is not None:
            rng.shuffle(blocks)
        for b in blocks:
            b.commit()
        for f in fifos:
            if f._commit(t):
                progress = True
        if self._trace is not None and (self._trace_end_fs is None or t < self._trace_end_fs):
            self._emit_trace(t, ticking, blocks, fifos)
        for d in ticking:
            cycles[d] += 1
            next_fs[d] = t + self._domains[d].period_fs
        self.steps += 1
        return progress

    def _ticking_group(self, ticking: tuple[str, ...]) -> tuple[list, list, frozenset]:
        """The blocks and the FIFOs (each once) of the domains ``ticking`` at an instant, and
        the set of those domains: the same every time these domains tick together, so built
        the first time (no block or FIFO is added once the run has started)."""
        group = self._groups.get(ticking)
        if group is None:
            blocks = [b for d in ticking for b in self._blocks_of[d]]
            fifos = list({id(f): f for d in ticking for f in self._fifos_of[d]}.values())
            group = self._groups[ticking] = (blocks, fifos, frozenset(ticking))
        return group

    def _emit_trace(self, t: int, ticking, blocks, fifos) -> None:
        """Report the signals whose committed value changed in this step, every owner (block
        or FIFO) of the ticking domains in name order, each owner's signals in its order."""
        key = (tuple(ticking), len(blocks), len(fifos))
        owners = self._trace_owners.get(key)
        if owners is None:  # the same owners every time these domains tick together
            owners = sorted([*blocks, *fifos], key=lambda o: o.name)
            self._trace_owners[key] = owners
        last = self._last_values
        changed = {}
        for owner in owners:
            seen = last.setdefault(owner.name, {})
            for sig, v in owner.signal_values().items():
                if sig not in seen or seen[sig] != v:
                    seen[sig] = v
                    changed[f"{owner.name}.{sig}"] = v
        self._trace(t, {d: self._cycles[d] for d in sorted(ticking)}, changed)

    def run(
        self,
        until: Callable[[], bool],
        *,
        budget_cycles: dict[str, int] | int,
        watchdog_cycles: int | None = 1000,
        budget_remedy: str | None = None,
        budget_head: str = BUDGET_HEAD,
        watchdog_remedy: str | None = None,
        on_progress: Callable[[], None] | None = None,
    ) -> dict:
        """Step until ``until()`` is true (checked before the first step and after every step).

        ``budget_cycles``: the most cycles this run may execute, for every domain (int) or per
        domain name (dict; domains not named are unbounded). The run raises
        :class:`BudgetExceeded` instead of starting a step that would take a domain past it.
        ``watchdog_cycles``: raise :class:`DeadlockError` at the first step without progress
        that ends ``watchdog_cycles`` periods of the slowest clock domain after the last step
        with progress (or after one slowest period before the run's first step); ``None``
        disables it. ``budget_remedy``, ``watchdog_remedy``: what the budget's and the
        watchdog's messages tell the user to change; ``budget_head``: how the budget's message
        begins (a limit the user set is not an error).
        In time, not in steps, so an engine that skips quiet stretches reaches the
        same verdict at the same instant. ``on_progress()`` is called every
        :data:`PROGRESS_STEPS` steps and at the end, for a progress bar; it must not touch the
        model. Returns :meth:`stats`.
        """
        budget = self._budget(budget_cycles)
        if watchdog_cycles is not None:
            check_int(
                "watchdog_cycles", watchdog_cycles, 1,
                "periods of the slowest clock without progress before a deadlock"
            )
        start = dict(self._cycles)
        p_max = max((dom.period_fs for dom in self._domains.values()), default=1)
        # time of the last step with progress; before the first step: one slowest period back
        last_progress = (min(self._next_fs.values()) if self._domains else 0) - p_max
        countdown = PROGRESS_STEPS
        while not until():
            t = min(self._next_fs.values()) if self._domains else 0
            for d, limit in budget.items():
                if self._next_fs[d] == t and self._cycles[d] - start[d] >= limit:
                    raise self._stop(BudgetExceeded, budget_head,
                                     budget_message(d, limit, budget_remedy))
            if self.step():
                last_progress = t
            elif (watchdog_cycles is not None and t - last_progress >= watchdog_cycles * p_max
                  and not until()):
                raise self._stop(DeadlockError, "deadlock",
                                 watchdog_message(t - last_progress, p_max,
                                                  watchdog_remedy))
            countdown -= 1
            if countdown == 0:
                countdown = PROGRESS_STEPS
                if on_progress is not None:
                    on_progress()
        if on_progress is not None:
            on_progress()
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
                out[d] = check_int(
                    f"budget_cycles['{d}']", n, 0, "the most cycles this run may take"
                )
            return out
        n = check_int("budget_cycles", budget_cycles, 0, "the most cycles this run may take")
        return dict.fromkeys(self._domains, n)
