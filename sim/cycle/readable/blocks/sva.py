"""The SVA as a clocked block of the readable kernel: row buffers in front of a lock-step
pipeline of stages.

Ports: ``in_left``, ``in_right`` (:class:`~sim.cycle.readable.beats.DescriptorBeat`\\ s in
raster order, frame after frame), ``out`` (:class:`~sim.cycle.readable.beats.WordBeat`\\ s in
raster order). Rows, words and counters run over the stream of frames: output row r is row
r % H of frame r // H.

- **Input** (the row buffers): pops one left/right pair per cycle when both are visible (a joint
  pop) and the row being received fits the row buffers
  (:func:`~sim.cycle.rules.sva_rows_done_before_input`: y_in <= y_issued + r + 1, r the box
  radius, y_issued the box rows whose every slot has been issued; a frame's rows r + 2 ..
  2r + 2 once the previous frame is issued): the buffers hold the rows the next box row
  reads, the one leaving its column sums included, plus one row arriving (their sizes are in
  the plan). The input side does not stall with the pipeline.
- **Sequencer** (:func:`~sim.cycle.rules.sva_slot`): a frame is k - 1 *passes* of W slots that
  seed the box filter's column sums, then per box row W + r slots, the first r of a row
  filling the box's row window and the others each *issuing* a word (read from the row
  buffers into the first stage). In a cycle in which the pipeline advances the next slot goes
  if the input row it adds is complete, a slot II (``slot_ii``) of ticks after the
  previous slot, a word an II of ticks after the previous word, and a frame's first slot
  after the median's flush of the previous frame (:func:`~sim.cycle.rules.sva_frame_start`).
- **Pipeline** (:mod:`sim.cycle.stages`): the stages in stream order, L cycles of latency in all,
  move in lock-step. Its *tick* counts the cycles in which it advanced. Word j issued at tick
  t_j is in stage s while offset_s < tick - t_j <= offset_s + latency_s; it is in the output
  register at its exit tick, L after the tick of the word it leaves with
  (:func:`~sim.cycle.rules.sva_exit_item`: itself, or with the median the word m W + m after
  it, or a flush tick): it is pushed then if ``out`` has room; if not, the whole pipeline
  *stalls* (nothing moves, nothing is issued, the tick holds) until it has.
- **Data**: the functional model's streaming kernels (:class:`sva.pipeline.pipeline.SvaStream`) run
over
  the descriptors this block actually received, row by row as rows complete.

Activity: busy when a pair is popped, a word issued or pushed, a word is in the pipeline, or
the next word's row is ready (its slots and passes are going, or it waits out the II); blocked
when the pipeline stalls; starved when no word is in the pipeline and the next word's row is
not ready (a frame's passes included); idle when the frame is out. Each stage reports its
own in every cycle: busy when it holds a word and the pipeline advances, blocked when it holds
one and the pipeline stalls, starved when it holds none, idle once the frame's last word has
left it; with the most words it held (``stage_stats``).

Traced: ``status``, ``input.row`` / ``input.col`` (the next pair), ``input.rows_ready``
(box rows ready), ``output.row`` / ``output.col`` (the next word), ``output.valid`` (pushed
in its last cycle), ``output.disparity`` (the last word pushed), ``lr_check.reject`` (that word
is invalid), ``pipeline.issue`` (a word entered this cycle), ``pipeline.stall``,
``pipeline.words`` (words issued and not yet pushed), and per stage ``stage.<name>.status`` and
``stage.<name>.words``.

Compiled twin: ``sim/cycle/compiled/sva.py``.
"""

from __future__ import annotations

from bisect import bisect_left
from collections import deque

import numpy as np

from stereosim.sim.cycle.contract import ACTIVITIES
from stereosim.sim.cycle.fifo.readable import Fifo
from stereosim.sim.cycle.plan import STATUS_CODES, BlockPlan, ChipPlan
from stereosim.sim.cycle.readable.beats import WordBeat
from stereosim.sim.cycle.readable.blocks.base import ChipBlock
from stereosim.sim.cycle.rules import (
    frame_row,
    rows_ready_in_frame,
    sva_exit_item,
    sva_frame_start,
    sva_issue_tick,
    sva_last_input_row,
    sva_rows_done_before_input,
    sva_slot,
)
from stereosim.sim.cycle.stages import stage_offsets
from stereosim.sva.pipeline.pipeline import SvaStream

NEVER = -(1 << 40)  # "the previous tick" before the first slot


class SvaBlock(ChipBlock):
    """The SVA of the plan entry ``entry`` (box radius, passes, skew, slot II, stages,
    latency, II): the module docstring's rules. Ports: ``inputs`` = [``in_left``,
    ``in_right``], ``outputs`` = [``out``]; its data path is the plan's configuration
    (``sva``) over descriptors of the plan's ``descriptor_bits``, its words ``word_bits``
    wide."""

    def __init__(self, plan: ChipPlan, entry: BlockPlan, inputs: list[Fifo],
                 outputs: list[Fifo]):
        super().__init__(plan, entry, inputs, outputs)
        self.height, self.width = plan.shape
        self.in_left, self.in_right = inputs
        (self.out,) = outputs
        self.sva = plan.spec.sva  # the resolved SVA (trusted: checked where the run started)
        self.radius = entry.lookahead
        self.passes = entry.passes
        self.skew = entry.skew
        self.flush_ii = entry.flush_ii
        self.slot_ii = entry.slot_ii
        self.first_row = entry.first_row
        self.latency = entry.latency
        self.ii = entry.ii
        self.stages = entry.stages
        self.offsets = stage_offsets(entry.stages)
        self.n = self.height * self.width
        self.frame_slots = self.passes * self.width + self.height * (self.width + self.radius)
        self.bits = plan.descriptor_bits
        self.parts = plan.part_bits
        # per frame in flight: the descriptors and pixels received, and the functional
        # streaming kernels over them
        self.data: dict[int, tuple] = {}
        self.word_mask = (1 << plan.word_bits) - 1
        self.received = 0
        self.slots = 0  # slots issued over the stream
        self.issued = 0  # words issued
        self.emitted = 0  # words pushed
        rows = self.frames * self.height
        # the descriptor rows' window (sim.cycle.buffers): the cycle each input row started to
        # enter, the cycle the last word of each box row was issued (its rows are read)
        self.rows_entered = np.full(rows + 1, -1, np.int64)
        self.rows_done = np.full(rows + 1, -1, np.int64)
        # the cycle each box row got ready (its last input row complete): inspection only
        self.ready_cycle = np.full(rows, -1, np.int64)
        self.rows_ready = 0
        # the pipeline: its tick; the issue ticks of words tick_base .. issued - 1 that a stage
        # or an exit still reads (oldest first)
        self.tick = 0
        self.ticks: deque[int] = deque()
        self.tick_base = 0
        self.last_slot = NEVER
        self.last_tick = NEVER
        self.pushed = False
        self.issued_now = False
        self.stalled = False
        self.last_word = 0
        self.stage_status = [0] * len(self.stages)
        self.stage_counts = [dict.fromkeys(ACTIVITIES, 0) for _ in self.stages]
        self.stage_peak = [0] * len(self.stages)
        self._pair = None
        self._word = None
        self._slot = None
        self._advance = False
        self._cycle = 0

    def _frame(self, f: int) -> tuple:
        """(left descriptors, right descriptors, left pixels, stream) of frame f."""
        if f not in self.data:
            dtype = np.uint32 if self.bits <= 32 else np.uint64
            shape = (self.height, self.width)
            d_l, d_r, img = np.zeros(shape, dtype), np.zeros(shape, dtype), np.zeros(shape,
                                                                                   np.uint8)
            self.data[f] = (d_l, d_r, img, SvaStream(d_l, d_r, img, self.sva, self.parts))
        return self.data[f]

    def _rows_complete(self, f: int) -> int:
        """Input rows of frame f received whole."""
        return min(self.height, max(0, self.received - f * self.n) // self.width)

    def stage_words(self, s: int, tick: int) -> int:
        """Words in stage s at ``tick``: issued at t with offset < tick - t <= offset +
        latency."""
        ticks = self.ticks
        off, lat = self.offsets[s], self.stages[s].latency
        lo = bisect_left(ticks, tick - off - lat)
        hi = bisect_left(ticks, tick - off)
        return hi - lo

    def exit_tick(self, j: int) -> int | None:
        """The tick word j is in the output register (:func:`~sim.cycle.rules.
        sva_exit_item`), None while the word it leaves with is not issued."""
        f, i = divmod(j, self.n)
        item, extra = sva_exit_item(i, self.skew, self.n, self.flush_ii)
        g = f * self.n + item
        if g >= self.issued:
            return None
        return self.ticks[g - self.tick_base] + extra + self.latency

    def _next_slot(self) -> tuple[int, int] | None:
        """(earliest tick, word it issues or -1) of the next slot, None while the input row
        it adds is not complete or every slot has gone."""
        if self.slots >= self.frames * self.frame_slots:
            return None
        f, i = divmod(self.slots, self.frame_slots)
        row, word = sva_slot(i, self.width, self.height, self.radius, self.passes,
                             self.first_row)
        if row >= 0 and self._rows_complete(f) <= row:
            return None
        earliest = self.last_slot + self.slot_ii
        if i == 0 and f > 0:
            earliest = max(earliest, sva_frame_start(self.last_tick, self.slot_ii, self.skew,
                                                        self.flush_ii))
        if word >= 0:  # a word: an II after the previous word
            earliest = sva_issue_tick(earliest, self.last_tick, self.ii)
        return earliest, word

    def _word_row_ready(self) -> bool:
        """The next word's box row has its input rows (:func:`~sim.cycle.rules.
        sva_last_input_row`)."""
        f, j = divmod(self.issued, self.n)
        last = sva_last_input_row(j // self.width, self.radius, self.height)
        return self._rows_complete(f) > last

    def evaluate(self, now_cycle: int) -> None:
        n = self.frames * self.n
        w = self.width
        self._cycle = now_cycle
        self._word = None
        moved = False
        # the row buffers: a pair in while the arriving row fits
        wait_fifo = None
        y_in = self.received // w
        if self.received < n and self.issued // w >= sva_rows_done_before_input(
                y_in, self.radius, self.height):
            if self.in_left.can_pop() and self.in_right.can_pop():
                self._pair = (self.in_left.pop(), self.in_right.pop())
                if self.received % w == 0:
                    self.rows_entered[y_in] = now_cycle
                moved = True
            else:
                wait_fifo = self.in_left if not self.in_left.can_pop() else self.in_right
        # the output register: the oldest word, at its exit tick, leaves if there is room
        at_output = self.emitted < n and self.exit_tick(self.emitted) == self.tick
        stall = at_output and not self.out.can_push()
        if at_output and not stall:
            f, j = divmod(self.emitted, self.n)
            stream = self._frame(f)[3]
            stream.advance(self._rows_complete(f))
            y, x = divmod(j, w)
            self._word = int(stream.q[y, x])
            self.out.push(WordBeat(f, x, y, self._word))
            moved = True
        # the sequencer: the next slot goes when the pipeline advances, its row is complete
        # and the tick has reached its spacing
        self._advance = not stall
        nxt = self._next_slot()
        self._slot = nxt[1] if nxt is not None and self._advance and self.tick >= nxt[0] \
            else None
        pending = self.emitted < n and self._word_row_ready()
        self._stage_activity(stall, n)
        if moved or (self._slot is not None and self._slot >= 0):
            self.busy()
        elif stall:
            self.blocked(self.out)
        elif self.issued > self.emitted or pending:
            self.busy()  # words in the pipeline, or a ready row's slots (or II) going
        elif self.emitted < n:
            self.starved(wait_fifo if wait_fifo is not None else self.in_left)
        else:
            self.idle()

    def _stage_activity(self, stall: bool, n: int) -> None:
        """Each stage's activity this cycle and the most words it has held."""
        for s, st in enumerate(self.stages):
            words = self.stage_words(s, self.tick)
            if words:
                status = "blocked" if stall else "busy"
            elif self.issued == n and self.tick - self.last_tick > self.offsets[s] + st.latency:
                status = "idle"
            else:
                status = "starved"
            self.stage_counts[s][status] += 1
            self.stage_status[s] = STATUS_CODES[status]
            self.stage_peak[s] = max(self.stage_peak[s], words)

    def commit(self) -> None:
        w = self.width
        if self._word is not None:
            self.last_word = self._word
            self.emitted += 1
            if self.emitted % self.n == 0:
                self.data.pop(self.emitted // self.n - 1, None)  # the frame has left
        self.pushed = self._word is not None
        self._word = None
        self.issued_now = self._slot is not None and self._slot >= 0
        if self._slot is not None:
            self.slots += 1
            self.last_slot = self.tick
            if self._slot >= 0:
                self.ticks.append(self.tick)
                self.last_tick = self.tick
                self.issued += 1
                if self.issued % w == 0:
                    self.rows_done[self.issued // w - 1] = self._cycle
            self._slot = None
        self.stalled = not self._advance
        if self._advance:
            self.tick += 1
        # forget issue ticks no stage and no exit reads any more
        while (self.ticks and self.tick_base < self.emitted
               and self.ticks[0] + self.latency < self.tick):
            self.ticks.popleft()
            self.tick_base += 1
        if self._pair is not None:
            left, right = self._pair
            d_l, _, img, _ = self._frame(left.frame)
            d_l[left.y, left.x] = left.descriptor
            img[left.y, left.x] = left.pixel
            self._frame(right.frame)[1][right.y, right.x] = right.descriptor
            self.received += 1
            self._pair = None
            if self.received % w == 0:
                h = self.height
                while self.rows_ready < self.frames * h:
                    f, y = divmod(self.rows_ready, h)
                    if self._rows_complete(f) <= sva_last_input_row(y, self.radius, h):
                        break
                    self.ready_cycle[self.rows_ready] = self._cycle + 1
                    self.rows_ready += 1

    def stage_stats(self) -> dict:
        """Per stage (in stream order): busy / starved / blocked / idle cycles and the most
        words it held."""
        return {st.name: {**self.stage_counts[s], "peak_words": self.stage_peak[s]}
                for s, st in enumerate(self.stages)}

    def stage_peaks(self) -> dict[str, int]:
        return {st.name: self.stage_peak[s] for s, st in enumerate(self.stages)}

    def row_window(self) -> tuple[np.ndarray, np.ndarray]:
        """The descriptor rows' window (:mod:`sim.cycle.buffers`), rows over the stream: the
        cycle each input row started to enter, the cycle each box row's last word was
        issued."""
        return self.rows_entered, self.rows_done

    def signal_values(self):
        w = self.width
        out = {
            "status": self.status_code,
            "input.row": frame_row(self.received // w, self.height, self.frames)[1],
            "input.col": self.received % w,
            "input.rows_ready": rows_ready_in_frame(self.received // w, self.height,
                                                    self.radius, self.frames),
            "output.row": frame_row(self.emitted // w, self.height, self.frames)[1],
            "output.col": self.emitted % w,
            "output.valid": int(self.pushed),
            "output.disparity": self.last_word & self.word_mask,
            "lr_check.reject": int(self.pushed and self.last_word < 0),
            "pipeline.issue": int(self.issued_now),
            "pipeline.stall": int(self.stalled),
            "pipeline.words": self.issued - self.emitted,
        }
        for s, st in enumerate(self.stages):
            out[f"stage.{st.name}.status"] = self.stage_status[s]
            out[f"stage.{st.name}.words"] = self.stage_words(s, self.tick)
        return out
