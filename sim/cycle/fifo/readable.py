"""A clocked FIFO with a stated depth, width and latency, optionally crossing clock domains.

The producer (a block of the ``src`` domain) and the consumer (a block of the ``dst`` domain)
each see the FIFO through committed state only; pushes and pops are staged during evaluation and
applied at the commit of the step. The rules (docs/clock-kernel.md has timing diagrams):

* **Data.** An item pushed at the producer edge at instant ``t`` can be popped from the
  ``n``-th consumer edge strictly after ``t``, with ``n = latency_cycles`` in one domain and
  ``n = latency_cycles + sync_cycles - 1`` across domains. In one domain: pushed in cycle ``c``,
  poppable in cycle ``c + latency_cycles``.
* **Space.** A slot freed by a pop at the consumer edge at instant ``t`` counts as free for the
  producer from the ``m``-th producer edge strictly after ``t``, with ``m = 1`` in one domain
  (the next cycle) and ``m = sync_cycles`` across domains (the read pointer is synchronised back).
  The producer counts its own pushes at once, so its view of the occupancy is never below the
  real one and the FIFO never holds more than ``depth`` items.

Consequences in one domain with latency 1: depth 1 moves one item every 2 cycles, depth 2 one
item per cycle; in general a FIFO sustains ``min(1, depth / (latency_cycles + 1))`` items per
cycle.

The rule itself (the edges, visibility and room) is the FIFO block's, :mod:`.rule`, which the
compiled engine and the estimate call too; this class is its readable twin, and its statistics
are the ones every engine reports (:mod:`.counts`). Compiled twin: ``sim/cycle/compiled/fifo.py``
(the walk) and :mod:`.compiled`. :class:`KernelError`, the readable kernel's error, lives here
too: most of the rules it enforces are the FIFO's, and the kernel (:mod:`sim.cycle.readable`)
raises it for the rest.
"""

from __future__ import annotations

from collections import deque

from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.fifo.counts import fifo_counts
from stereosim.sim.cycle.fifo.rule import fifo_edges, room_at, visible_at
from stereosim.sim.cycle.rules import ClockDomain, check_int


class KernelError(RuntimeError):
    """A block or the wiring broke a rule of the kernel (a bug in a model, not in user input):
    pushing into a full FIFO, two pushes in one cycle, popping an item that is not visible,
    touching a FIFO outside its domain's edge, reporting no or two activities in a cycle."""


class Fifo:
    """``depth`` items of ``width_bits`` bits from domain ``src`` to domain ``dst``.

    Producer API (evaluate() of a ``src`` block): :meth:`can_push`, :meth:`push`.
    Consumer API (evaluate() of a ``dst`` block): :meth:`can_pop`, :meth:`peek`, :meth:`pop`,
    :meth:`visible_count`. At most one push per producer cycle and one pop per consumer cycle.

    Statistics (:meth:`stats`): pushes, pops, the largest committed occupancy
    (``max_occupancy``, items physically held), the largest occupancy the producer saw after its
    push (``max_producer_occupancy``: slots in use including those whose freeing had not reached
    the producer yet -- any depth at least this large accepts every push this run made), a
    histogram of the committed occupancy at each consumer edge (index = occupancy), producer
    cycles that began with the FIFO full as the producer sees it (``cycles_full``), consumer
    cycles that began with no item visible (``cycles_empty``), and ``bits_transferred`` (pops x
    width_bits).
    """

    def __init__(
        self,
        name: str,
        depth: int,
        width_bits: int,
        latency_cycles: int = 1,
        *,
        src: ClockDomain,
        dst: ClockDomain,
        sync_cycles: int = 2,
        handshake_signals: bool = False,
    ):
        if not isinstance(name, str) or not name:
            raise ConfigError(f"FIFO name must be a non-empty string; got {name!r}")
        check_int(
            f"fifo '{name}': depth", depth, 1, "a FIFO needs at least one slot: use depth=1 or more"
        )
        check_int(f"fifo '{name}': width_bits", width_bits, 1, "the width of one item in bits")
        check_int(
            f"fifo '{name}': latency_cycles",
            latency_cycles,
            1,
            "no combinational path: use latency_cycles=1 or more",
        )
        check_int(
            f"fifo '{name}': sync_cycles", sync_cycles, 1, "synchroniser stages, typically 2"
        )
        for role, dom in (("src", src), ("dst", dst)):
            if not isinstance(dom, ClockDomain):
                raise ConfigError(f"fifo '{name}': {role} must be a ClockDomain; got {dom!r}")
        self.name = name
        self.depth = depth
        self.width_bits = width_bits
        self.latency_cycles = latency_cycles
        self.sync_cycles = sync_cycles
        self.src = src
        self.dst = dst
        self.crossing = src != dst
        # n-th consumer edge after a push, m-th producer edge after a pop (module docstring)
        self._data_edges, self._space_edges = fifo_edges(latency_cycles, sync_cycles,
                                                         self.crossing)

        self._items: deque = deque()  # (first consumer cycle it is visible, item), in order
        self._frees: deque = deque()  # first producer cycle each freed slot is seen, in order
        self._pushes = 0
        self._pops = 0
        self._frees_seen = 0
        self._src_cycle = -1
        self._dst_cycle = -1
        self._src_open = False
        self._dst_open = False
        self._push_staged = False
        self._push_item = None
        self._pop_staged = False
        self._src_ticked = False
        self._dst_ticked = False
        self.pushed = False  # pushed at the producer's last edge (traced)
        self.popped = False  # popped at the consumer's last edge (traced)
        self.handshake_signals = handshake_signals

        self._max_occupancy = 0
        self._max_producer_occupancy = 0
        self._histogram = [0] * (depth + 1)
        self._cycles_full = 0
        self._cycles_empty = 0

    def __repr__(self) -> str:
        return f"Fifo({self.name!r}, {self.occupancy}/{self.depth})"

    # ---- views -------------------------------------------------------------------------------

    @property
    def occupancy(self) -> int:
        """Items physically held (committed pushes minus committed pops)."""
        return self._pushes - self._pops

    @property
    def pushes(self) -> int:
        return self._pushes

    @property
    def pops(self) -> int:
        return self._pops

    @property
    def producer_occupancy(self) -> int:
        """The occupancy as the producer sees it now (frees reach it late)."""
        return self._pushes - self._frees_seen

    def visible_count(self) -> int:
        """How many items, from the head, the consumer can see in this cycle."""
        n = 0
        cyc = self._dst_cycle
        for ready, _ in self._items:
            if ready > cyc:
                break
            n += 1
        return n

    # ---- producer ----------------------------------------------------------------------------

    def can_push(self) -> bool:
        """True if the producer sees a free slot and has not pushed in this cycle."""
        return not self._push_staged and self._pushes - self._frees_seen < self.depth

    def push(self, item) -> None:
        """Stage ``item``; it enters the FIFO at this step's commit."""
        if not self._src_open:
            raise KernelError(
                f"fifo '{self.name}' pushed outside an edge of its producer domain "
                f"'{self.src.name}' (or the FIFO was not added with add_fifo)"
            )
        if self._push_staged:
            raise KernelError(f"fifo '{self.name}' pushed twice in one producer cycle")
        if self._pushes - self._frees_seen >= self.depth:
            raise KernelError(
                f"fifo '{self.name}' pushed while full ({self.depth}/{self.depth} as the "
                "producer sees it); check can_push() first"
            )
        self._push_staged = True
        self._push_item = item

    # ---- consumer ----------------------------------------------------------------------------

    def can_pop(self) -> bool:
        """True if the head item is visible to the consumer and it has not popped this cycle."""
        items = self._items
        return not self._pop_staged and bool(items) and items[0][0] <= self._dst_cycle

    def peek(self, index: int = 0):
        """The ``index``-th visible item from the head (not removed)."""
        if self._pop_staged:
            raise KernelError(f"fifo '{self.name}' peeked after a pop in the same cycle")
        if not 0 <= index < self.visible_count():
            raise KernelError(
                f"fifo '{self.name}' has no visible item {index} (visible: "
                f"{self.visible_count()}); check can_pop() or visible_count() first"
            )
        return self._items[index][1]

    def pop(self):
        """Stage the removal of the head item and return it."""
        if not self._dst_open:
            raise KernelError(
                f"fifo '{self.name}' popped outside an edge of its consumer domain "
                f"'{self.dst.name}' (or the FIFO was not added with add_fifo)"
            )
        if self._pop_staged:
            raise KernelError(f"fifo '{self.name}' popped twice in one consumer cycle")
        if not self.can_pop():
            raise KernelError(
                f"fifo '{self.name}' popped with no visible item; check can_pop() first"
            )
        self._pop_staged = True
        return self._items[0][1]

    # ---- kernel side -------------------------------------------------------------------------

    def _begin_step(self, ticking: set, cycles: dict) -> None:
        """Open the FIFO for the domains that tick now and sample the per-cycle statistics."""
        self._src_ticked = self.src.name in ticking
        self._dst_ticked = self.dst.name in ticking
        if self._src_ticked:
            self._src_open = True
            cyc = self._src_cycle = cycles[self.src.name]
            frees = self._frees
            while frees and frees[0] <= cyc:
                frees.popleft()
                self._frees_seen += 1
            if self._pushes - self._frees_seen >= self.depth:
                self._cycles_full += 1
        if self.dst.name in ticking:
            self._dst_open = True
            cyc = self._dst_cycle = cycles[self.dst.name]
            self._histogram[self._pushes - self._pops] += 1
            items = self._items
            if not items or items[0][0] > cyc:
                self._cycles_empty += 1

    def _commit(self, now_fs: int) -> bool:
        """Apply the staged push and pop; True if either happened."""
        if self._src_ticked:
            self.pushed = self._push_staged
        if self._dst_ticked:
            self.popped = self._pop_staged
        pushed = self._push_staged
        if pushed:
            ready = visible_at(now_fs, self.dst, self._data_edges)
            self._items.append((ready, self._push_item))
            self._pushes += 1
            self._push_staged = False
            self._push_item = None
        popped = self._pop_staged
        if popped:
            self._items.popleft()
            self._pops += 1
            self._frees.append(room_at(now_fs, self.src, self._space_edges))
            self._pop_staged = False
        if pushed:  # only a push raises the occupancy, or the producer's view of it
            occ = self._pushes - self._pops
            self._max_occupancy = max(self._max_occupancy, occ)
            seen = self._pushes - self._frees_seen
            self._max_producer_occupancy = max(self._max_producer_occupancy, seen)
        self._src_open = False
        self._dst_open = False
        return pushed or popped

    # ---- tracing and statistics --------------------------------------------------------------

    def signals(self) -> list[tuple[str, int]]:
        if not self.handshake_signals:
            return [("occupancy", self.depth.bit_length())]
        return [("occupancy", self.depth.bit_length()), ("push", 1), ("pop", 1), ("full", 1),
                ("empty", 1)]

    def signal_values(self) -> dict:
        """Committed occupancy; with ``handshake_signals``, also the push (pop) of the
        producer's (consumer's) last edge, full as the producer sees it, and empty."""
        occ = self._pushes - self._pops
        if not self.handshake_signals:
            return {"occupancy": occ}
        return {"occupancy": occ, "push": int(self.pushed), "pop": int(self.popped),
                "full": int(self._pushes - self._frees_seen >= self.depth),
                "empty": int(occ == 0)}

    def stats(self) -> dict:
        return fifo_counts(
            pushes=self._pushes, pops=self._pops, depth=self.depth, width_bits=self.width_bits,
            max_occupancy=self._max_occupancy,
            max_producer_occupancy=self._max_producer_occupancy, histogram=self._histogram,
            cycles_full=self._cycles_full, cycles_empty=self._cycles_empty)
