"""The SVA as a clocked block of the readable kernel.

Ports: ``in_left``, ``in_right`` (descriptor beats ``(x, y, descriptor, pixel)`` in raster
order), ``out`` (output words ``(x, y, word)`` in raster order).

- **Input**: pops one left/right pair per cycle when both are visible (a joint pop) and the row
  being received fits the row buffers (:func:`~sim.cycle.rules.sva_rows_done_before_input`:
  y_in <= y_out + r + m + 1, r the box radius, m the median radius): the SVA holds the rows its
  next output row needs plus one row arriving (the streaming buffers; their sizes are in the
  plan).
- **Output**: output row y becomes *ready* in the cycle after input row
  :func:`~sim.cycle.rules.sva_last_input_row` (min(y + r + m, H - 1)) is complete (the box
  filter needs r rows below, the median m more; the LR check's diagonal search and the SGM
  paths stay within rows already in). Word j (raster) is pushed at the first cycle from
  :func:`~sim.cycle.rules.sva_word_due` (ready + the latency L, previous push + the II) with
  space in ``out``; L and II come from the SVA's stages (:mod:`sim.cycle.stages`). Without
  stalls the words leave every II cycles and the first at ready(0) + L.
- **Data**: the functional model's streaming kernels (:class:`sva.pipeline.SvaStream`) run over
  the descriptors this block actually received, row by row as rows complete.

Activity: busy when a pair is popped or a word pushed, or while a ready row waits out the
pipeline latency or the initiation interval; blocked when a word is due and ``out`` is full;
starved when the next row is not ready and an input FIFO has nothing to give; idle when done.
Traced: ``status``, ``input.row`` / ``input.col`` (the next pair), ``input.rows_ready``
(output rows ready), ``output.row`` / ``output.col`` (the next word), ``output.valid`` (pushed
in its last cycle), ``output.disparity`` (the last word pushed) and ``lr_check.reject`` (that
word is invalid).
"""

from __future__ import annotations

import numpy as np

from sim.config import SvaConfig
from sim.cycle.clock import Block, ClockDomain
from sim.cycle.plan import STATUS_CODES, BlockPlan
from sim.cycle.rules import sva_last_input_row, sva_rows_done_before_input, sva_word_due
from sva.pipeline import SvaStream

NEVER = -(1 << 40)  # "the previous push" before the first one


class SvaBlock(Block):
    def __init__(self, plan: BlockPlan, domain: ClockDomain, shape: tuple[int, int], in_left,
                 in_right, out, cfg: SvaConfig, bits: int, word_bits: int):
        super().__init__(plan.name, domain)
        self.height, self.width = shape
        self.in_left, self.in_right, self.out = in_left, in_right, out
        self.cfg = cfg
        self.lookahead = plan.lookahead
        self.latency = plan.latency
        self.ii = plan.cycles
        dtype = np.uint32 if bits <= 32 else np.uint64
        self.desc_l = np.zeros(shape, dtype)
        self.desc_r = np.zeros(shape, dtype)
        self.img_l = np.zeros(shape, np.uint8)
        self.stream = SvaStream(self.desc_l, self.desc_r, self.img_l, cfg, bits)
        self.word_mask = (1 << word_bits) - 1
        self.received = 0
        self.emitted = 0
        self.rows_ready = 0
        self.ready_cycle = np.full(self.height, -1, np.int64)  # cycle each output row got ready
        # the descriptor rows' window (sim.cycle.buffers): the cycle each input row started to
        # enter, the cycle each output row's last word was pushed
        self.rows_entered = np.full(self.height + 1, -1, np.int64)
        self.rows_done = np.full(self.height + 1, -1, np.int64)
        self.last_push = NEVER
        self.pushed = False
        self.last_word = 0
        self._pair = None
        self._word = None
        self._cycle = 0

    def _rows_complete(self) -> int:
        return self.received // self.width

    def _due(self, j: int) -> int | None:
        ready = int(self.ready_cycle[j // self.width])
        if ready < 0:
            return None
        return sva_word_due(ready, self.latency, self.last_push, self.ii)

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        self._cycle = now_cycle
        self._word = None
        moved = False
        y_out = self.emitted // self.width
        y_in = self.received // self.width
        wait_fifo = None
        if self.received < n and y_out >= sva_rows_done_before_input(y_in, self.lookahead):
            if self.in_left.can_pop() and self.in_right.can_pop():
                self._pair = (self.in_left.pop(), self.in_right.pop())
                if self.received % self.width == 0:
                    self.rows_entered[y_in] = now_cycle
                moved = True
            else:
                wait_fifo = self.in_left if not self.in_left.can_pop() else self.in_right
        blocked = False
        pending = False
        if self.emitted < n:
            due = self._due(self.emitted)
            if due is not None:
                pending = True
                if now_cycle >= due:
                    if self.out.can_push():
                        self.stream.advance(self._rows_complete())
                        y, x = divmod(self.emitted, self.width)
                        self._word = int(self.stream.q[y, x])
                        self.out.push((x, y, self._word))
                        moved = True
                    else:
                        blocked = True
        if moved:
            self.busy()
        elif blocked:
            self.blocked(self.out)
        elif pending:
            self.busy()  # a ready row in the pipeline: latency or initiation interval
        elif self.emitted < n:
            self.starved(wait_fifo if wait_fifo is not None else self.in_left)
        else:
            self.idle()

    def commit(self) -> None:
        if self._pair is not None:
            (x, y, dl, pixel), (xr, yr, dr, _) = self._pair
            self.desc_l[y, x] = dl
            self.desc_r[yr, xr] = dr
            self.img_l[y, x] = pixel
            self.received += 1
            self._pair = None
            if self.received % self.width == 0:
                rows = self.received // self.width
                # output rows whose last needed input row is rows - 1 are ready next cycle
                while (self.rows_ready < self.height and sva_last_input_row(
                        self.rows_ready, self.lookahead, self.height) <= rows - 1):
                    self.ready_cycle[self.rows_ready] = self._cycle + 1
                    self.rows_ready += 1
        self.pushed = self._word is not None
        if self._word is not None:
            self.last_push = self._cycle
            self.last_word = self._word
            self.emitted += 1
            if self.emitted % self.width == 0:
                self.rows_done[self.emitted // self.width - 1] = self._cycle
            self._word = None

    def signal_values(self):
        w = self.width
        return {
            "status": STATUS_CODES.get(self.status, 0),
            "input.row": self.received // w,
            "input.col": self.received % w,
            "input.rows_ready": self.rows_ready,
            "output.row": self.emitted // w,
            "output.col": self.emitted % w,
            "output.valid": int(self.pushed),
            "output.disparity": self.last_word & self.word_mask,
            "lr_check.reject": int(self.pushed and self.last_word < 0),
        }
