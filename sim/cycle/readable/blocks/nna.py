"""The NNA submodule and the merge of split frames as clocked blocks of the readable kernel.

One submodule turns one camera's pixel stream (of its tile) into its descriptor stream. It has
two halves that work in the same cycle, each an object of its own inside the block (a
:class:`LineBuffer` feeding a :class:`MacArray`, the stage a chain of layers repeats):

- **Line buffer** (input): pops at most one pixel per cycle into a buffer of ``rows`` image
  rows, while the row arriving fits beside the rows the next output row still reads
  (:func:`~sim.cycle.rules.nna_rows_started_before_input`). With rows = 9 (the 9x9 window) a new
  row waits until the window has moved on; with 10 it arrives while the window computes.
- **MAC array** (output): output row y may start once input row
  :func:`~sim.cycle.rules.nna_last_input_row` (min(y + h, H - 1), the replicate border) is
  complete. Each descriptor occupies the array for ``cycles`` = ceil(K*K*C / macs) cycles
  (census: 1) and is pushed in its last cycle; if ``out`` is full the finished descriptor is
  held (blocked) and the next one starts the cycle after the push. Without stalls the
  initiation interval is ``cycles``.

Latency of the first descriptor, with the input arriving one pixel per cycle from cycle a (first
pop) and nothing else stalling: row min(h, H - 1) is complete after its last pixel is popped in
cycle a + min(h + 1, H) W - 1, the row may start in the next cycle, and the descriptor is pushed
``cycles - 1`` cycles later.

Beats (:mod:`sim.cycle.readable.beats`): in :class:`~sim.cycle.readable.beats.PixelBeat`, out
:class:`~sim.cycle.readable.beats.DescriptorBeat`. Data: the descriptors of a row are computed,
when its first descriptor is pushed, from the pixels this line buffer actually received (the
functional kernel applied to the received rows max(0, y - h) .. min(H - 1, y + h)), so any
mistake in what reached the buffer shows in the bit-exactness tests.

Traced signals (:mod:`sim.cycle.plan`): ``status``; ``line_buffer.row_in`` (the image row being
received), ``line_buffer.fill`` (rows held for the next output row), ``mac.phase`` (MAC cycles
spent on the current descriptor; ``cycles`` while a finished one waits), ``mac.row`` /
``mac.col`` (the next descriptor), ``out.valid`` (pushed in its last cycle) and
``out.descriptor`` (the last pushed).

Compiled twins: ``sim/cycle/compiled/nna.py`` (the submodule) and
``sim/cycle/compiled/merge.py`` (the merge).
"""

from __future__ import annotations

import numpy as np

from stereosim.nna.descriptor import compute_descriptor
from stereosim.sim.config import NnaConfig
from stereosim.sim.cycle.plan import BlockPlan, ChipPlan
from stereosim.sim.cycle.readable.beats import DescriptorBeat
from stereosim.sim.cycle.readable.blocks.base import ChipBlock
from stereosim.sim.cycle.readable.fifo import Fifo
from stereosim.sim.cycle.rules import frame_row, nna_last_input_row, nna_rows_started_before_input


class LineBuffer:
    """The submodule's input half: the pixels of its tile's input region of each frame, in
    raster order, frame after frame (input row r of the tile, over the stream, is row
    r % in_rows of frame r // in_rows).

    State (committed): ``received`` pixels so far, ``pixels`` (per frame in flight, what
    arrived, at its image position), ``row_cycles`` (frame 0: the cycle each input row was
    complete), ``rows_entered`` (the cycle each input row started to enter, over the stream: the
    row window of :mod:`sim.cycle.buffers`)."""

    def __init__(self, entry: BlockPlan, image_shape: tuple[int, int], frames: int):
        self.tile = entry.tile
        self.rows, self.half = entry.rows, entry.half
        self.image_shape = image_shape
        self.in_rows, self.in_width = entry.tile.in_shape
        self.out_rows = entry.tile.shape[0]
        self.total = frames * self.in_rows * self.in_width
        self.pixels: dict[int, np.ndarray] = {}
        self.received = 0
        self.row_cycles = np.full(self.in_rows, -1, np.int64)
        self.rows_entered = np.full(frames * self.in_rows + 1, -1, np.int64)
        self._beat = None
        self._cycle = 0

    def rows_complete(self, f: int) -> int:
        """Input rows of frame f received whole."""
        n_in = self.in_rows * self.in_width
        return min(self.in_rows, max(0, self.received - f * n_in) // self.in_width)

    def evaluate(self, inp: Fifo, out_rows_done: int, now_cycle: int) -> bool:
        """Pop the next pixel if one is visible and its row fits beside the rows the output row
        after the ``out_rows_done`` finished ones reads; True if it did."""
        self._cycle = now_cycle
        if self.received >= self.total or not inp.can_pop():
            return False
        need = nna_rows_started_before_input(self.received // self.in_width, self.rows,
                                             self.half, self.tile.top_halo, self.out_rows,
                                             self.in_rows)
        if out_rows_done < need:
            return False
        self._beat = inp.pop()
        if self.received % self.in_width == 0:
            self.rows_entered[self.received // self.in_width] = now_cycle
        return True

    def commit(self) -> None:
        beat = self._beat
        if beat is None:
            return
        image = self.pixels.get(beat.frame)
        if image is None:
            image = self.pixels[beat.frame] = np.zeros(self.image_shape, np.uint8)
        image[beat.y, beat.x] = beat.pixel
        self.received += 1
        if self.received <= self.in_rows * self.in_width and self.received % self.in_width == 0:
            self.row_cycles[self.received // self.in_width - 1] = self._cycle
        self._beat = None

    def window(self, f: int, y: int) -> tuple[int, np.ndarray]:
        """The received rows image row y of frame f reads, max(0, y - h) .. min(H - 1, y + h)
        within the tile's input region, over its input columns; with the first row's index."""
        t = self.tile
        lo = max(t.in_y0, y - self.half)
        hi = min(t.in_y1, y + self.half + 1)
        return lo, self.pixels[f][lo:hi, t.in_x0:t.in_x1]

    def release(self, f: int) -> None:
        """Frame f's last descriptor has left: its pixels are no longer read."""
        self.pixels.pop(f, None)


class MacArray:
    """The submodule's output half: the descriptors of its tile's output region, in raster
    order, frame after frame, each ``cycles`` MAC cycles from the line buffer's rows.

    State (committed): ``emitted`` descriptors so far, ``phase`` (MAC cycles spent on the
    current descriptor; ``cycles`` while a finished one waits for room), ``pushed`` (in the
    last cycle), ``last_descriptor``, ``rows_done`` (the cycle each output row's last
    descriptor was pushed, over the stream)."""

    def __init__(self, entry: BlockPlan, frames: int, cfg: NnaConfig, image_rows: int):
        self.tile = entry.tile
        self.half, self.cycles = entry.half, entry.cycles
        self.cfg = cfg
        self.image_rows = image_rows
        self.height, self.width = entry.tile.shape
        self.total = frames * self.height * self.width
        self.emitted = 0
        self.phase = 0
        self.pushed = False
        self.last_descriptor = 0
        self.rows_done = np.full(frames * self.height + 1, -1, np.int64)
        self._desc_row: np.ndarray | None = None
        self._desc_key = (-1, -1)
        self._push = None
        self._phase_next = 0
        self._cycle = 0

    @property
    def rows_out(self) -> int:
        """Output rows whose every descriptor has been pushed (over the stream)."""
        return self.emitted // self.width

    def _row_ready(self, buffer: LineBuffer, f: int, y: int) -> bool:
        """Image row y of frame f may start: the last input row it reads is in."""
        last_in = self.tile.in_y0 + buffer.rows_complete(f) - 1
        return last_in >= nna_last_input_row(y, self.half, self.image_rows)

    def _descriptors_of_row(self, buffer: LineBuffer, f: int, y: int) -> np.ndarray:
        """Descriptors of image row y of frame f over the tile's columns, from the received
        pixels (computed once per row)."""
        if self._desc_key != (f, y):
            t = self.tile
            lo, window = buffer.window(f, y)
            row = compute_descriptor(np.ascontiguousarray(window), self.cfg)[y - lo]
            self._desc_row = row[t.x0 - t.in_x0:t.x1 - t.in_x0].copy()
            self._desc_key = (f, y)
        return self._desc_row

    def evaluate(self, buffer: LineBuffer, out: Fifo, now_cycle: int) -> str | None:
        """One MAC cycle: ``"busy"`` if the array worked on a descriptor or pushed one,
        ``"blocked"`` if a finished descriptor waits for room in ``out`` with nothing else to
        do, None if it waits for rows (or the stream is through)."""
        self._cycle = now_cycle
        self._phase_next = self.phase
        self._push = None
        if self.emitted >= self.total:
            return None
        f, j = divmod(self.emitted, self.height * self.width)
        y, x = divmod(j, self.width)
        y += self.tile.y0
        if self.phase == 0 and not self._row_ready(buffer, f, y):
            return None
        cpd = self.cycles
        if self.phase + 1 < cpd:
            self._phase_next = self.phase + 1
            return "busy"
        worked = self.phase < cpd
        if not out.can_push():
            self._phase_next = cpd
            return "busy" if worked else "blocked"
        desc = int(self._descriptors_of_row(buffer, f, y)[x])
        x += self.tile.x0
        out.push(DescriptorBeat(f, x, y, desc, int(buffer.pixels[f][y, x])))
        self._push = desc
        self._phase_next = 0
        return "busy"

    def commit(self, buffer: LineBuffer) -> None:
        self.pushed = self._push is not None
        if self._push is not None:
            self.emitted += 1
            if self.emitted % self.width == 0:
                self.rows_done[self.emitted // self.width - 1] = self._cycle
            n = self.height * self.width
            if self.emitted % n == 0:
                buffer.release(self.emitted // n - 1)  # the frame has left
            self.last_descriptor = self._push
            self._push = None
        self.phase = self._phase_next


class NnaSubmodule(ChipBlock):
    """One NNA submodule serving the tile of its plan entry (the whole frame, or a column tile /
    row band of it) over the plan's stream of frames: its line buffer receives the tile's input
    region of each frame in raster order, frame after frame, and its MAC array emits the
    tile's output region in raster order; rows and columns are those of the tile, the image
    borders (replicate) stay those of each frame.

    Ports: ``inputs`` = [the source's FIFO], ``outputs`` = [the FIFO to the SVA or the merge].
    Activity: busy when the line buffer popped a pixel or the MAC array worked or pushed;
    blocked when only a finished descriptor waiting for room remains; starved while the stream
    is not through; idle after."""

    def __init__(self, plan: ChipPlan, entry: BlockPlan, inputs: list[Fifo],
                 outputs: list[Fifo]):
        super().__init__(plan, entry, inputs, outputs)
        (self.inp,), (self.out,) = inputs, outputs
        self.line_buffer = LineBuffer(entry, plan.shape, self.frames)
        self.mac = MacArray(entry, self.frames, plan.cfg.nna, plan.shape[0])

    def evaluate(self, now_cycle: int) -> None:
        buffer, mac = self.line_buffer, self.mac
        popped = buffer.evaluate(self.inp, mac.rows_out, now_cycle)
        state = mac.evaluate(buffer, self.out, now_cycle)
        if popped or state == "busy":
            self.busy()
        elif state == "blocked":
            self.blocked(self.out)
        elif mac.emitted < mac.total or buffer.received < buffer.total:
            self.starved(self.inp)
        else:
            self.idle()

    def commit(self) -> None:
        self.line_buffer.commit()
        self.mac.commit(self.line_buffer)

    def row_window(self) -> tuple[np.ndarray, np.ndarray]:
        """The line buffer's row window (:mod:`sim.cycle.buffers`), rows over the stream: the
        cycle each input row started to enter, the cycle each output row was done."""
        return self.line_buffer.rows_entered, self.mac.rows_done

    def signal_values(self):
        buffer, mac, t = self.line_buffer, self.mac, self.line_buffer.tile
        # the row being received and the next output row, within their frames (one past the
        # last row once the stream is through)
        f_in, r_in = frame_row(buffer.received // buffer.in_width, buffer.in_rows, self.frames)
        f_out, r_out = frame_row(mac.rows_out, mac.height, self.frames)
        y_out = t.y0 + r_out
        oldest = f_out * buffer.in_rows + max(0, y_out - buffer.half - t.in_y0)
        return {
            "status": self.status_code,
            "line_buffer.row_in": t.in_y0 + r_in,
            "line_buffer.fill": max(0, f_in * buffer.in_rows + r_in - oldest),
            "mac.phase": mac.phase,
            "mac.row": y_out,
            "mac.col": t.x0 + mac.emitted % mac.width,
            "out.valid": int(mac.pushed),
            "out.descriptor": mac.last_descriptor,
        }


class Merge(ChipBlock):
    """Reassembles a camera's descriptor stream from its submodules' tiles, in raster order.

    Ports: ``inputs`` (one FIFO per submodule, each with its producer's tile), ``outputs`` =
    [``out``]. Each cycle it moves the next descriptor in raster order (from the tile that owns
    it) to ``out``: pop and push in the same cycle, so one beat per cycle at most; starved on
    that tile's FIFO, blocked on ``out``. With row bands it drains band after band, so a later
    band's output waits in its FIFO meanwhile. Traced: ``status``, ``count`` (descriptors
    moved), ``out.valid``.
    """

    def __init__(self, plan: ChipPlan, entry: BlockPlan, inputs: list[Fifo],
                 outputs: list[Fifo]):
        super().__init__(plan, entry, inputs, outputs)
        self.height, self.width = plan.shape
        self.inputs = inputs
        self.tiles = [plan.block(plan.fifo(fifo.name).producer).tile for fifo in inputs]
        (self.out,) = outputs
        self.moved = 0
        self.pushed = False
        self._push = False

    def _owner(self, x: int, y: int) -> int:
        return next(i for i, t in enumerate(self.tiles) if t.owns(x, y))

    def evaluate(self, now_cycle: int) -> None:
        self._push = False
        n = self.height * self.width
        if self.moved >= self.frames * n:
            self.idle()
            return
        y, x = divmod(self.moved % n, self.width)
        src = self.inputs[self._owner(x, y)]
        if not src.can_pop():
            self.starved(src)
            return
        if not self.out.can_push():
            self.blocked(self.out)
            return
        self.out.push(src.pop())
        self._push = True
        self.busy()

    def commit(self) -> None:
        self.pushed = self._push
        if self._push:
            self.moved += 1
            self._push = False

    def signal_values(self):
        return {"status": self.status_code, "count": self.moved, "out.valid": int(self.pushed)}
