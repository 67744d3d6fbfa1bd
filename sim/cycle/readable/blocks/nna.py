"""The NNA submodule and the merge of split frames as clocked blocks of the readable kernel.

One submodule turns one camera's pixel stream (of its tile) into its descriptor stream through
a pipeline of layer stages, one per layer of the network (:class:`~nna.submodule.timing.LayerPlan`;
a single layer and the census unit: one stage). Each stage has two halves that work in the same
cycle, each an object of its own (a :class:`LineBuffer` feeding a :class:`MacArray`):

- **Line buffer** (input): ``rows`` rows of the layer's input region. Layer 0's pops at most one
  pixel per cycle from the source's FIFO; layer l >= 1's is written by layer l - 1's MAC array.
  Either takes the next item only while the row arriving fits beside the rows its layer's next
  output row still reads (:func:`~sim.cycle.rules.nna_rows_started_before_input` with the
  layer's rows, half kernel h_l, top halo and row counts). With rows = 9 for a 9x9 layer a new
  row waits until the window has moved on; with 10 it arrives while the window computes.
- **MAC array** (output): computes the layer's output region in raster order. Output row y may
  start once input row :func:`~sim.cycle.rules.nna_last_input_row` (min(y + h_l, H - 1), the
  replicate border) is complete. Each output occupies the array for ``ii`` = II_l =
  ceil(m_l / macs_l) cycles (census: 1) and leaves in its last cycle -- the last layer pushes
  the descriptor into ``out``, a layer before it writes its activations into the next layer's
  line buffer --; if there is no room (``out`` full, or the next line buffer's rule says
  wait) the finished output is held (the layer is blocked) and the next one starts the cycle
  after it leaves. Without stalls the initiation interval is II_l.

Rows flow between the layers without a frame store. Latency of the first descriptor, with the
input arriving one pixel per cycle from cycle a (first pop) and nothing stalling: layer 0's
input row r is complete in D_-1(r) = a + r W + in_x1 - 1 (W the frame's width, in_x1 the end
of the tile's input columns: a + (r + 1) W - 1 for a whole frame); layer l's output row y
starts in S_l(y) = max(D_l-1(min(y + h_l, H - 1)), D_l(y - 1)) + 1 and ends in D_l(y) =
S_l(y) + W_l II_l - 1 (W_l its output region's width); the first descriptor leaves in
S_L-1(0) + cpp_L-1 - 1 -- one layer: a + min(h + 1, H) W - 1 + cycles. The receptive field
decides: 9 input rows for one 9x9 layer and for four 3x3 layers alike.

Beats (:mod:`sim.cycle.readable.beats`): in :class:`~sim.cycle.readable.beats.PixelBeat`, out
:class:`~sim.cycle.readable.beats.DescriptorBeat`. Data: each layer's output row is computed,
when its first output leaves, from what its line buffer actually received (the rows
max(0, y - h_l) .. min(H - 1, y + h_l) of its input region; the CNN's arithmetic is
:func:`~quant.intconv.int_layer_rows`, the census's :func:`~nna.descriptor.compute_descriptor`),
so any mistake in what reached a buffer shows in the bit-exactness tests.

Traced signals (:mod:`sim.cycle.plan`): ``status``; ``line_buffer.row_in`` (the image row being
received), ``line_buffer.fill`` (rows held for the next output row), ``mac.phase`` (MAC cycles
spent on the current output; ``ii`` while a finished one waits), ``mac.row`` / ``mac.col``
(the next output) -- with several layers, per layer, prefixed ``layer<l>.``, with the layer's
own ``layer<l>.status`` --, ``out.valid`` (pushed in its last cycle) and ``out.descriptor`` (the
last pushed).

Compiled twins: ``sim/cycle/compiled/nna.py`` (the submodule) and
``sim/cycle/compiled/merge.py`` (the merge).
"""

from __future__ import annotations

import numpy as np

from stereosim.nna.descriptor import NnaSpec, census_of, compute_descriptor, hybrid_word
from stereosim.nna.submodule.timing import LayerPlan
from stereosim.quant.intconv import int_layer_rows
from stereosim.sim.cycle.fifo.readable import Fifo
from stereosim.sim.cycle.plan import STATUS_CODES, BlockPlan, ChipPlan
from stereosim.sim.cycle.readable.beats import DescriptorBeat
from stereosim.sim.cycle.readable.blocks.base import ChipBlock
from stereosim.sim.cycle.rules import frame_row, nna_last_input_row, nna_rows_started_before_input

ACTIVITIES = ("busy", "starved", "blocked", "idle")


class LineBuffer:
    """A layer's input half: the items of its input region of each frame, in raster order, frame
    after frame (input row r of the region, over the stream, is row r % in_rows of frame r //
    in_rows) -- layer 0's the tile's pixels, a later layer's the activations of the layer before.

    State (committed): ``received`` items so far, ``values`` (per frame in flight, what arrived,
    at its image position: layer 0 a uint8 (H, W) image, a later layer int32 (C_in, H, W)),
    ``row_cycles`` (frame 0: the cycle each input row was complete), ``rows_entered`` (the cycle
    each input row started to enter, over the stream: the row window of
    :mod:`sim.cycle.buffers`)."""

    def __init__(self, layer: LayerPlan, image_shape: tuple[int, int], frames: int):
        self.tile = layer.tile
        self.rows, self.half = layer.rows, layer.half
        self.channels = layer.channels_in if layer.index > 0 else 0
        self.image_shape = image_shape
        self.in_rows, self.in_width = layer.tile.in_shape
        self.out_rows = layer.tile.shape[0]
        self.total = frames * self.in_rows * self.in_width
        self.values: dict[int, np.ndarray] = {}
        self.received = 0
        self.row_cycles = np.full(self.in_rows, -1, np.int64)
        self.rows_entered = np.full(frames * self.in_rows + 1, -1, np.int64)
        self._item = None
        self._cycle = 0

    @property
    def pixels(self) -> dict[int, np.ndarray]:
        """Layer 0's received images, per frame."""
        return self.values

    def rows_complete(self, f: int) -> int:
        """Input rows of frame f received whole."""
        n_in = self.in_rows * self.in_width
        return min(self.in_rows, max(0, self.received - f * n_in) // self.in_width)

    def has_room(self, out_rows_done: int) -> bool:
        """May the next item enter: the stream is not through and its row fits beside the rows
        the output row after the ``out_rows_done`` finished ones reads?"""
        if self.received >= self.total:
            return False
        need = nna_rows_started_before_input(self.received // self.in_width, self.rows,
                                             self.half, self.tile.top_halo, self.out_rows,
                                             self.in_rows)
        return out_rows_done >= need

    def evaluate(self, inp: Fifo, out_rows_done: int, now_cycle: int) -> bool:
        """Layer 0: pop the next pixel if one is visible and there is room; True if it did."""
        self._cycle = now_cycle
        if not inp.can_pop() or not self.has_room(out_rows_done):
            return False
        beat = inp.pop()
        self.write(beat.frame, beat.x, beat.y, beat.pixel, now_cycle)
        return True

    def write(self, f: int, x: int, y: int, value, now_cycle: int) -> None:
        """Stage the next item (applied at commit): the caller checked :meth:`has_room`."""
        self._cycle = now_cycle
        self._item = (f, x, y, value)
        if self.received % self.in_width == 0:
            self.rows_entered[self.received // self.in_width] = now_cycle

    def commit(self) -> None:
        if self._item is None:
            return
        f, x, y, value = self._item
        image = self.values.get(f)
        if image is None:
            shape = (self.channels, *self.image_shape) if self.channels else self.image_shape
            image = self.values[f] = np.zeros(shape, np.int32 if self.channels else np.uint8)
        if self.channels:
            image[:, y, x] = value
        else:
            image[y, x] = value
        self.received += 1
        if self.received <= self.in_rows * self.in_width and self.received % self.in_width == 0:
            self.row_cycles[self.received // self.in_width - 1] = self._cycle
        self._item = None

    def window(self, f: int, y: int) -> tuple[int, np.ndarray]:
        """The received rows image row y of frame f reads, max(0, y - h) .. min(H - 1, y + h)
        within the region's input rows, over its input columns; with the first row's index."""
        t = self.tile
        lo = max(t.in_y0, y - self.half)
        hi = min(t.in_y1, y + self.half + 1)
        return lo, self.values[f][..., lo:hi, t.in_x0:t.in_x1]

    def release(self, f: int) -> None:
        """Frame f's last descriptor has left: its items are no longer read."""
        self.values.pop(f, None)


class MacArray:
    """A layer's output half: the outputs of its output region, in raster order, frame after
    frame, each ``ii`` MAC cycles from the line buffer's rows.

    State (committed): ``emitted`` outputs so far, ``phase`` (MAC cycles spent on the current
    output; ``ii`` while a finished one waits for room), ``pushed`` (in the last cycle),
    ``last_value`` (the last output), ``rows_done`` (the cycle each output row's last output
    left, over the stream), ``first_cycle`` / ``last_cycle`` (of the first and last output),
    ``activity`` (cycles busy, starved, blocked, idle)."""

    def __init__(self, layer: LayerPlan, frames: int, spec: NnaSpec, image_rows: int,
                 last: bool, census_source: LineBuffer | None = None, bits: int = 0):
        self.tile = layer.tile
        self.index, self.last = layer.index, last
        self.half, self.ii = layer.half, layer.ii
        self.spec = spec
        self.cnn = spec.cnn  # None for the census
        # the hybrid's last layer: layer 0's line buffer, whose rows its census unit reads,
        # and the descriptor's bits
        self.census_source = census_source
        self.bits = bits
        self.image_rows = image_rows
        self.height, self.width = layer.tile.shape
        self.total = frames * self.height * self.width
        self.emitted = 0
        self.phase = 0
        self.pushed = False
        self.last_value = 0
        self.rows_done = np.full(frames * self.height + 1, -1, np.int64)
        self.first_cycle = self.last_cycle = -1
        self.activity = dict.fromkeys(ACTIVITIES, 0)
        self.status = "idle"
        self._row: np.ndarray | None = None
        self._row_key = (-1, -1)
        self._out = None
        self._phase_next = 0
        self._cycle = 0

    @property
    def rows_out(self) -> int:
        """Output rows whose every output has left (over the stream)."""
        return self.emitted // self.width

    def position(self) -> tuple[int, int, int]:
        """(frame, image row, image column) of the next output."""
        f, j = divmod(self.emitted, self.height * self.width)
        y, x = divmod(j, self.width)
        return f, self.tile.y0 + y, self.tile.x0 + x

    def _row_ready(self, buffer: LineBuffer, f: int, y: int) -> bool:
        """Image row y of frame f may start: the last input row it reads is in."""
        last_in = self.tile.in_y0 + buffer.rows_complete(f) - 1
        return last_in >= nna_last_input_row(y, self.half, self.image_rows)

    def _outputs_of_row(self, buffer: LineBuffer, f: int, y: int) -> np.ndarray:
        """Outputs of image row y of frame f over the region's columns, from the received items
        (computed once per row): descriptors (W_l,) for the last layer, activations (C, W_l)
        before it. The hybrid's last layer adds the census of the row, from the input rows
        layer 0's line buffer received (:meth:`_census_of_row`)."""
        if self._row_key != (f, y):
            t = self.tile
            lo, window = buffer.window(f, y)
            if self.cnn is None:
                row = compute_descriptor(np.ascontiguousarray(window), self.spec)[y - lo]
            else:
                row = int_layer_rows(self.cnn, self.index, window, lo, y, y + 1)[..., 0, :]
            row = row[..., t.x0 - t.in_x0:t.x1 - t.in_x0]
            if self.census_source is not None:
                row = hybrid_word(row, self._census_of_row(f, y), self.cnn.channels,
                                  self.bits)
            self._row = row.copy()
            self._row_key = (f, y)
        return self._row

    def _census_of_row(self, f: int, y: int) -> np.ndarray:
        """The census signatures of image row y of frame f over this region's columns, from
        the input rows y - r_c .. y + r_c (clipped to the tile's input rows: the image's
        borders replicate) that layer 0's line buffer received -- the census unit's rows
        (both engines track them against their capacity, :mod:`sim.cycle.buffers`)."""
        src, t = self.census_source, self.tile
        t0 = src.tile
        r_c = self.spec.cfg.census.window[1] // 2
        lo = max(t0.in_y0, y - r_c)
        hi = min(t0.in_y1, y + r_c + 1)
        rows = np.ascontiguousarray(src.values[f][lo:hi, t0.in_x0:t0.in_x1])
        return census_of(rows, self.spec.cfg)[y - lo, t.x0 - t0.in_x0:t.x1 - t0.in_x0]

    def evaluate(self, buffer: LineBuffer, room: bool, now_cycle: int):
        """One MAC cycle; ``room``: the finished output may leave now. Returns (status, output)
        -- status ``"busy"`` if the array worked on an output or one left, ``"blocked"`` if a
        finished one waits for room with nothing else to do, ``"starved"`` if it waits for rows,
        ``"idle"`` once the stream is through; output (frame, x, y, value) if one leaves."""
        self._cycle = now_cycle
        self._phase_next = self.phase
        self._out = None
        if self.emitted >= self.total:
            return self._report("idle"), None
        f, y, x = self.position()
        if self.phase == 0 and not self._row_ready(buffer, f, y):
            return self._report("starved"), None
        ii = self.ii
        if self.phase + 1 < ii:
            self._phase_next = self.phase + 1
            return self._report("busy"), None
        worked = self.phase < ii
        if not room:
            self._phase_next = ii
            return self._report("busy" if worked else "blocked"), None
        value = self._outputs_of_row(buffer, f, y)[..., x - self.tile.x0]
        self._out = (f, x, y, value if value.ndim else int(value))
        self._phase_next = 0
        return self._report("busy"), self._out

    def _report(self, status: str) -> str:
        self.status = status
        return status

    def commit(self) -> None:
        self.activity[self.status] += 1
        self.pushed = self._out is not None
        if self._out is not None:
            self.emitted += 1
            if self.first_cycle < 0:
                self.first_cycle = self._cycle
            self.last_cycle = self._cycle
            if self.emitted % self.width == 0:
                self.rows_done[self.emitted // self.width - 1] = self._cycle
            value = self._out[3]
            self.last_value = value if isinstance(value, int) else 0
            self._out = None
        self.phase = self._phase_next

    def frames_done(self) -> int:
        """Frames whose every output has left."""
        return self.emitted // (self.height * self.width)


class NnaSubmodule(ChipBlock):
    """One NNA submodule serving the tile of its plan entry (the whole frame, or a column tile /
    row band of it) over the plan's stream of frames: a pipeline of layer stages (the entry's
    ``layers``), layer 0's line buffer receiving the tile's input region of each frame in raster
    order, frame after frame, the last layer's MAC array emitting the tile's output region in
    raster order; rows and columns are those of each layer's regions, the image borders
    (replicate) stay those of each frame.

    Ports: ``inputs`` = [the source's FIFO], ``outputs`` = [the FIFO to the SVA or the merge].
    Activity: busy when layer 0's line buffer popped a pixel or a MAC array worked or an output
    left; blocked when only finished descriptors waiting for room in ``out`` remain; starved
    while the stream is not through; idle after. Each layer's own activity (busy, starved on its
    rows, blocked on room, idle) is in :meth:`layer_stats`."""

    def __init__(self, plan: ChipPlan, entry: BlockPlan, inputs: list[Fifo],
                 outputs: list[Fifo]):
        super().__init__(plan, entry, inputs, outputs)
        (self.inp,), (self.out,) = inputs, outputs
        n = len(entry.layers)
        self.buffers = [LineBuffer(lay, plan.shape, self.frames) for lay in entry.layers]
        hybrid = plan.hybrid
        self.macs = [MacArray(lay, self.frames, plan.spec.nna, plan.shape[0], lay.index == n - 1,
                              self.buffers[0] if hybrid and lay.index == n - 1 else None,
                              plan.descriptor_bits)
                     for lay in entry.layers]
        self.line_buffer, self.mac = self.buffers[0], self.macs[-1]
        self._popped = False

    def evaluate(self, now_cycle: int) -> None:
        buffers, macs = self.buffers, self.macs
        self._popped = buffers[0].evaluate(self.inp, macs[0].rows_out, now_cycle)
        states = []
        for i, mac in enumerate(macs):
            if mac.last:
                room = self.out.can_push()
            else:
                room = buffers[i + 1].has_room(macs[i + 1].rows_out)
            state, item = mac.evaluate(buffers[i], room, now_cycle)
            states.append(state)
            if item is None:
                continue
            f, x, y, value = item
            if mac.last:
                self.out.push(DescriptorBeat(f, x, y, value, int(buffers[0].values[f][y, x])))
            else:
                buffers[i + 1].write(f, x, y, value, now_cycle)
        if self._popped or "busy" in states:
            self.busy()
        elif states[-1] == "blocked":
            self.blocked(self.out)
        elif any(m.emitted < m.total for m in macs) or buffers[0].received < buffers[0].total:
            self.starved(self.inp)
        else:
            self.idle()

    def commit(self) -> None:
        for buffer in self.buffers:
            buffer.commit()
        done = self.mac.frames_done()
        for mac in self.macs:
            mac.commit()
        if self.mac.frames_done() > done:  # the frame has left: no layer reads it any more
            for buffer in self.buffers:
                buffer.release(done)

    def row_windows(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each layer's line buffer's row window (:mod:`sim.cycle.buffers`), rows over the
        stream: the cycle each input row started to enter, the cycle each output row of the
        layer was done."""
        return [(b.rows_entered, m.rows_done) for b, m in zip(self.buffers, self.macs)]

    def layer_stats(self) -> list[dict]:
        """Per layer: its cycles busy, starved, blocked and idle, and the cycles its first and
        last output left."""
        return [{**m.activity, "first_output_cycle": m.first_cycle,
                 "last_output_cycle": m.last_cycle} for m in self.macs]

    def _layer_signals(self, buffer: LineBuffer, mac: MacArray) -> dict:
        t = buffer.tile
        # the row being received and the next output row, within their frames (one past the
        # last row once the stream is through)
        f_in, r_in = frame_row(buffer.received // buffer.in_width, buffer.in_rows, self.frames)
        f_out, r_out = frame_row(mac.rows_out, mac.height, self.frames)
        y_out = mac.tile.y0 + r_out
        oldest = f_out * buffer.in_rows + max(0, y_out - buffer.half - t.in_y0)
        return {
            "line_buffer.row_in": t.in_y0 + r_in,
            "line_buffer.fill": max(0, f_in * buffer.in_rows + r_in - oldest),
            "mac.phase": mac.phase,
            "mac.row": y_out,
            "mac.col": mac.tile.x0 + mac.emitted % mac.width,
        }

    def signal_values(self):
        out = {"status": self.status_code}
        single = len(self.macs) == 1
        for i, (buffer, mac) in enumerate(zip(self.buffers, self.macs)):
            pre = "" if single else f"layer{i}."
            if not single:
                out[f"{pre}status"] = STATUS_CODES[mac.status] if mac.activity[mac.status] else 0
            out.update({pre + k: v for k, v in self._layer_signals(buffer, mac).items()})
        out["out.valid"] = int(self.mac.pushed)
        out["out.descriptor"] = self.mac.last_value
        return out


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
