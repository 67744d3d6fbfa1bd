"""The row windows of the chip -- buffers whose fill changes as rows come and go -- tracked from
what an engine did, and checked against their capacity.

Two buffers hold a sliding window of image rows:

- an NNA submodule's **line buffer** (``nna.line_buffer``, ``nna.line_buffer_rows`` rows of its
  tile's input width; with a network of several layers one per layer,
  ``nna.layer<l>.line_buffer``, of the rows and input region of :class:`~sim.cycle.stages.
  LayerPlan`): when the layer's MAC array's next output row is y (rows of its output region),
  it still reads input rows from ``y + top_halo - half`` (the layer's); a row arriving is held
  with them;
- the SVA's **descriptor rows** (``sva.descriptor_rows``, k + 2 rows of each view, k the box
  size): with box row y next its slots still read rows from ``y - 1 - r`` (the row leaving the
  column sums; r the box radius); a row arriving is held with them.

Both engines record, per buffer, the cycle each input row started to enter (its first beat)
and the cycle each output row was done (its last beat pushed). From those alone
:func:`window_peaks` computes the most rows the window ever held -- at the instant a row starts
to enter, ``r - max(0, y + offset) + 1`` with y the output rows done before that cycle -- and
:func:`buffer_report` refuses a run in which any window held more rows than its capacity
(:class:`BufferOverflow`, naming the buffer). The room rules of :mod:`sim.cycle.rules` keep the
windows within capacity; this check does not call them, so a room rule that is wrong, or a
buffer sized below what the frame needs, stops the run instead of being absorbed (the words come
from the functional kernels and would not show it).

The SVA's pipeline stages hold words in flight in their registers (their delay lines,
:class:`~core.timing.StagePlan`: ``slots`` words). Both engines count the words each
stage holds (a stage's words are those issued at a tick t with offset < tick - t <= offset +
latency); :func:`buffer_report` reports the most each held beside its capacity and refuses a run
in which a stage held more (an issue rule that lets words in faster than the stages can hold
them).
"""

from __future__ import annotations

import numpy as np

from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sva.geometry import box_radius


class BufferOverflow(RuntimeError):
    """A row window held more rows than its capacity, or a pipeline stage more words: a room
    rule is broken (a model bug)."""


def tracked(plan: ChipPlan) -> list[tuple[str, str, int, int, int, int, int, int, int]]:
    """``(block, buffer, capacity rows, capacity bits, row slot of its input rows, row slot of
    its output rows in the engines' arrays, offset, input rows per frame, output rows per
    frame)`` of every row window, in plan order (NNA submodules side-major -- each layer's
    line buffer, then a hybrid's census rows -- then the SVA). The engines keep two row slots
    per layer and for the SVA (input rows 2 k, output rows 2 k + 1); the census rows' window
    reads layer 0's input rows and the last layer's output rows."""
    out = []
    slots = 0
    for b in plan.blocks_of("nna"):
        first = slots
        for lay in b.layers:  # one line buffer per layer (one layer: nna.line_buffer)
            buf = next(x for x in b.buffers if x.name == lay.buffer.name)
            t = lay.tile
            out.append((b.name, buf.name, buf.rows, buf.bits, slots, slots + 1,
                        t.top_halo - lay.half, t.in_shape[0], t.shape[0]))
            slots += 2
        census = next((x for x in b.buffers if x.name == "nna.census_rows"), None)
        if census is not None:  # the census of output row y reads from input row y - r_c
            t0, last = b.layers[0].tile, b.layers[-1].tile
            r_c = plan.cfg.nna.census.window[1] // 2
            out.append((b.name, census.name, census.rows, census.bits, first, slots - 1,
                        last.y0 - t0.in_y0 - r_c, t0.in_shape[0], last.shape[0]))
    sva = plan.block("sva")
    buf = next(x for x in sva.buffers if x.name == "sva.descriptor_rows")
    h = plan.shape[0]
    out.append(("sva", buf.name, buf.rows, buf.bits, slots, slots + 1,
                -box_radius(plan.cfg.sva) - 1, h, h))
    return out


def window_peaks(entered: np.ndarray, done: np.ndarray, offset: int, in_rows: int | None = None,
                 out_rows: int | None = None) -> tuple[int, int]:
    """(most rows held, the cycle it was reached) of a row window: ``entered[r]`` the cycle
    input row r started to enter, ``done[y]`` the cycle output row y was done (-1: not
    reached), rows counted over a stream of frames of ``in_rows`` input and ``out_rows`` output
    rows (default: one frame). With y output rows done, the next output row is row y % out_rows
    of frame y // out_rows, which still reads input rows from max(0, that row + offset) of its
    frame."""
    n_in = int(np.argmin(entered >= 0)) if (entered < 0).any() else len(entered)
    if n_in == 0:
        return 0, -1
    in_rows = in_rows or len(entered)
    out_rows = out_rows or len(done)
    rows = np.arange(n_in)
    t = entered[:n_in]
    out_done = done[done >= 0]
    y = np.searchsorted(out_done, t, side="left")  # output rows done before each instant
    frame, local = np.divmod(y, out_rows)
    oldest = np.minimum(frame * in_rows + np.maximum(0, local + offset), rows)
    held = rows - oldest + 1
    i = int(np.argmax(held))
    return int(held[i]), int(t[i])


def buffer_report(plan: ChipPlan, windows: list[tuple[int, int]],
                  stage_peaks: dict[str, int]) -> dict:
    """``{block: {buffer: {capacity_rows, peak_rows, capacity_bits, peak_bits}}}`` from the most
    rows each row window held and the cycle it did (``windows``, in :func:`tracked` order:
    :func:`window_peaks` of an engine's row instants), and for every SVA stage
    ``{"pipeline.<stage>": {capacity_words, peak_words, capacity_bits, peak_bits}}`` from the
    most words each held (``stage_peaks``); raises BufferOverflow if a window or a stage
    exceeded its capacity."""
    report: dict[str, dict] = {}
    for (block, name, cap_rows, cap_bits, *_), (peak, at) in zip(tracked(plan), windows,
                                                                  strict=True):
        if peak > cap_rows:
            raise BufferOverflow(
                f"buffer {block}.{name} held {peak} rows at {plan.block(block).domain} cycle "
                f"{at}, above its capacity of {cap_rows}: a room rule lets rows in that the "
                "buffer cannot hold (a bug in the model)"
            )
        report.setdefault(block, {})[name] = {
            "capacity_rows": cap_rows, "peak_rows": peak, "capacity_bits": cap_bits,
            "peak_bits": cap_bits * peak // cap_rows,
        }
    for st in plan.block("sva").stages:
        peak = stage_peaks[st.name]
        if peak > st.slots:
            raise BufferOverflow(
                f"buffer sva.pipeline.{st.name} held {peak} words, above the {st.slots} its "
                "registers hold: the issue rule lets words in faster than the stage can hold "
                "them (a bug in the model)"
            )
        report["sva"][f"pipeline.{st.name}"] = {
            "capacity_words": st.slots, "peak_words": peak,
            "capacity_bits": st.register_bits, "peak_bits": peak * st.slot_bits,
        }
    return report


def windows_of(plan: ChipPlan, occ: np.ndarray) -> list[tuple[int, int]]:
    """(peak, cycle) of every row window from whole arrays of row instants (the readable
    kernel's :meth:`~sim.cycle.readable.chip.Chip.window_rows`)."""
    return [window_peaks(occ[slot], occ[out_slot], offset, in_rows, out_rows)
            for _, _, _, _, slot, out_slot, offset, in_rows, out_rows in tracked(plan)]
