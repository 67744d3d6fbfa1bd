"""The analytic model of the chip: throughput, latency, memory and traffic without simulating.

:func:`estimate` answers, for a configuration and a frame size, the questions an architect screens
with before running the cycle model: the frame rate each block sustains and the bottleneck, the
first-output and whole-frame latency of one frame, SRAM bits per buffer and per FIFO, bytes per
frame through each FIFO, MACs per frame, and the paper's own arithmetic (four 3x3 layers vs one
9x9 layer; float vs binary descriptors). It walks the chip plan (:mod:`sim.cycle.plan`: the same
blocks, FIFOs, windows and work) and applies the timing rules of :mod:`sim.cycle.rules` per image
row instead of per cycle:

- **Throughput.** A block's *work* per frame is the cycles its critical resource is busy --
  the figure the cycle report ranks (:meth:`ChipPlan.work_cycles`): descriptors x ``ceil(K*K*C /
  macs)`` per NNA submodule (census: 1 cycle), words x the SVA's II (:mod:`sim.cycle.stages`) for
  the SVA, one beat per pixel for a merge, ``max(N, ceil(N f / B))`` cycles for a memory source (N
  pixels, f its clock, B its bandwidth in bytes/s; through the DRAM channel, its read bursts'
  rounds) and ``H (W + hblank)`` pixel clocks for a camera. The block with the largest work time
  sets the frame rate. Exact (the same integers the simulator counts), except a bandwidth-limited
  memory source that is also back-pressured (its tokens pile up while blocked, so it works less than
  the formula says; it is then not the bottleneck).
- **Latency.** Times are carried per image row: the cycle each stage receives the first and the
  last beat of a row. A stage's output row y is ready the cycle after the input row it needs is
  complete (NNA: row min(y + h, H - 1), h the window's half height; SVA: box row y needs row
  min(y + r, H - 1), r the box radius); the NNA's first output leaves ``max(ready + latency,
  previous + II)`` and the rest of the row follows at the II. The SVA's sequencer (its rules
  in :mod:`sim.cycle.rules`) issues a frame's k - 1 passes, then box row y's first word at
  ``sva_first_word_tick`` / ``sva_row_issue_tick`` (r look-ahead slots) and its others at the
  II; word j leaves L after the word it leaves with (``sva_exit_item``: the median's skew of
  m W + m words, the last ones with flush ticks). FIFOs add their visibility delay,
  ``first_edge_after(push instant) + latency + (sync - 1 if crossing) - 1`` consumer cycles,
  computed on the same femtosecond grid as :class:`sim.cycle.rules.ClockDomain`. The line buffer's
  room rule and the SVA's look-ahead window (row y_in enters once the last word of box row
  y_in - r - 2 has entered the SVA's pipeline) are applied. Exact (to the cycle) when no FIFO
  fills; see docs/whatif.md for what is approximated when one does. The NNA -> SVA FIFO is exact
  either way: when it is within a beat of its round trip (:func:`fills`) its handshake is walked
  beat by beat (:class:`LinkWalk`, with the FIFO's own visibility and free-slot rules), as its mean
  rate puts a row's last pop up to a cycle off and the rows add up (exact when its producer's row
  times are: one submodule per camera).
- **Sources** (:class:`SourceTimes`, the rules of the cycle model's sources): a camera
  streaming into the NNA delivers at its pixel clock; a memory source at its token bucket, or
  through the DRAM channel once its read burst is in (the bursts take the read slots in turn,
  requested at once: a lower bound, the prefetch never waits) and a burst's pixels one a
  cycle; a memory source reading a camera's DRAM frame buffers not before the first NNA edge
  after the camera wrote the pixel, and a burst requested once the camera wrote its last
  pixel. Exact to the cycle behind frame buffers (tests/sim/cycle/test_estimate.py,
  test_estimate_presets.py).
- **Delivered rate, totals** (:func:`delivered_fps`): the frame rate the chip delivers (the
  work bound, a camera's rate, or fewer behind one frame buffer), the chip's SRAM with every
  instance counted once (:func:`~sim.cycle.figures.chip_sram`) and the energy a frame and the
  power at the delivered rate (:func:`~sim.cycle.energy.estimate_energy`: a run's items from
  the plan's counts; the clocks over a frame period at that rate).
- **FIFO rate.** A FIFO of depth d moves at most d items per round trip (push -> visible -> pop
  -> free seen by the producer): ``(latency + 1)`` cycles in one domain, about
  ``(latency + sync - 1.5) T_consumer + (sync - 0.5) T_producer`` across domains (half a period
  for the edge alignment on average). A link slower than its producer stretches the stream.
- **Merge FIFOs.** Column tiles reach the work bound only if their FIFOs to the merge hold
  what a tile computes while the merge serves the others: :func:`merge_depth_needed`
  (``throughput.merge_depth_needed``) is the least depth that does, to the entry.
- **Memory, traffic, work.** SRAM bits per buffer, per-action counts and the FIFOs (names,
  depths, widths, beats per frame) come from the plan -- the numbers the simulator reports.
"""

from __future__ import annotations

import dataclasses
import math

from stereosim.core.config import ChipConfig, config_to_dict
from stereosim.core.errors import InputError, UserError
from stereosim.nna.geometry import Tile
from stereosim.nna.submodule.timing import mac_done
from stereosim.sim.cycle.energy import EnergyTable, energy_table, estimate_energy
from stereosim.sim.cycle.fifo import rule as fifo_rule
from stereosim.sim.cycle.fifo.rule import room_from, room_seen_within, seen_from, visible_from
from stereosim.sim.cycle.figures import (
    action_counts,
    chip_sram,
    layer_report,
    nna_fps,
    sram_bits,
)
from stereosim.sim.cycle.lent import lent_report
from stereosim.sim.cycle.plan import ChipPlan, FifoPlan, build_plan
from stereosim.sim.cycle.rules import (
    burst_last,
    burst_of,
    camera_cycle,
    dram_read_ready_fs,
    dram_slot,
    edges_through,
    first_edge_at,
    memory_first_cycle,
    nna_last_input_row,
    nna_rows_started_before_input,
    sva_exit_item,
    sva_first_word_tick,
    sva_frame_start,
    sva_frame_ticks,
    sva_last_input_row,
    sva_pass_start,
    sva_rows_done_before_input,
    sva_slot,
)

FS_PER_S = 10**15

# The paper's four-layer MC-CNN-fast descriptor net: 3x3 kernels, 1 -> 32 -> 32 -> 32 -> 32.
FOUR_LAYERS = ((3, 1, 32), (3, 32, 32), (3, 32, 32), (3, 32, 32))
SINGLE_LAYER = ((9, 1, 32),)


def visible(f: FifoPlan, cycle: float, plan: ChipPlan) -> float:
    """The consumer cycle from which an item pushed in producer ``cycle`` can be popped
    (:func:`~sim.cycle.fifo.rule.visible_from`; a fractional cycle kept in one domain)."""
    p_dst = plan.domains[f.dst].period_fs
    p_src, cycle = (plan.domains[f.src].period_fs, round(cycle)) if f.crossing else (p_dst, cycle)
    return visible_from(cycle, p_src, p_dst, p_src / p_dst, f.data_edges)


def round_trip_fs(f: FifoPlan, plan: ChipPlan) -> float:
    """Push -> visible -> pop -> free seen by the producer -> next push (module docstring)."""
    p_src, p_dst = plan.domains[f.src].period_fs, plan.domains[f.dst].period_fs
    return fifo_rule.round_trip_fs(f.data_edges, f.space_edges, p_src, p_dst, f.crossing)


def fills(f: FifoPlan, plan: ChipPlan) -> bool:
    """Can ``f`` limit its stream: are its ``depth`` slots no more than a round trip and one
    beat (``round_trip_fs`` in consumer cycles, plus one)? Then the row model's mean rate is
    off by up to a cycle a row, and the estimate walks its handshake beat by beat."""
    return f.depth <= round_trip_fs(f, plan) / plan.domains[f.dst].period_fs + 1


class LinkWalk:
    """A FIFO's handshake beat by beat, with the FIFO's own rules (:mod:`sim.cycle.fifo.rule`):
    the producer pushes beat k once it is made (its row's unobstructed times, and ``step`` cycles
    after its previous push: a blocked producer resumes from its push) and it sees the slot of
    beat k - depth freed (:func:`room_from` of that pop, ``space_edges``); the consumer pops
    it once visible (:func:`visible_from`, ``data_edges``), a cycle after its previous pop and
    not before its row is let in.

    Shortcut (exact): a slot freed by a pop is seen at most ``K = floor(data_edges P_dst /
    P_src) + space_edges`` producer cycles after the push. If ``depth x step >= K`` and ``step
    P_src >= P_dst``, once ``depth`` beats in a row were pushed at their own pace (not waiting
    for a slot) and popped as soon as visible, every later beat of the row is too: the rest of
    the row follows at ``step`` without walking it. Only a link slower than its producer
    (``depth x step < K``) is walked over the whole frame (O(H W): about 1.9 s for a 720p
    census frame behind a 2-deep FIFO). Exact when the producer's row times are; a merge of
    column tiles makes its rows unevenly (half at the tiles' II, half drained at once), which
    the even spacing assumed here does not see."""

    def __init__(self, f: FifoPlan, plan: ChipPlan, step: int):
        self.depth = f.depth
        self.p_src = plan.domains[f.src].period_fs
        self.p_dst = plan.domains[f.dst].period_fs
        self.data_edges, self.space_edges = f.data_edges, f.space_edges
        self.step = step
        k = room_seen_within(self.data_edges, self.space_edges, self.p_src, self.p_dst)
        self.shortcut = f.depth * step >= k and step * self.p_src >= self.p_dst
        self.pops: list[int] = []
        self.push = -(1 << 40)

    def row(self, first: float, last: float, w: int, released: float) -> int:
        """Pop cycle of the row's last beat, for a row made from ``first`` to ``last``
        (producer cycles, evenly) and let in from consumer cycle ``released``."""
        pops, d, step = self.pops, self.depth, self.step
        p_src, p_dst, de, se = self.p_src, self.p_dst, self.data_edges, self.space_edges
        first, last = math.ceil(first), math.ceil(last)
        span = last - first
        even = span == (w - 1) * step
        q = max(pops[-1] + 1 if pops else 0, math.ceil(released))
        p = self.push
        run = 0  # beats in a row pushed at their own pace and popped once visible
        x = 0
        while x < w:
            p = max(first + -(-x * span // max(1, w - 1)), p + step)
            own = p
            if len(pops) >= d:
                p = max(p, room_from(pops[-d], p_src, p_dst, p_dst / p_src, se))
            v = visible_from(p, p_src, p_dst, p_src / p_dst, de)
            run = run + 1 if p == own and v >= q else 0
            q = max(q, v)
            pops.append(q)
            q += 1
            x += 1
            if run >= d and even and self.shortcut and x < w:
                # the rest of the row at the producer's pace (class docstring)
                p += (w - x) * step
                pops.extend(visible_from(p - j * step, p_src, p_dst, p_src / p_dst, de)
                            for j in range(min(d, w - x) - 1, -1, -1))
                break
        self.push = p
        del pops[:-d]
        return pops[-1]


def block_work(plan: ChipPlan) -> dict[str, tuple[int, float]]:
    """Work per frame of every block as (cycles, clock in Hz), as the cycle report counts it;
    a memory source's is its transfer, max(N, ceil(N f / B)) cycles (its busy cycles unless it
    is also back-pressured). A camera's work is its frame period, ``(H + vblank) (W +
    hblank)`` pixel clocks, so a camera-bound rate is the camera's own frame rate (with
    ``sva.pairs`` = P pairs sharing the chip, 1/P of it: the chip takes P frames a period)."""
    h, w = plan.shape
    n = h * w
    out: dict[str, tuple[int, float]] = {}
    for b in plan.blocks:
        if b.kind == "sink":
            continue
        busy = 0
        if b.kind == "memory":
            hz = round(plan.domains[b.domain].freq_hz)
            busy = max(n, memory_first_cycle(n - 1, hz, b.bytes_per_s) + 1)
        out[b.name] = (plan.work_cycles(b, busy), plan.domains[b.domain].freq_hz)
    return out


def merge_depth_needed(plan: ChipPlan) -> int | None:
    """The least ``fifo.nna_to_merge_depth`` at which column tiles keep the frame rate the
    blocks' work allows (``fps_bound``); None without a merge of column tiles.

    The merge drains a camera's tiles in raster order: row y of tile 0, of tile 1, ..., then
    row y + 1. In the steady state each row takes T NNA cycles (the slowest block's work per
    row; a camera streaming into the NNA: its line), of which the merge serves tile t for
    G_t >= w_t a cycles (w_t the tile's width, a = max(1, R f_nna / (W f_sva)) cycles a
    descriptor at the SVA's pace, R = (W - 1) II + max(II, (r + 1) a_slot) its ticks a row,
    :func:`~sim.cycle.rules.sva_frame_ticks`), sum_t G_t = T. Meanwhile tile t goes on computing one
    descriptor per c cycles, less the slack T - w_t c it has each row, so its FIFO must hold
    P_t = w_t - G_t / c descriptors. The tiles settle (by blocking) into the sharing that
    minimises the largest P_t: P with sum_t max(w_t a, c (w_t - P)) = T (P = 0 if T leaves room
    for all), L = P c cycles -- equal tiles of width w at the NNA's bound: P = w (k - 1) / k.
    A FIFO of depth d and the descriptor in the MAC array cover (d + 1) c cycles, which must
    reach L plus the FIFO's round trip (``data_edges + space_edges``) plus one cycle:
    d = ceil((L + round trip + 1) / c) - 1, at least 1.

    The criterion is the cycle model's sustained rate over a stream (``stream.sustained_fps``)
    reaching ``fps_bound``: at this depth it does, one entry less it does not
    (tests/sim/cycle/test_estimate.py; frames from memory). A camera streaming into the NNA staggers
    the tiles by itself (each receives its part of a line later than the one to its left), so
    there the figure is an upper bound (1-2 entries over where measured). At this depth tiles
    still wait a little while they settle, so the frame latency can be a few cycles per row
    above this estimate's. Not included: the SVA's frame start. Between frames it issues no
    word for (r + 1) a + S + (k - 1) W a ticks (the column sums' passes and the median's
    flush, :func:`~sim.cycle.rules.sva_frame_ticks`) while its row buffers let the next
    frame's rows run at most 2r + 2 rows ahead; an SVA only a little faster than the NNA
    then holds the NNA back at each frame boundary, and a stream needs deeper FIFOs than
    this figure to stay at the bound (40 x 410, 8 submodules, the SVA at 465 MHz: 400 entries
    against 77)."""
    if plan.cfg.nna.split != "columns" or plan.parts < 2:
        return None
    h = plan.shape[0]
    subs = [b for b in plan.blocks_of("nna") if b.side == 0]  # one camera's tiles
    c = subs[0].ii
    f_nna = plan.domains["nna"].freq_hz
    sva = plan.block("sva")
    # the SVA's pace a descriptor inside a frame: a row's words and the gap before the next
    sva_row = sva_frame_ticks(1, plan.shape[1], sva.ii, sva.lookahead, sva.slot_ii,
                              0, 0, 1)
    a = max(1.0, sva_row / plan.shape[1] * f_nna / plan.domains["sva"].freq_hz)
    work = block_work(plan)
    # each block's time a row inside a frame (the SVA: its row, without the frame's start)
    row_s = max(sva_row / plan.domains["sva"].freq_hz if name == "sva" else cycles / hz / h
                for name, (cycles, hz) in work.items() if plan.block(name).kind != "camera")
    if plan.camera_direct:
        camera = plan.blocks_of("camera")[0]
        row_s = max(row_s, camera.line_clocks / plan.domains["camera"].freq_hz)
    period = row_s * f_nna
    widths = sorted((b.tile.x1 - b.tile.x0 for b in subs), reverse=True)
    # sum_t max(w_t a, c (w_t - P)) falls as P grows while P < w_t (1 - a / c): solve it for P
    # over the n widest tiles, the others at w_t a, for the first n whose solution is still
    # above the next tile's turning point (the sum never exceeds T at P = w_max (1 - a / c))
    share = 0.0
    for n in range(1, len(widths) + 1):
        p = (c * sum(widths[:n]) + a * sum(widths[n:]) - period) / (c * n)
        turn = widths[n] * (1 - a / c) if n < len(widths) else 0.0
        if p >= turn:
            share = max(0.0, p)
            break
    link = plan.fifo(subs[0].outputs[0])
    round_trip = round_trip_fs(link, plan) / plan.domains[link.dst].period_fs  # one domain
    depth = math.ceil((share * c + round_trip + 1) / c - 1e-9) - 1
    return max(1, depth)


# ----------------------------------------------------------------------------------------------
# latency: the row timeline


def _feeder(plan: ChipPlan):
    """The block that pushes one camera's pixels into the NNA's FIFOs: a camera streaming
    straight in, or a memory source (frames in memory, or a camera's frame buffers)."""
    return next(b for b in plan.blocks if b.kind in ("memory", "camera") and b.outputs)


class SourceTimes:
    """The cycle (of the feeding block's domain) in which pixel k (raster, frame 0) leaves an
    unobstructed source, by the rules of :mod:`sim.cycle.readable.blocks.sources`:

    - a camera streaming into the NNA: its pixel clock (:func:`camera_cycle`);
    - a memory source: its token bucket (:func:`memory_first_cycle`), or through the DRAM
      channel once its read burst is in (:func:`dram_slot`, :func:`dram_read_ready_fs`:
      the bursts take the read slots in turn, each requested at once -- a prefetch that never
      waits: a lower bound) and a cycle after the burst's pixel before it (a burst's pixels
      leave one a cycle once it is in);
    - reading a camera's frame buffers (``feed``): not before the first NNA edge after the
      camera wrote the pixel (:func:`camera_cycle`, :func:`seen_from`), and through the DRAM
      channel a burst is requested once the camera wrote its last pixel.

    Frame 0 of the camera is the stream's frame 0 (it is always taken)."""

    def __init__(self, plan: ChipPlan):
        self.plan = plan
        self.src = _feeder(plan)
        self.period = plan.domains[self.src.domain].period_fs
        self.camera = plan.block(self.src.feed) if self.src.feed else None
        self.cam_period = plan.domains["camera"].period_fs if plan.camera else 0
        self.ready: list[int] = []  # DRAM: per read burst, the first cycle its first pixel leaves
        self.slot = -1

    def _camera(self, k: int) -> int:
        w = self.plan.shape[1]
        raster = self.camera if self.camera is not None else self.src
        return camera_cycle(0, k % w, k // w, raster.line_clocks, raster.frame_clocks, 1)

    def _burst_first(self, b: int) -> int:
        """The cycle the first pixel of read burst b leaves: once the burst is in, and after
        the previous burst's pixels, one a cycle (the camera wrote them all before the burst
        was requested)."""
        d = self.plan.dram
        n = self.plan.shape[0] * self.plan.shape[1]
        while len(self.ready) <= b:
            r = len(self.ready)
            request = 0
            if self.camera is not None:  # after the camera wrote the burst's last pixel
                request = self._camera(burst_last(r, n, d.read_pixels)) * self.cam_period
            self.slot = dram_slot(request, self.slot, d.slot_fs, d.round_slots, d.reads.first, 1)
            ready = first_edge_at(dram_read_ready_fs(self.slot, d.slot_fs, d.latency_fs),
                                  self.period)
            self.ready.append(max(ready, self.ready[-1] + d.read_pixels if r else 0))
        return self.ready[b]

    def cycle(self, k: int) -> int:
        src = self.src
        if src.kind == "camera":
            return self._camera(k)
        n = self.plan.shape[0] * self.plan.shape[1]
        if self.plan.dram is not None:
            px = self.plan.dram.read_pixels
            first = max(k, self._burst_first(burst_of(k, n, px)[0]) + k % px)
        else:
            hz = round(self.plan.domains[src.domain].freq_hz)
            first = max(k, memory_first_cycle(k, hz, src.bytes_per_s))
        if self.camera is not None:  # the camera has written it into the frame buffer
            first = max(first, seen_from(self._camera(k), self.cam_period, self.period, 1))
        return first


def _tile_rows(plan: ChipPlan, sub, pops: list | None = None,
               times: SourceTimes | None = None) -> dict[int, tuple[float, float]]:
    """NNA cycles of the first and last descriptor push of every output row of one submodule
    (``sub``: its block in the plan); ``pops`` (a list) receives the NNA cycle it pops its
    last input pixel; ``times``: its camera's source (one for the tiles of a camera)."""
    h_img, w_img = plan.shape
    first_layer = sub.layers[0]
    tile: Tile = first_layer.tile
    half, c, rows = first_layer.half, first_layer.ii, first_layer.rows
    tw_in = tile.in_x1 - tile.in_x0
    tw = tile.x1 - tile.x0
    src = plan.fifo(sub.inputs[0])
    times = times or SourceTimes(plan)
    p_nna = plan.domains["nna"].period_fs
    # the source -> NNA link: one pop per NNA cycle, at most depth items per round trip
    ii_in = max(1.0, round_trip_fs(src, plan) / src.depth / p_nna)
    if src.crossing:
        ii_in = max(ii_in, plan.domains[src.src].period_fs / p_nna)
    pop_end: dict[int, float] = {}
    out: dict[int, tuple[float, float]] = {}
    next_out = tile.y0
    prev_end = -1.0
    prev_out_last = -1.0
    for y_in in range(tile.in_y0, tile.in_y1):
        k0 = y_in * w_img + tile.in_x0
        k1 = y_in * w_img + tile.in_x1 - 1
        start = max(visible(src, times.cycle(k0), plan), prev_end + 1)
        # line-buffer room: the output rows that must have left before this row may enter
        started = nna_rows_started_before_input(y_in - tile.in_y0, rows, half, tile.top_halo,
                                                tile.y1 - tile.y0, tile.in_y1 - tile.in_y0)
        if started > 0 and tile.y0 + started - 1 in out:
            start = max(start, out[tile.y0 + started - 1][1] + 1)
        end = max(visible(src, times.cycle(k1), plan),
                  math.ceil(start + (tw_in - 1) * ii_in))
        pop_end[y_in] = end
        prev_end = end
        while next_out < tile.y1 and nna_last_input_row(next_out, half, h_img) <= y_in:
            ready = pop_end[nna_last_input_row(next_out, half, h_img)] + 1
            first = mac_done(max(ready, prev_out_last + 1), c)
            last = first + (tw - 1) * c
            out[next_out] = (first, last)
            prev_out_last = last
            next_out += 1
    if pops is not None:
        pops.append(prev_end)
    return _later_layers(sub, out, h_img)


def _later_layers(sub, rows: dict[int, tuple[float, float]], h_img: int
                  ) -> dict[int, tuple[float, float]]:
    """The rows of a submodule's last layer from its first layer's (``rows``: first and last
    output of each row): layer l's row y starts once layer l - 1's row min(y + h_l, H - 1) is
    out and its own row before has ended, and takes W_l II_l cycles (no room wait: exact while
    each layer's line buffer has a row of slack and no later layer is faster than one before,
    else a lower bound)."""
    for lay in sub.layers[1:]:
        t, c = lay.tile, lay.ii
        out = {}
        prev = -1.0
        for y in range(t.y0, t.y1):
            start = max(rows[nna_last_input_row(y, lay.half, h_img)][1], prev) + 1
            out[y] = (mac_done(start, c), mac_done(start, (t.x1 - t.x0) * c))
            prev = out[y][1]
        rows = out
    return rows


def _merged_rows(plan: ChipPlan, side: int):
    """First/last push (NNA cycles) of each row of one camera's descriptor stream towards the
    SVA, the items-per-cycle the stream can sustain and the NNA cycle the camera's last pixel
    was popped (the source's read of the frame is over)."""
    h, w = plan.shape
    subs = [b for b in plan.blocks if b.kind == "nna" and b.side == side]
    c = subs[0].ii
    pops: list = []
    times = SourceTimes(plan)
    per_tile = [_tile_rows(plan, b, pops, times) for b in subs]
    if len(subs) == 1:
        return per_tile[0], float(c), max(pops)
    rows_split = plan.cfg.nna.split == "rows"
    rows: dict[int, tuple[float, float]] = {}
    prev_end = -1.0
    for y in range(h):
        first = None
        for t, sub in enumerate(subs):
            tile = sub.tile
            if not tile.y0 <= y < tile.y1:
                continue
            link = plan.fifo(sub.outputs[0])
            tw = tile.x1 - tile.x0
            t_first, t_last = per_tile[t][y]
            start = max(visible(link, t_first, plan), prev_end + 1)
            if rows_split and y == tile.y0 and t > 0:
                # a band's FIFO holds d items while the merge drains the bands before it: the
                # band produced d + 1 descriptors ahead and makes the rest at its own II now
                n_band = tile.shape[0] * tile.shape[1]
                per_tile[t] = _delay_band(per_tile[t], tile, start, n_band, link.depth, c)
                t_first, t_last = per_tile[t][y]
            end = max(start + tw - 1, visible(link, t_last, plan))
            first = start if first is None else first
            prev_end = end
        rows[y] = (first, prev_end)
    if rows_split:
        # the merge drains a band at one beat per cycle; the band's own II is in its row times
        return rows, 1.0, max(pops)
    widest = max(b.tile.x1 - b.tile.x0 for b in subs)
    return rows, max(1.0, c * widest / w), max(pops)


def _delay_band(rows, tile: Tile, merge_start: float, n_band: int, depth: int, c: int):
    """A row band back-pressured by the merge until ``merge_start``: its descriptors after the
    first depth + 1 follow at its II from then on (approximation; docs/whatif.md)."""
    w = tile.x1 - tile.x0
    out = {}
    for y, (first, last) in rows.items():
        j0 = (y - tile.y0) * w
        lo = merge_start + (j0 - depth - 1) * c
        out[y] = (max(first, lo), max(last, lo + (w - 1) * c))
    return out


def _box_row_input(sva, y: int, w: int, h: int) -> int:
    """The input row box row y waits for: its look-ahead's (``sva_last_input_row``), and for
    row 0 also the frame's first slot's (``sva_slot``: the automatic weights' band)."""
    if y == 0:
        return max(sva_slot(i, w, h, sva.lookahead, sva.passes, sva.first_row)[0]
                   for i in (0, sva.passes * w))
    return sva_last_input_row(y, sva.lookahead, h)


def timeline(plan: ChipPlan) -> dict:
    """First and last output word of one frame (SVA cycles, as the sink pops them) and the
    cycles of intermediate events, from the row model of the module docstring."""
    h, w = plan.shape
    nna_rows, nna_ii, last_pop = _merged_rows(plan, 0)
    sva = plan.block("sva")
    la = sva.lookahead
    link = plan.fifo(sva.inputs[0])
    to_sink = plan.fifo(sva.outputs[0])
    p_nna, p_sva = plan.domains["nna"].period_fs, plan.domains["sva"].period_fs
    # the NNA -> SVA stream: one pop per SVA cycle, the producer's II, the FIFO's round trip
    ii_link = max(1.0, round_trip_fs(link, plan) / link.depth / p_sva)
    ii_in = max(ii_link, nna_ii * p_nna / p_sva)
    # the SVA -> sink FIFO: the SVA's II, or depth words per round trip
    sink_trip = round_trip_fs(to_sink, plan) / p_sva  # cycles (one domain)
    ii_out = max(float(sva.ii), sink_trip / to_sink.depth)
    walk = None
    if fills(link, plan):
        # the producer's pace after a block: a submodule's II, or the merge's one beat a cycle
        producer = plan.block(link.producer)
        walk = LinkWalk(link, plan, producer.ii if producer.kind == "nna" else 1)
    in_end: dict[int, float] = {}
    box_rows: dict[int, tuple[float, float]] = {}  # each box row's first and last issue
    r, a, skew = la, sva.slot_ii, sva.skew
    never = -(1 << 40)
    next_out = 0
    prev_end = -1.0
    prev_out = never
    for y in range(h):
        first, last = nna_rows[y]
        done = sva_rows_done_before_input(y, la, h)
        # the row window is released when the last word of box row done - 1 enters the
        # pipeline (the estimate has no stalls: ticks are cycles)
        released = box_rows[done - 1][1] + 1 if done > 0 else 0
        if walk is not None:
            # a FIFO within a beat of its round trip: its handshake beat by beat (LinkWalk)
            end = walk.row(first, last, w, released)
        else:
            start = max(visible(link, first, plan), prev_end + 1)
            span = (w - 1) * ii_link
            if released > start:
                # the look-ahead window held the row back: the FIFO filled meanwhile, so its
                # first `depth` beats leave one per cycle and the rest at the upstream's own II
                # (its row times above are those of an unobstructed producer)
                start = released
                held = min(link.depth, w)
                span = (held - 1) * ii_link + (w - held) * ii_in
            end = max(visible(link, last, plan), math.ceil(start + span))
        in_end[y] = end
        prev_end = end
        while next_out < h and _box_row_input(sva, next_out, w, h) <= y:
            ready = in_end[_box_row_input(sva, next_out, w, h)] + 1
            passes_end = never
            if next_out == 0:  # the column sums' passes (their rows are in)
                passes_end = sva_frame_start(never, a, skew, sva.flush_ii)
                for q in range(sva.passes):
                    row = sva_slot(q * w, w, h, r, sva.passes, sva.first_row)[0]
                    passes_end = sva_pass_start(in_end[row] + 1, passes_end) + w * a
            o_first = math.ceil(sva_first_word_tick(ready, prev_out, ii_out, r, a,
                                                    passes_end))
            o_last = math.ceil(o_first + (w - 1) * ii_out)
            box_rows[next_out] = (o_first, o_last)
            prev_out = o_last
            next_out += 1

    def leaves(j: int) -> float:
        """The cycle word j of the frame reaches the output register: L after the word it
        leaves with; the last S words with flush slots, one a median II f or at the sink
        FIFO's rate."""
        item, slots = sva_exit_item(j, skew, h * w, 1)  # flush slots after the last word
        y_i, x_i = divmod(item, w)
        flush = slots * max(float(sva.flush_ii), sink_trip / to_sink.depth)
        return box_rows[y_i][0] + x_i * ii_out + flush + sva.latency

    return {
        "nna_first_push": nna_rows[0][0],
        "sva_first_ready": in_end[sva_last_input_row(0, la, h)] + 1,
        "source_last_pop_nna": last_pop,
        "first_output_cycle": visible(to_sink, math.ceil(leaves(0)), plan),
        "last_output_cycle": visible(to_sink, math.ceil(leaves(h * w - 1)), plan),
        "period_fs": {name: d.period_fs for name, d in plan.domains.items()},
        "stream_ii_sva_cycles": {"nna_to_sva": ii_in, "sva_to_sink": ii_out},
    }


# ----------------------------------------------------------------------------------------------
# the paper's arithmetic


def layer_macs_per_pixel(layers) -> int:
    return sum(k * k * c_in * c_out for k, c_in, c_out in layers)


def paper_analysis(shape: tuple[int, int]) -> dict:
    """Four 3x3 layers vs one 9x9 layer (MACs, weights, feature-map memory) and float vs binary
    descriptor traffic, for a frame of ``shape`` (the paper's figures are for 1280x720)."""
    h, w = shape
    n = h * w
    channels = 32
    four, one = layer_macs_per_pixel(FOUR_LAYERS), layer_macs_per_pixel(SINGLE_LAYER)
    return {
        "macs_per_pixel": {"four_layer_3x3": four, "single_layer_9x9": one},
        "macs_per_frame": {"four_layer_3x3": four * n, "single_layer_9x9": one * n},
        "weights": {"four_layer_3x3": four, "single_layer_9x9": one},
        # the paper keeps one intermediate feature map in memory at a time (float32)
        "feature_map_bytes": {
            "four_layer_float32_frame": n * channels * 4,
            "four_layer_int8_frame": n * channels,
            # streamed instead: each 3x3 layer needs 3 rows of its input (int8)
            "four_layer_int8_line_buffers": sum(3 * w * c_in for _, c_in, _ in FOUR_LAYERS),
            "single_layer_int8_line_buffer": 9 * w,
        },
        "descriptor_bytes_per_frame": {
            "float32_32ch": n * channels * 4,
            "binary_32bit": n * channels // 8,
        },
    }


# ----------------------------------------------------------------------------------------------
# the estimate


def delivered_fps(plan: ChipPlan, tl: dict, fps_bound: float, bottleneck: str
                  ) -> tuple[float, str]:
    """The frame rate the chip delivers and why: the work bound (frames from memory; a camera
    that is the bottleneck: its own rate, P x for ``sva.pairs`` = P), or behind a camera with
    frame buffers that sends more frames than the chip takes, the frames it does take: with
    two buffers or more the reader always has the next frame (the work bound); with one (one
    pair) the next frame is taken only if it starts after the reader finished the last, so
    a frame costs floor(R / T) + 1 camera periods T (R: the reader's end of frame 0,
    :func:`~sim.cycle.rules.frame_buffer_admits`)."""
    if not plan.camera:
        return fps_bound, "the work bound (frames from memory)"
    cam = plan.blocks_of("camera")[0]
    if plan.block(bottleneck).kind == "camera":
        return fps_bound, f"the camera's frame rate{' (every pair)' if plan.pairs > 1 else ''}"
    if plan.camera_direct:
        return fps_bound, "the work bound (below the camera's rate: the camera overflows)"
    if plan.cfg.source.frame_buffers > 1 or plan.pairs > 1:
        return fps_bound, "the work bound (the chip drops the camera frames beyond it)"
    period_fs = cam.frame_clocks * plan.domains["camera"].period_fs
    link = plan.fifo(_feeder(plan).outputs[0])
    read_end_fs = (p_src := plan.domains[link.src].period_fs) * fifo_rule.visible_until(
        tl["source_last_pop_nna"], p_src, plan.domains[link.dst].period_fs, link.data_edges)
    periods = read_end_fs // period_fs + 1
    return (min(fps_bound, plan.camera_fps / periods),
            f"one frame buffer: one camera frame in {periods} (the chip drops the others)")


def one_frame_cycles(plan: ChipPlan, last_output_sva_cycle: int) -> dict[str, int]:
    """Each domain's cycles in a one-frame run that ends with the last output word in SVA cycle
    ``last_output_sva_cycle`` (:func:`~sim.cycle.rules.edges_through`): the clock counts a
    one-frame cycle run prices (:func:`~sim.cycle.energy.estimate_energy`)."""
    t_end = last_output_sva_cycle * plan.domains["sva"].period_fs
    return {name: edges_through(t_end, d.period_fs) for name, d in plan.domains.items()}


def submodules_for(plan: ChipPlan, fps: float) -> dict | None:
    """The least even ``nna.stereo_submodules`` whose NNA work bound (:func:`~sim.cycle.figures.
    nna_fps`, its busiest submodule's) reaches ``fps`` at the plan's frame size, everything
    else as configured; with the ``nna.submodules`` the chip then needs (the lent ones beside)
    and the merge depth its column tiles need (:func:`merge_depth_needed`). None when no count
    up to ``nna.stereo_submodules``' largest does, or the frame cannot be split that far.

    The NNA's rate grows with the count in steps (the widest tile sets it), so the search
    starts at the count the current rate scales to and walks down, then up, in steps of 2."""
    cfg = plan.cfg
    most = next(f.metadata["hi"] for f in dataclasses.fields(type(cfg.nna))
                if f.name == "stereo_submodules")
    rates: dict[int, tuple[float, ChipPlan] | None] = {}

    def rate(s: int):
        if s not in rates:
            n = cfg.nna
            other = dataclasses.replace(cfg, nna=dataclasses.replace(
                n, stereo_submodules=s, submodules=max(n.submodules, s + n.lent_submodules)))
            try:
                p = build_plan(other, plan.shape)
                rates[s] = (nna_fps(p), p)
            except UserError:  # more tiles than columns, more submodules than the key allows
                rates[s] = None
        return rates[s]

    s = cfg.nna.stereo_submodules
    guess = 2 * math.ceil(s * fps / nna_fps(plan) / 2)
    s = min(max(2, guess), most)
    while s > 2 and rate(s - 2) is not None and rate(s - 2)[0] >= fps:
        s -= 2
    while s <= most and (rate(s) is None or rate(s)[0] < fps):
        if rate(s) is None and s > guess:
            return None  # the frame cannot be split further
        s += 2
    if s > most:
        return None
    got, p = rate(s)
    return {"fps": round(fps, 3), "stereo_submodules": s, "per_camera": s // 2,
            "nna_fps": got, "submodules": p.cfg.nna.submodules,
            "merge_depth_needed": merge_depth_needed(p)}


def estimate(cfg: ChipConfig, shape: tuple[int, int], table: EnergyTable | None = None) -> dict:
    """The analytic report for one frame of ``shape`` = (H, W) (module docstring); keys follow
    the cycle report's where both have the figure. The chip plan is built first, so a chip
    that cannot be built is refused here as in the cycle model. ``energy``: the frame's energy
    and the power at the delivered rate (:func:`delivered_fps`) from ``table`` (default:
    stereosim's, :func:`~sim.cycle.energy.energy_table`)."""
    plan = build_plan(cfg, shape)
    h, w = shape
    tl = timeline(plan)
    work = block_work(plan)
    work_s = {name: cycles / hz for name, (cycles, hz) in work.items()}
    bottleneck = max(sorted(work_s), key=lambda n: work_s[n])
    frame_s = work_s[bottleneck]
    p_sva = tl["period_fs"]["sva"]
    fifos = sorted(plan.fifos, key=lambda f: f.name)
    fifo_rate = {}
    for f in fifos:
        rt_s = round_trip_fs(f, plan) / FS_PER_S
        fifo_rate[f.name] = min(f.depth / rt_s, plan.domains[f.src].freq_hz,
                                plan.domains[f.dst].freq_hz)
    buffers = sram_bits(plan)
    subs = plan.blocks_of("nna")
    widest = max(b.tile.x1 - b.tile.x0 for b in subs)
    warnings = []
    if plan.camera_direct:  # with frame buffers the camera writes into DRAM: no FIFO to fill
        camera = plan.blocks_of("camera")[0]
        line_s = camera.line_clocks / plan.domains["camera"].freq_hz
        if widest * subs[0].ii / plan.domains["nna"].freq_hz > line_s:
            warnings.append(
                "the NNA needs more time per row than the camera gives it: the camera will "
                "overflow the source FIFO (more nna.stereo_submodules, nna.macs or clocks.nna_mhz)"
            )
    merge_depth = merge_depth_needed(plan)
    if merge_depth is not None and cfg.fifo.nna_to_merge_depth < merge_depth:
        warnings.append(
            f"the merge FIFOs (fifo.nna_to_merge_depth={cfg.fifo.nna_to_merge_depth}) are "
            f"shallower than the {merge_depth} the column tiles need: the merge drains the "
            "tiles in raster order, so each tile waits for the others and frames come slower "
            "than the work bound and this latency estimate say (both are upper bounds"
            + ("; a camera can overflow while they do" if plan.camera_direct else "")
            + f"); set fifo.nna_to_merge_depth={merge_depth} or more, or run the cycle model"
        )
    if subs[0].rows < 2 * subs[0].half + 2:
        warnings.append(
            "nna.line_buffer_rows holds only the window: a row waits for the window to move "
            "(latency estimate approximate)"
        )
    camera_fps = None if plan.camera_fps is None else round(plan.camera_fps, 3)
    fps, fps_basis = delivered_fps(plan, tl, 1.0 / frame_s, bottleneck)
    fps = round(fps, 3)  # as the report gives it, and the power is given at
    if (plan.frame_buffered and plan.cfg.source.on_overflow == "error"
            and plan.block(bottleneck).kind != "camera"):
        warnings.append(
            f"the chip takes {1.0 / frame_s:.3f} fps (bottleneck {bottleneck}), fewer frames "
            "than the cameras send: in a stream a frame will find no free frame buffer and the "
            "run stops (source.on_overflow=drop_frame drops it instead)")
    energy = estimate_energy(plan, table or energy_table(), fps, fps_basis)
    nna_bits = sum(v for k, v in buffers.items() if k.startswith("nna."))
    actions = action_counts(plan)
    return {
        "image": {"width": w, "height": h},
        "config": config_to_dict(cfg),
        "throughput": {
            "fps_bound": round(1.0 / frame_s, 3),
            "bottleneck": bottleneck,
            "work_ms_per_frame": {n: round(v * 1e3, 6) for n, v in sorted(work_s.items())},
            "fps_bound_per_block": {n: round(1.0 / v, 3) for n, v in sorted(work_s.items())},
            "fifo_items_per_s": {n: round(v, 1) for n, v in sorted(fifo_rate.items())},
            # a camera's real frame rate: its whole raster, vertical blanking included
            "camera_fps": camera_fps,
            # the rate the chip delivers, what power is given at (delivered_fps)
            "fps_delivered": fps,
            "fps_delivered_basis": fps_basis,
            # the least fifo.nna_to_merge_depth that keeps column tiles at fps_bound
            "merge_depth_needed": merge_depth,
            # the NNA submodules that keep up with the camera (None: no camera, or none do)
            "submodules_for_camera": (submodules_for(plan, plan.camera_fps)
                                      if plan.camera else None),
        },
        "latency": {
            "first_output_us": tl["first_output_cycle"] * p_sva / 1e9,
            "frame_ms": tl["last_output_cycle"] * p_sva / 1e12,
            "first_output_sva_cycle": round(tl["first_output_cycle"]),
            "last_output_sva_cycle": round(tl["last_output_cycle"]),
        },
        "sram_bits": buffers,
        "sram_bits_total": {
            "nna_per_submodule": nna_bits,
            "nna_stereo": cfg.nna.stereo_submodules * nna_bits,
            "sva": sum(v for k, v in buffers.items() if k.startswith("sva.")),
            "fifos": sum(f.sram_bits for f in fifos),
        },
        "chip_sram": chip_sram(plan),
        "fifo_sram_bits": {f.name: f.sram_bits for f in fifos},
        "fifo_bytes_per_frame": {f.name: f.beats * f.width_bits // 8 for f in fifos},
        "actions": actions,
        "macs_per_frame": 2 * actions["nna_per_camera"]["macs"],
        **({"nna_layers": layer_report(plan)} if len(subs[0].layers) > 1 else {}),
        **({"lent_network": lent_report(plan.lent, plan.dram, h * w)} if plan.lent else {}),
        "energy": energy,
        "paper": paper_analysis(shape),
        "warnings": warnings,
    }


def parse_size(text: str) -> tuple[int, int]:
    """``"1280x720"`` -> (720, 1280) = (H, W); raises InputError on anything else."""

    wh = text.lower().split("x")
    if len(wh) != 2 or not all(p.strip().isdigit() for p in wh):
        raise InputError(f"size {text!r} is not WIDTHxHEIGHT, e.g. 1280x720")
    w, h = int(wh[0]), int(wh[1])
    if w < 2 or h < 1 or w * h > 1 << 26:
        raise InputError(f"size {text!r}: give at least 2x1 and at most 64 M pixels")
    return h, w
