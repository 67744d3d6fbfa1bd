"""The SVA as a clocked block of the cycle model.

Ports: ``in_left``, ``in_right`` (descriptor beats ``(x, y, descriptor, pixel)`` in raster
order), ``out`` (output words ``(x, y, word)`` in raster order).

- **Input**: pops one left/right pair per cycle when both are visible (a joint pop) and the row
  being received, y_in, fits the row buffers: y_in <= y_out + r + m + 1, where y_out is the
  output row in progress, r the box radius, m the median radius. The SVA thus holds the rows its
  next output row needs plus one row arriving (the streaming buffers; their sizes are reported).
- **Output**: output row y becomes *ready* in the cycle after input row min(y + r + m, H - 1) is
  complete (the box filter needs r rows below, the median m more; the LR check's diagonal
  search and the SGM paths stay within rows already in). Output word j (raster) is pushed at
  the first cycle c with c >= ready(row of j) + pipeline_latency, c >= push(j - 1) +
  cycles_per_pixel, and space in ``out``. Without stalls the initiation interval is
  cycles_per_pixel and the first word leaves at ready(0) + pipeline_latency.
- **Data**: the functional model's streaming kernels (:class:`sva.pipeline.SvaStream`) run over
  the descriptors this block actually received, row by row as rows complete.

Activity: busy when a pair is popped or a word pushed, or while a ready row waits out the
pipeline latency or the initiation interval; blocked when a word is due and ``out`` is full;
starved when the next row is not ready and an input FIFO has nothing to give; idle when done.
"""

from __future__ import annotations

import numpy as np

from sim.config import SvaConfig
from sim.cycle.clock import Block, ClockDomain
from sva.pipeline import SvaStream


class SvaBlock(Block):
    def __init__(self, name: str, domain: ClockDomain, shape: tuple[int, int], in_left, in_right,
                 out, cfg: SvaConfig, bits: int, dtype):
        super().__init__(name, domain)
        self.height, self.width = shape
        self.in_left, self.in_right, self.out = in_left, in_right, out
        self.cfg = cfg
        self.lookahead = cfg.box_size // 2 + (cfg.median // 2 if cfg.median > 1 else 0)
        self.desc_l = np.zeros(shape, dtype)
        self.desc_r = np.zeros(shape, dtype)
        self.img_l = np.zeros(shape, np.uint8)
        self.stream = SvaStream(self.desc_l, self.desc_r, self.img_l, cfg, bits)
        self.received = 0
        self.emitted = 0
        self.ready_cycle = np.full(self.height, -1, np.int64)  # cycle each output row got ready
        self.last_push = -(1 << 40)
        self._pair = None
        self._pushed_at: int | None = None
        self._cycle = 0

    def _rows_complete(self) -> int:
        return self.received // self.width

    def _earliest(self, j: int) -> int | None:
        y = j // self.width
        ready = int(self.ready_cycle[y])
        if ready < 0:
            return None
        return max(ready + self.cfg.pipeline_latency, self.last_push + self.cfg.cycles_per_pixel)

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        self._cycle = now_cycle
        moved = False
        y_out = self.emitted // self.width
        y_in = self.received // self.width
        wait_fifo = None
        if self.received < n and y_in <= y_out + self.lookahead + 1:
            if self.in_left.can_pop() and self.in_right.can_pop():
                self._pair = (self.in_left.pop(), self.in_right.pop())
                moved = True
            else:
                wait_fifo = self.in_left if not self.in_left.can_pop() else self.in_right
        blocked = False
        pending = False
        if self.emitted < n:
            due = self._earliest(self.emitted)
            if due is not None:
                pending = True
                if now_cycle >= due:
                    if self.out.can_push():
                        self.stream.advance(self._rows_complete())
                        y, x = divmod(self.emitted, self.width)
                        self.out.push((x, y, int(self.stream.q[y, x])))
                        self._pushed_at = now_cycle
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
                for y_ready in range(self.height):
                    if self.ready_cycle[y_ready] < 0 and (
                        min(y_ready + self.lookahead, self.height - 1) <= rows - 1
                    ):
                        self.ready_cycle[y_ready] = self._cycle + 1
        if self._pushed_at is not None:
            self.last_push = self._pushed_at
            self.emitted += 1
            self._pushed_at = None

    def work_cycles(self) -> int:
        """Output-pipeline cycles: cycles_per_pixel for every word (the SVA's throughput)."""
        return self.emitted * self.cfg.cycles_per_pixel

    def signals(self):
        return [("rows_in", 16), ("words_out", 32)]

    def signal_values(self):
        return {"rows_in": self._rows_complete(), "words_out": self.emitted}
