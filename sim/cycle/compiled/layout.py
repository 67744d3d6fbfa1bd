"""The chip plan serialised for the compiled engine: named record arrays, no magic columns.

:func:`serialise` turns a :class:`~sim.cycle.plan.ChipPlan` into a :class:`Net`, the one
argument of every kernel: the plan's constants frozen for the run (``prm``, :data:`CONSTANTS`),
what the run changes and how it ends (``state``, :data:`STATE`), the indices of the streams,
FIFOs, blocks and row slots the kernels read by name (``ids``, :data:`IDS`), one record per event
stream (``streams``: its length, how many events are known, its ring in ``ring``), per camera
tile (``tiles``), per FIFO (``fifos``) and per block (``blocks``), the statistics the kernels
accumulate (``acc``), the watchdog's long gaps (``gaps``) and the row instants (``rows``).

Event streams (the cycle of every beat of a FIFO's producer or consumer, in beat order), by
kind (``STREAM.kind``):

- :data:`SOURCE_PUSH` per side: the source pushes pixel k (raster order of the frame, the
  source's domain);
- :data:`LINE_POP` per tile: its line buffer pops input pixel i (raster order of the tile's
  input region);
- :data:`MAC_PUSH` per tile: its MAC array pushes descriptor j (raster order of the tile's
  output region);
- :data:`LAYER_PUSH` per tile and layer l < L - 1 of a network of L > 1 layers: layer l's MAC
  array writes output k (raster order of its output region) into layer l + 1's line buffer
  (the last layer's outputs are the tile's :data:`MAC_PUSH`);
- :data:`MERGE_MOVE` per side, split frames only: the merge moves descriptor m (raster order);
- :data:`SVA_POP`: the SVA pops pair j; :data:`SVA_PUSH`: it pushes word j; :data:`SINK_POP`:
  the sink pops word j;
- :data:`SVA_ISSUE`: the SVA's pipeline *tick* at which word j is issued
  (:mod:`sim.cycle.rules`: advancing cycles, not a cycle -- so the cursors skip it);
- :data:`DRAM_READ`: through the DRAM channel, the first source cycle the stereo pair's read
  burst r is in the chip; :data:`DRAM_WRITE`: the first sink cycle write-back burst u has left
  the write buffer (:class:`~sim.cycle.readable.blocks.sources.DramChannel`; empty without the
  channel).

The SVA's stages (``stages``, in stream order): offset and latency in ticks, the words their
registers hold, and what the walker counts (the most words held, busy and blocked cycles; the
cycle after which the last word has left the stage).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.sim.cycle.buffers import tracked
from stereosim.sim.cycle.plan import MAX_RUN_FS, ChipPlan
from stereosim.sim.cycle.rules import sink_pattern
from stereosim.sim.cycle.stages import stage_offsets

#: "never" (an event not computed, a stop that does not come): above every instant a run
#: reaches, which the plan's budget keeps at most MAX_RUN_FS
INF = 1 << 62
assert MAX_RUN_FS < INF

# stream kinds (``STREAM.kind``)
(SOURCE_PUSH, LINE_POP, MAC_PUSH, MERGE_MOVE, SVA_POP, SVA_PUSH, SINK_POP, SVA_ISSUE, DRAM_READ,
 DRAM_WRITE, LAYER_PUSH) = range(11)
# FIFO kinds (how its items map onto streams): source -> NNA tile, NNA tile -> merge,
# NNA (or merge) -> SVA, SVA -> sink
FIFO_TO_NNA, FIFO_TO_MERGE, FIFO_TO_SVA, FIFO_TO_SINK = range(4)
# block kinds
K_MEMORY, K_CAMERA, K_NNA, K_MERGE, K_SVA, K_SINK = range(6)
KIND_CODES = {"memory": K_MEMORY, "camera": K_CAMERA, "nna": K_NNA, "merge": K_MERGE,
              "sva": K_SVA, "sink": K_SINK}
# activities, in the order of sim.cycle.contract.ACTIVITIES
A_BUSY, A_STARVED, A_BLOCKED, A_IDLE = range(4)
# run outcome
END_DONE, END_STUCK, END_CAP, END_OVERFLOW, END_WATCHDOG = range(5)
ERR_NONE, ERR_RING, ERR_GAPS = 0, 1, 2

# the plan's constants, frozen for the run (``Net.prm``, one record)
CONSTANTS = np.dtype([
    ("h", np.int64), ("w", np.int64), ("n", np.int64),  # one frame's rows, columns, pixels
    ("frames", np.int64), ("frame_clocks", np.int64), ("parts", np.int64),
    ("sides", np.int64),  # sides computed: 1 when the right side's events are the left's
    ("merge", np.int64), ("camera", np.int64), ("line_clocks", np.int64),
    ("mem_hz", np.int64), ("mem_bps", np.int64), ("half", np.int64), ("rows", np.int64),
    ("nna_ii", np.int64), ("lookahead", np.int64), ("pipe_latency", np.int64), ("sva_ii", np.int64),
    ("passes", np.int64), ("skew", np.int64), ("flush_ii", np.int64),  # the SVA's sequencer
    ("slot_ii", np.int64), ("first_row", np.int64),
    ("latency", np.int64),
    ("per_src", np.int64), ("per_nna", np.int64), ("per_sva", np.int64), ("p_max", np.int64),
    ("cap_fs", np.int64),  # events at instants >= cap_fs are not computed
    ("watchdog_fs", np.int64), ("stats", np.int64),  # 1: accumulate statistics and gaps
    ("n_stages", np.int64),
    # a camera writing into frame buffers (fb of them), read by the memory sources
    ("fb", np.int64), ("fb_drop", np.int64), ("cam_line", np.int64), ("cam_frame", np.int64),
    ("per_cam", np.int64),
    ("pairs", np.int64),  # camera pairs sharing the chip frame by frame (sva.pairs)
    # the DRAM channel (dram = 1; sim.cycle.plan.DramPlan): slot length, round, the read pair's
    # and the write-back's slots, latency, pixels per read burst, read bursts ahead, words per
    # write burst, write buffer bursts
    ("dram", np.int64), ("d_slot", np.int64), ("d_round", np.int64), ("d_rfirst", np.int64),
    ("d_wfirst", np.int64), ("d_wcount", np.int64), ("d_lat", np.int64), ("d_rpx", np.int64),
    ("d_pref", np.int64), ("d_wwords", np.int64), ("d_wbuf", np.int64),
])

# what the kernels write as the run goes, and how it ends (``Net.state``, one record)
STATE = np.dtype([
    ("target", np.int64),  # words the sink takes to finish (fewer once a camera drops frames)
    ("fb_taken", np.int64),  # frame buffers: frames taken so far
    ("fb_next", np.int64),  # the next camera frame to decide
    ("sva_regular", np.int64),  # SVA words issued II ticks after the previous, without a stall
    ("sva_peaks_full", np.int64),  # 1: every SVA stage has held ceil(latency / II) words
    ("d_rslot", np.int64), ("d_wslot", np.int64),  # the last DRAM read and write slots (-1)
    # outcome
    ("end", np.int64), ("error", np.int64), ("horizon_fs", np.int64), ("first_pop", np.int64),
    ("iterations", np.int64),
])

# the indices the kernels read by name (``Net.ids``, one record): the streams of the SVA, the
# sink and the DRAM channel; the FIFOs around the SVA; the SVA's and the sink's blocks; the
# SVA's rows of row instants in ``Net.occ`` (the tiles' are in their records)
IDS = np.dtype([
    ("sva_pop", np.int64), ("sva_push", np.int64), ("sink_pop", np.int64),
    ("sva_issue", np.int64), ("dram_read", np.int64), ("dram_write", np.int64),
    ("fifo_sva_left", np.int64), ("fifo_sva_right", np.int64), ("fifo_sink", np.int64),
    ("block_sva", np.int64), ("block_sink", np.int64),
    ("occ_sva_in", np.int64), ("occ_sva_out", np.int64),
])

STREAM = np.dtype([
    ("kind", np.int64), ("side", np.int64), ("tile", np.int64), ("n", np.int64),
    ("count", np.int64), ("mask", np.int64), ("off", np.int64), ("period", np.int64),
    ("block", np.int64),
])

# an NNA tile of one camera: output region (x0 .. x1, y0 .. y1), input region (ix0 .., iy0 ..),
# their row widths and pixels per frame, the streams of its source's pushes, its line buffer's
# pops, its MAC array's pushes and its side's merge (-1: none), its FIFOs, its block, and its
# rows of row instants in ``Net.occ`` (input rows, output rows)
TILE = np.dtype([
    ("side", np.int64), ("t", np.int64), ("x0", np.int64), ("x1", np.int64), ("y0", np.int64),
    ("y1", np.int64), ("ix0", np.int64), ("ix1", np.int64), ("iy0", np.int64), ("iy1", np.int64),
    ("iw", np.int64), ("ow", np.int64), ("n_in", np.int64), ("n_out", np.int64),
    ("top_halo", np.int64), ("source_push", np.int64), ("line_pop", np.int64),
    ("mac_push", np.int64), ("merge_move", np.int64), ("src_fifo", np.int64),
    ("out_fifo", np.int64), ("block", np.int64), ("occ_in", np.int64), ("occ_out", np.int64),
    ("layer0", np.int64), ("n_layers", np.int64),  # its layers' records in ``Net.layers``
])

# a layer stage of an NNA tile (:class:`~nna.submodule.timing.LayerPlan`; one per tile for a single
# layer and the census): its half kernel, line buffer rows and cycles per output pixel, its
# regions (output x0 .. x1, y0 .. y1, input ix0 .., iy0 ..; row widths and items per frame),
# the streams of the items entering its line buffer (layer 0: the tile's pops; else the layer
# before's outputs) and of its outputs, its rows of row instants in ``Net.occ``, and what its
# loop counts (busy and blocked cycles, its first output) and the block's walker's cursor
LAYER = np.dtype([
    ("tile", np.int64), ("index", np.int64), ("last", np.int64), ("half", np.int64),
    ("rows", np.int64), ("ii", np.int64), ("top_halo", np.int64),
    ("x0", np.int64), ("x1", np.int64), ("y0", np.int64), ("y1", np.int64), ("ix0", np.int64),
    ("ix1", np.int64), ("iy0", np.int64), ("iy1", np.int64), ("iw", np.int64), ("ow", np.int64),
    ("n_in", np.int64), ("n_out", np.int64), ("in_stream", np.int64), ("out_stream", np.int64),
    ("occ_in", np.int64), ("occ_out", np.int64),
    ("busy", np.int64), ("blocked", np.int64), ("first", np.int64), ("wk", np.int64),
])

FIFO = np.dtype([
    ("kind", np.int64), ("side", np.int64), ("tile", np.int64), ("depth", np.int64),
    ("data_edges", np.int64), ("space_edges", np.int64), ("per_src", np.int64),
    ("per_dst", np.int64), ("push", np.int64), ("pop", np.int64), ("width", np.int64),
    ("crossing", np.int64), ("items", np.int64),
])

BLOCK = np.dtype([
    ("kind", np.int64), ("side", np.int64), ("tile", np.int64), ("period", np.int64),
    ("stream", np.int64),  # a source's pushes (the other blocks find theirs via tiles, FIFOs)
    ("fifo_in", np.int64), ("fifo_in2", np.int64), ("fifo_out", np.int64),
])

# statistics accumulated while the events are computed (and by the walkers behind them)
ACC = np.dtype([
    ("blocked", np.int64), ("starved", np.int64),  # blocks
    ("empty", np.int64),  # FIFOs: consumer cycles without a visible head, up to the last pop
    ("last_pop", np.int64),  # merge FIFOs: the merge's last pop of each tile FIFO
    ("walk", np.int64),  # walkers: the next event / beat to settle
    ("ptr", np.int64),  # walkers: a pointer into the stream they count in
    ("prev", np.int64),  # walkers: the previous beat's event
    ("last_busy", np.int64),  # the block's last busy instant so far (fs)
    ("over_cycle", np.int64), ("over_k", np.int64), ("over_tile", np.int64),  # a camera's
    ("gaps", np.int64),  # long gaps kept (Net.gaps)
    ("dram", np.int64),  # cycles a memory source or the sink waited on the DRAM channel
])

# an SVA stage: its place in the pipeline, and what the walker counts
STAGE = np.dtype([
    ("off", np.int64), ("lat", np.int64), ("slots", np.int64),
    ("peak", np.int64), ("busy", np.int64), ("blocked", np.int64),
    ("done", np.int64),  # the cycle after which the frame's last word has left it (-1: not yet)
])

# a row window's walk (sim.cycle.buffers.window_peaks, behind the streams): the slots of its row
# instants in ``occ`` (input rows, output rows), the streams whose counts say how
# many rows are known and their row widths, the window's offset and rows per frame, and the walk
WINDOW = np.dtype([
    ("slot", np.int64), ("out_slot", np.int64), ("in_stream", np.int64), ("in_width", np.int64),
    ("out_stream", np.int64), ("out_width", np.int64), ("offset", np.int64),
    ("in_rows", np.int64), ("out_rows", np.int64),
    ("row", np.int64), ("done", np.int64),  # the next input row; output rows done before it
    ("peak", np.int64), ("at", np.int64),  # the most rows held, and the cycle (-1: none yet)
])

# per tile of a camera, the table a source's or a merge's loop reads (``Net.scratch``): the
# tile's region (input region for a source, output region for a merge: x0 .. x1, y0 .. y1, its
# row width and pixels per frame), the ring of the stream it waits on (its line buffer's pops,
# its MAC array's pushes: offset, mask, events known, the highest index the ring no longer
# holds), the tile's FIFO (depth, periods of its consumer and producer, the visibility or
# free-slot edges), and the merge's counts of that FIFO (empty cycles, last pop)
TABLE = np.dtype([
    ("x0", np.int64), ("x1", np.int64), ("y0", np.int64), ("y1", np.int64), ("width", np.int64),
    ("items", np.int64), ("off", np.int64), ("mask", np.int64), ("count", np.int64),
    ("lost", np.int64), ("depth", np.int64), ("per_dst", np.int64), ("per_src", np.int64),
    ("edges", np.int64), ("empty", np.int64), ("last_pop", np.int64),
])

# a FIFO's occupancy walk: consumer timeline (histogram) and producer timeline (crossing)
WALK = np.dtype([
    ("inc", np.int64), ("dec", np.int64), ("cycle", np.int64), ("level", np.int64),
    ("top", np.int64), ("at_depth", np.int64), ("hoff", np.int64),
])


class Net(NamedTuple):
    prm: np.ndarray  # CONSTANTS, one record
    state: np.ndarray  # STATE, one record
    ids: np.ndarray  # IDS, one record
    streams: np.ndarray  # STREAM
    ring: np.ndarray  # int64: every stream's ring
    tiles: np.ndarray  # TILE, side-major
    layers: np.ndarray  # LAYER: per tile (side-major) its layers in order
    fifos: np.ndarray  # FIFO, in plan order
    blocks: np.ndarray  # BLOCK, in plan order
    acc: np.ndarray  # ACC: per block (0 .. B-1), then per FIFO (B .. B+F-1)
    walks: np.ndarray  # WALK: per FIFO the consumer walk, then per FIFO the producer walk
    hist: np.ndarray  # int64: the FIFOs' occupancy histograms (WALK.hoff)
    gaps: np.ndarray  # int64 (blocks, capacity, 2): long gaps (start_fs, end_fs) between
    # busy instants, per block; ACC.gaps counts them
    rows: np.ndarray  # int64 (2, H + 1): the first frame's row instants (Chip.row_times)
    occ: np.ndarray  # int64 (2 tiles + 2, R): a ring of R rows (row r at r % R) of the tracked
    # buffers' row instants over the stream, cycles of their block (sim.cycle.buffers): per
    # tile and layer (LAYER.occ_in) the cycle its line buffer took the first item of each input
    # row, (LAYER.occ_out) the cycle it let the last output of each output row leave (a
    # tile's TILE.occ_in / occ_out: its first layer's and its last layer's);
    # (IDS.occ_sva_in) the cycle the SVA took the first pair of each input row,
    # (IDS.occ_sva_out) the cycle it issued the last word of each output row (its rows read:
    # the row window's release, which the SVA's pops wait on); -1 where not reached
    scratch: np.ndarray  # TABLE (tiles per camera): per-tile tables of a kernel call
    cursors: np.ndarray  # int64 (streams,): events up to an instant (the samplers')
    stages: np.ndarray  # STAGE: the SVA's stages in stream order
    frame_fs: np.ndarray  # int64 (3, frames): per frame of the stream the chip took, the
    # instant (fs) of its first pixel (pushed by the left source, or a camera's) and of its last
    # word popped by the sink, and the input frame it is; -1 where not reached
    win: np.ndarray  # WINDOW: the row windows' walks (sim.cycle.buffers), the tiles computed
    # (side-major) then the SVA's
    fbuf: np.ndarray  # int64 (2, frames): with frame buffers, per camera frame whether it was
    # dropped ([0]: 1) and per frame taken the instant (fs) the reader finished it ([1])
    sink: np.ndarray  # int64: the sink's pattern, [P, the allowed cycles of a period]
    # (sim.cycle.rules.sink_pattern)


class StatusTables(NamedTuple):
    """What a block's status at an instant reads besides the streams (the samplers'
    ``status_*``): the :class:`Net`'s tables of that name (``ids``: its one record)."""

    tiles: np.ndarray
    fifos: np.ndarray
    frame_fs: np.ndarray
    ids: np.void
    sink: np.ndarray


class TraceData(NamedTuple):
    """What a traced window shows of the data, for the frames ``frame0`` .. ``frame0 + F - 1``
    whose beats it sees: both views' descriptors (F, 2, H, W) uint64, the output words
    (F, H, W) int32 and the output word's mask."""

    desc: np.ndarray
    words: np.ndarray
    word_mask: np.int64
    frame0: np.int64


def _pow2(n: int) -> int:
    return 1 << max(4, int(n - 1).bit_length())


def _row_ring(plan: ChipPlan, capacity: int) -> int:
    """Rows the row-instant rings keep: every row an event ring of ``capacity`` events spans in
    the narrowest tile, and the windows' own rows, at most the stream's rows."""
    narrow = min(min(t.in_x1 - t.in_x0, t.x1 - t.x0) for t in plan.tiles)
    rows = capacity // narrow + 4 * (plan.cfg.nna.line_buffer_rows + plan.shape[0] // 8) + 64
    return min(_pow2(rows), _pow2(plan.frames * plan.shape[0] + 2))


def ring_capacity(plan: ChipPlan, scale: int = 1) -> int:
    """Events each ring keeps: enough for every reader of a stream (the chip's storage -- every
    layer's line buffer and the SVA's row windows, FIFO depths -- bounds how far one stream runs
    ahead of another); a pass that still reads an overwritten event says so and is rerun with
    larger rings."""
    cfg = plan.cfg
    h, w = plan.shape
    half = max(b.half for b in plan.blocks_of("nna"))
    sva = plan.block("sva")
    la = sva.lookahead + sva.skew // w + 1  # the box's rows, and the median's skew
    depths = sum(f.depth for f in plan.fifos)
    band = max(t.in_shape[0] for t in plan.tiles) if cfg.nna.split == "rows" else 0
    # the line buffers of every layer (one layer: nna.line_buffer_rows)
    lines = sum(lay.rows for lay in plan.blocks_of("nna")[0].layers)
    rows = lines + half + la + 6 + band
    return min(_pow2(scale * (2 * rows * w + 2 * depths + 4096)), _pow2(plan.frames * h * w + 1))


def _stream_specs(plan: ChipPlan, sides: int, block_index: dict, fifo_index: dict):
    """Every event stream, (kind, side, tile, events, period, block) -- of the left side only
    when the right side's events are the same --, the stream ids per side and tile (by name:
    ``source_push``, ``line_pop``, ``mac_push``, ``merge_move``; ``layer_push``: per tile, each
    layer's outputs) and the :data:`IDS` record."""
    h, w = plan.shape
    n, nf, doms, parts = h * w, plan.frames, plan.domains, plan.parts
    specs = []
    a_id, b_id, e_id, m_id = {}, {}, {}, {}  # source pushes, line pops, MAC pushes, merges
    l_id = {}  # per tile, each layer's outputs (the last layer's: its MAC pushes)
    for s in range(sides):
        # the block that pushes the pixels: a camera straight into the NNA, or a memory
        # source (reading frames in memory or a camera's frame buffers)
        kind = "camera" if plan.camera_direct else "memory"
        src = next(b for b in plan.blocks if b.kind == kind and b.side == s)
        a_id[s] = len(specs)
        specs.append((SOURCE_PUSH, s, -1, nf * n, doms[src.domain].period_fs,
                      block_index[src.name]))
    for b in plan.blocks_of("nna"):
        if b.side >= sides:
            continue
        t = plan.tiles.index(b.tile) if parts > 1 else 0
        tile = b.tile
        b_id[b.side, t] = len(specs)
        specs.append((LINE_POP, b.side, t, nf * tile.in_shape[0] * tile.in_shape[1],
                      doms["nna"].period_fs, block_index[b.name]))
        e_id[b.side, t] = len(specs)
        specs.append((MAC_PUSH, b.side, t, nf * tile.shape[0] * tile.shape[1],
                      doms["nna"].period_fs, block_index[b.name]))
        l_id[b.side, t] = []
        for lay in b.layers[:-1]:  # a layer before the last: its outputs into the next one
            l_id[b.side, t].append(len(specs))
            specs.append((LAYER_PUSH, b.side, t, nf * lay.items, doms["nna"].period_fs,
                          block_index[b.name]))
        l_id[b.side, t].append(e_id[b.side, t])
    if parts > 1:
        for s in range(sides):
            m_id[s] = len(specs)
            specs.append((MERGE_MOVE, s, -1, nf * n, doms["nna"].period_fs,
                          block_index[f"merge_{('left', 'right')[s]}"]))
    if sides == 1:
        a_id[1] = a_id[0]
        m_id.update({1: m_id[0]} if parts > 1 else {})
        for t in range(parts):
            b_id[1, t], e_id[1, t], l_id[1, t] = b_id[0, t], e_id[0, t], l_id[0, t]
    ids = np.zeros(1, IDS)
    idx = ids[0]
    for kind, field, blk in ((SVA_POP, "sva_pop", "sva"), (SVA_PUSH, "sva_push", "sva"),
                             (SINK_POP, "sink_pop", "sink"), (SVA_ISSUE, "sva_issue", "sva")):
        idx[field] = len(specs)
        specs.append((kind, -1, -1, nf * n, doms["sva"].period_fs, block_index[blk]))
    d = plan.dram
    r_bursts = nf * -(-n // d.read_pixels) if d is not None and d.reads is not None else 0
    w_bursts = nf * -(-n // d.write_words) if d is not None else 0
    idx["dram_read"] = len(specs)
    specs.append((DRAM_READ, -1, -1, r_bursts, doms[plan.source_domain].period_fs,
                  block_index["sink" if plan.camera_direct else "memory_left"]))
    idx["dram_write"] = len(specs)
    specs.append((DRAM_WRITE, -1, -1, w_bursts, doms["sva"].period_fs, block_index["sink"]))
    idx["fifo_sva_left"] = fifo_index["nna_left_to_sva"]
    idx["fifo_sva_right"] = fifo_index["nna_right_to_sva"]
    idx["fifo_sink"] = fifo_index["sva_to_sink"]
    idx["block_sva"], idx["block_sink"] = block_index["sva"], block_index["sink"]
    layers = len(plan.blocks_of("nna")[0].layers)
    idx["occ_sva_in"], idx["occ_sva_out"] = 4 * parts * layers, 4 * parts * layers + 1
    names = {"source_push": a_id, "line_pop": b_id, "mac_push": e_id, "merge_move": m_id,
             "layer_push": l_id}
    return specs, names, ids


def _tiles(plan: ChipPlan, names: dict, block_index: dict, fifo_index: dict
           ) -> tuple[np.ndarray, np.ndarray]:
    """The :data:`TILE` records, side-major, and their layers' :data:`LAYER` records."""
    parts = plan.parts
    n_layers = len(plan.blocks_of("nna")[0].layers)
    tiles = np.zeros(2 * parts, TILE)
    layers = np.zeros(2 * parts * n_layers, LAYER)
    for b in plan.blocks_of("nna"):
        t = plan.tiles.index(b.tile) if parts > 1 else 0
        tl = b.tile
        ti = b.side * parts + t
        first = ti * n_layers
        tiles[ti] = (
            b.side, t, tl.x0, tl.x1, tl.y0, tl.y1, tl.in_x0, tl.in_x1, tl.in_y0, tl.in_y1,
            tl.in_x1 - tl.in_x0, tl.x1 - tl.x0, tl.in_shape[0] * tl.in_shape[1],
            tl.shape[0] * tl.shape[1], tl.top_halo, names["source_push"][b.side],
            names["line_pop"][b.side, t], names["mac_push"][b.side, t],
            names["merge_move"][b.side] if parts > 1 else -1, fifo_index[b.inputs[0]],
            fifo_index[b.outputs[0]], block_index[b.name], 2 * first,
            2 * (first + n_layers - 1) + 1, first, n_layers)
        outs = names["layer_push"][b.side, t]
        for lay in b.layers:
            r = lay.tile
            i = lay.index
            layers[first + i] = (
                ti, i, 1 if i == n_layers - 1 else 0, lay.half, lay.rows, lay.ii,
                r.top_halo, r.x0, r.x1, r.y0, r.y1, r.in_x0, r.in_x1, r.in_y0, r.in_y1,
                r.in_x1 - r.in_x0, r.x1 - r.x0, r.in_shape[0] * r.in_shape[1],
                r.shape[0] * r.shape[1], names["line_pop"][b.side, t] if i == 0 else outs[i - 1],
                outs[i], 2 * (first + i), 2 * (first + i) + 1, 0, 0, -1, 0)
    return tiles, layers


def _fifos(plan: ChipPlan, names: dict, idx) -> np.ndarray:
    """The :data:`FIFO` records, in plan order: how each one's items map onto streams."""
    parts, doms = plan.parts, plan.domains
    a_id, b_id, e_id, m_id = (names[k] for k in ("source_push", "line_pop", "mac_push",
                                                 "merge_move"))
    fifos = np.zeros(len(plan.fifos), FIFO)
    for i, f in enumerate(plan.fifos):
        prod, cons = plan.block(f.producer), plan.block(f.consumer)
        if cons.kind == "nna":
            t = plan.tiles.index(cons.tile) if parts > 1 else 0
            kind, side, push, pop = FIFO_TO_NNA, cons.side, a_id[cons.side], b_id[cons.side, t]
        elif cons.kind == "merge":
            t = plan.tiles.index(prod.tile)
            kind, side, push, pop = FIFO_TO_MERGE, cons.side, e_id[prod.side, t], m_id[prod.side]
        elif cons.kind == "sva":
            t = -1
            side = prod.side
            push = m_id[side] if parts > 1 else e_id[side, 0]
            kind, pop = FIFO_TO_SVA, idx["sva_pop"]
        else:
            kind, side, t, push, pop = FIFO_TO_SINK, -1, -1, idx["sva_push"], idx["sink_pop"]
        fifos[i] = (kind, side, t, f.depth, f.data_edges, f.space_edges,
                    doms[f.src].period_fs, doms[f.dst].period_fs, push, pop, f.width_bits,
                    1 if f.crossing else 0, plan.frames * f.beats)
    return fifos


def _blocks(plan: ChipPlan, names: dict, fifo_index: dict) -> np.ndarray:
    """The :data:`BLOCK` records, in plan order."""
    blocks = np.zeros(len(plan.blocks), BLOCK)
    for i, b in enumerate(plan.blocks):
        t = plan.tiles.index(b.tile) if b.kind == "nna" and plan.parts > 1 else (
            0 if b.kind == "nna" else -1)
        blocks[i] = (KIND_CODES[b.kind], -1 if b.side is None else b.side, t,
                     plan.domains[b.domain].period_fs,
                     names["source_push"][b.side] if b.kind in ("memory", "camera") else -1,
                     fifo_index[b.inputs[0]] if b.inputs else -1,
                     fifo_index[b.inputs[1]] if len(b.inputs) > 1 and b.kind == "sva" else -1,
                     fifo_index[b.outputs[0]] if b.outputs else -1)
    return blocks


def _constants(plan: ChipPlan, sides: int, cap_fs: int, stats: bool) -> np.ndarray:
    """The :data:`CONSTANTS` record of the run."""
    cfg, doms = plan.cfg, plan.domains
    h, w = plan.shape
    prm = np.zeros(1, CONSTANTS)
    p = prm[0]
    p["h"], p["w"], p["n"], p["parts"] = h, w, h * w, plan.parts
    p["sides"] = sides
    p["merge"] = 1 if plan.parts > 1 else 0
    p["camera"] = 1 if plan.camera_direct else 0
    src = plan.blocks_of("camera" if plan.camera_direct else "memory")[0]
    p["line_clocks"] = src.line_clocks
    p["frame_clocks"] = src.frame_clocks
    p["frames"] = plan.frames
    p["pairs"] = plan.pairs
    p["mem_hz"] = round(doms[plan.source_domain].freq_hz)
    p["mem_bps"] = src.bytes_per_s
    sub = plan.blocks_of("nna")[0]
    p["half"], p["rows"], p["nna_ii"] = sub.half, sub.rows, sub.ii
    sva = plan.block("sva")
    p["lookahead"], p["pipe_latency"], p["sva_ii"] = sva.lookahead, sva.latency, sva.ii
    p["passes"], p["skew"], p["slot_ii"] = sva.passes, sva.skew, sva.slot_ii
    p["flush_ii"] = sva.flush_ii
    p["first_row"] = sva.first_row
    p["latency"] = cfg.fifo.latency_cycles
    p["per_src"] = doms[plan.source_domain].period_fs
    p["per_nna"], p["per_sva"] = doms["nna"].period_fs, doms["sva"].period_fs
    p["p_max"] = plan.p_max_fs
    p["cap_fs"] = cap_fs
    p["watchdog_fs"] = plan.watchdog_fs
    p["stats"] = 1 if stats else 0
    p["n_stages"] = len(sva.stages)
    d = plan.dram
    if d is not None:
        p["dram"], p["d_slot"], p["d_round"], p["d_lat"] = 1, d.slot_fs, d.round_slots, \
            d.latency_fs
        p["d_rfirst"] = d.reads.first if d.reads is not None else -1
        p["d_wfirst"], p["d_wcount"] = d.write_back.first, d.write_back.count
        p["d_rpx"], p["d_pref"] = d.read_pixels, d.prefetch
        p["d_wwords"], p["d_wbuf"] = d.write_words, d.write_buffer
        p["mem_bps"] = p["mem_hz"]  # the channel, not the token bucket, paces the reads
    if plan.frame_buffered:
        cam = plan.block("camera_left")
        p["fb"] = cfg.source.frame_buffers
        p["fb_drop"] = 1 if cfg.source.on_overflow == "drop_frame" else 0
        p["cam_line"], p["cam_frame"] = cam.line_clocks, cam.frame_clocks
        p["per_cam"] = doms["camera"].period_fs
    return prm


def _windows(plan: ChipPlan, layers: np.ndarray, idx, sides: int) -> np.ndarray:
    """The :data:`WINDOW` walks: the tiles computed (side-major), per layer (and a hybrid's
    census rows: layer 0's input, the last layer's output), then the SVA's."""
    w = plan.shape[1]
    n_layers = len(plan.blocks_of("nna")[0].layers)
    n = sides * plan.parts * n_layers
    rows = []
    k = 0  # the layer records walked so far
    for block, name, _, _, slot, out_slot, offset, in_rows, out_rows in tracked(plan):
        if block == "sva":
            rows.append((slot, out_slot, idx["sva_pop"], w, idx["sva_issue"], w, offset,
                         in_rows, out_rows, 0, 0, 0, -1))
        elif name == "nna.census_rows":  # the tile's layer 0 in, its last layer out
            if k > n:
                continue  # a mirrored right side: its walks are the left side's
            first, last = layers[k - n_layers], layers[k - 1]
            rows.append((slot, out_slot, first["in_stream"], first["iw"], last["out_stream"],
                         last["ow"], offset, in_rows, out_rows, 0, 0, 0, -1))
        elif k >= n:
            k += 1  # a mirrored right side: its walks are the left side's
        else:  # a layer of an NNA tile: the items entering its line buffer, its outputs
            lr = layers[k]
            rows.append((slot, out_slot, lr["in_stream"], lr["iw"], lr["out_stream"], lr["ow"],
                         offset, in_rows, out_rows, 0, 0, 0, -1))
            k += 1
    return np.array(rows, WINDOW)


def serialise(plan: ChipPlan, *, sink_stall=None, cap_fs: int = INF, stats: bool = True,
              capacity: int | None = None, gap_capacity: int = 64) -> tuple[Net, dict]:
    """The :class:`Net` of ``plan`` and the names behind its indices."""
    h, w = plan.shape
    nf = plan.frames
    block_index = {b.name: i for i, b in enumerate(plan.blocks)}
    fifo_index = {f.name: i for i, f in enumerate(plan.fifos)}
    cap = capacity or ring_capacity(plan)
    sides = 1 if plan.symmetric else 2
    specs, names, ids = _stream_specs(plan, sides, block_index, fifo_index)
    streams = np.zeros(len(specs), STREAM)
    for i, (kind, side, tile, count, period, blk) in enumerate(specs):
        size = min(cap, _pow2(count + 1))
        streams[i] = (kind, side, tile, count, 0, size - 1, 0, period, blk)
    streams["off"][1:] = np.cumsum(streams["mask"] + 1)[:-1]
    ring = np.zeros(int((streams["mask"] + 1).sum()), np.int64)
    tiles, layers = _tiles(plan, names, block_index, fifo_index)
    state = np.zeros(1, STATE)
    state[0]["target"] = nf * h * w  # fewer once a camera drops frames
    state[0]["d_rslot"], state[0]["d_wslot"] = -1, -1
    acc = np.zeros(len(plan.blocks) + len(plan.fifos), ACC)
    acc["last_pop"] = -1
    acc["over_cycle"] = INF
    acc["prev"] = -1
    acc["last_busy"] = -plan.p_max_fs  # the watchdog counts from one slowest period before 0
    walks = np.zeros(2 * len(plan.fifos), WALK)
    hoff = 0
    for i, f in enumerate(plan.fifos):
        walks[i]["hoff"] = hoff
        hoff += f.depth + 1
    rows = np.full((2, h + 1), -1, np.int64)
    rows[:, 0] = 0
    frame_fs = np.full((3, nf), -1, np.int64)
    if not plan.frame_buffered:
        frame_fs[2] = np.arange(nf)
    sva = plan.block("sva")
    stages = np.zeros(len(sva.stages), STAGE)
    for i, (st, off) in enumerate(zip(sva.stages, stage_offsets(sva.stages))):
        stages[i] = (off, st.latency, st.slots, 0, 0, 0, -1)
    net = Net(
        prm=_constants(plan, sides, cap_fs, stats), state=state, ids=ids,
        streams=streams, ring=ring, tiles=tiles, layers=layers, fifos=_fifos(plan, names, ids[0]),
        blocks=_blocks(plan, names, fifo_index), acc=acc, walks=walks,
        hist=np.zeros(hoff, np.int64),
        gaps=np.zeros((len(plan.blocks), gap_capacity, 2), np.int64), rows=rows,
        occ=np.full((2 * len(layers) + 2, _row_ring(plan, cap)), -1, np.int64),
        scratch=np.zeros(plan.parts, TABLE), cursors=np.zeros(len(specs), np.int64),
        stages=stages, frame_fs=frame_fs, win=_windows(plan, layers, ids[0], sides),
        fbuf=np.full((2, nf), -1, np.int64), sink=sink_pattern(sink_stall))
    return net, dict(names, streams=specs, block_index=block_index, fifo_index=fifo_index)
