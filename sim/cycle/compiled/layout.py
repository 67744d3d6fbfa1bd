"""The chip plan serialised for the compiled engine: named record arrays, no magic columns.

:func:`serialise` turns a :class:`~sim.cycle.plan.ChipPlan` into a :class:`Net`, the one
argument of every kernel: the run's constants (``prm``), one record per event stream
(``streams``: its length, how many events are known, its ring in ``ring``), per camera tile
(``tiles``), per FIFO (``fifos``) and per block (``blocks``), the statistics the kernels
accumulate (``acc``), the watchdog's long gaps (``gaps``) and the row instants (``rows``).

Event streams (the cycle of every beat of a FIFO's producer or consumer, in beat order):

- ``A`` per side: the source pushes pixel k (raster order of the frame, the source's domain);
- ``B`` per tile: its line buffer pops input pixel i (raster order of the tile's input region);
- ``E`` per tile: its MAC array pushes descriptor j (raster order of the tile's output region);
- ``M`` per side, split frames only: the merge moves descriptor m (raster order);
- ``P``: the SVA pops pair j; ``O``: it pushes word j; ``Q``: the sink pops word j;
- ``T``: the SVA's pipeline *tick* at which word j is issued (:mod:`sim.cycle.rules`: advancing
  cycles, not a cycle -- so the replay's cursors skip it);
- ``R``: through the DRAM channel, the first source cycle the stereo pair's read burst r is in
  the chip; ``W``: the first sink cycle write-back burst u has left the write buffer
  (:class:`~sim.cycle.readable.blocks.sources.DramChannel`; empty without the channel).

The SVA's stages (``stages``, in stream order): offset and latency in ticks, the words their
registers hold, and what the walker counts (the most words held, busy and blocked cycles; the
cycle after which the last word has left the stage).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.sim.cycle.buffers import tracked
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sim.cycle.rules import FS_PER_S
from stereosim.sim.cycle.stages import stage_offsets

INF = 1 << 62

# stream kinds
S_A, S_B, S_E, S_M, S_P, S_O, S_Q, S_T, S_R, S_W = range(10)
# FIFO kinds (how its items map onto streams)
F_SRC, F_MERGE, F_TO_SVA, F_SINK = range(4)
# block kinds
K_MEMORY, K_CAMERA, K_NNA, K_MERGE, K_SVA, K_SINK = range(6)
KIND_CODES = {"memory": K_MEMORY, "camera": K_CAMERA, "nna": K_NNA, "merge": K_MERGE,
              "sva": K_SVA, "sink": K_SINK}
# activities, in the order of sim.cycle.contract.ACTIVITIES
A_BUSY, A_STARVED, A_BLOCKED, A_IDLE = range(4)
# run outcome
END_DONE, END_STUCK, END_CAP, END_OVERFLOW, END_WATCHDOG = range(5)
ERR_NONE, ERR_RING, ERR_GAPS = 0, 1, 2

PARAMS = np.dtype([
    ("h", np.int64), ("w", np.int64), ("n", np.int64),  # one frame's rows, columns, pixels
    ("frames", np.int64), ("frame_clocks", np.int64), ("parts", np.int64),
    ("sides", np.int64),  # sides computed: 1 when the right side's events are the left's
    ("merge", np.int64), ("camera", np.int64), ("line_clocks", np.int64),
    ("mem_hz", np.int64), ("mem_bps", np.int64), ("half", np.int64), ("rows", np.int64),
    ("cpd", np.int64), ("lookahead", np.int64), ("pipe_latency", np.int64), ("cpp", np.int64),
    ("latency", np.int64), ("stall_period", np.int64), ("stall_phase", np.int64),
    ("per_src", np.int64), ("per_nna", np.int64), ("per_sva", np.int64), ("p_max", np.int64),
    ("cap_fs", np.int64),  # events at instants >= cap_fs are not computed
    ("watchdog_fs", np.int64), ("stats", np.int64),  # 1: accumulate statistics and gaps
    ("n_stages", np.int64),
    ("target", np.int64),  # words the sink takes to finish
    # a camera writing into frame buffers (fb of them), read by the memory sources
    ("fb", np.int64), ("fb_drop", np.int64), ("cam_line", np.int64), ("cam_frame", np.int64),
    ("per_cam", np.int64),
    ("pairs", np.int64),  # camera pairs sharing the chip frame by frame (sva.pairs)
    ("fb_taken", np.int64),  # frames taken so far
    ("fb_next", np.int64),  # the next camera frame to decide
    ("sva_regular", np.int64),  # SVA words issued II ticks after the previous, without a stall
    ("sva_peaks_full", np.int64),  # 1: every SVA stage has held ceil(latency / II) words
    # the DRAM channel (dram = 1; sim.cycle.plan.DramPlan): slot length, round, the read pair's
    # and the write-back's slots, latency, pixels per read burst, read bursts ahead, words per
    # write burst, write buffer bursts; the last read and write slots taken (-1: none yet)
    ("dram", np.int64), ("d_slot", np.int64), ("d_round", np.int64), ("d_rfirst", np.int64),
    ("d_wfirst", np.int64), ("d_wcount", np.int64), ("d_lat", np.int64), ("d_rpx", np.int64),
    ("d_pref", np.int64), ("d_wwords", np.int64), ("d_wbuf", np.int64), ("d_rslot", np.int64),
    ("d_wslot", np.int64),
    # outcome
    ("end", np.int64), ("error", np.int64), ("horizon_fs", np.int64), ("first_pop", np.int64),
    ("iterations", np.int64),
])

STREAM = np.dtype([
    ("kind", np.int64), ("side", np.int64), ("tile", np.int64), ("n", np.int64),
    ("count", np.int64), ("mask", np.int64), ("off", np.int64), ("period", np.int64),
    ("block", np.int64),
])

TILE = np.dtype([
    ("side", np.int64), ("t", np.int64), ("x0", np.int64), ("x1", np.int64), ("y0", np.int64),
    ("y1", np.int64), ("ix0", np.int64), ("ix1", np.int64), ("iy0", np.int64), ("iy1", np.int64),
    ("iw", np.int64), ("ow", np.int64), ("n_in", np.int64), ("n_out", np.int64),
    ("top_halo", np.int64), ("a", np.int64), ("b", np.int64), ("e", np.int64),
    ("src_fifo", np.int64), ("out_fifo", np.int64), ("block", np.int64),
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

# a row window's walk (sim.cycle.buffers.window_peaks, behind the streams): the slot of its row
# instants in ``occ`` (input rows; output rows at slot + 1), the streams whose counts say how
# many rows are known and their row widths, the window's offset and rows per frame, and the walk
WINDOW = np.dtype([
    ("slot", np.int64), ("in_stream", np.int64), ("in_width", np.int64),
    ("out_stream", np.int64), ("out_width", np.int64), ("offset", np.int64),
    ("in_rows", np.int64), ("out_rows", np.int64),
    ("row", np.int64), ("done", np.int64),  # the next input row; output rows done before it
    ("peak", np.int64), ("at", np.int64),  # the most rows held, and the cycle (-1: none yet)
])

# a FIFO's occupancy walk: consumer timeline (histogram) and producer timeline (crossing)
WALK = np.dtype([
    ("inc", np.int64), ("dec", np.int64), ("cycle", np.int64), ("level", np.int64),
    ("top", np.int64), ("at_depth", np.int64), ("hoff", np.int64),
])


class Net(NamedTuple):
    prm: np.ndarray  # PARAMS, one record
    streams: np.ndarray  # STREAM
    ring: np.ndarray  # int64: every stream's ring
    tiles: np.ndarray  # TILE, side-major
    fifos: np.ndarray  # FIFO, in plan order
    blocks: np.ndarray  # BLOCK, in plan order
    acc: np.ndarray  # ACC: per block (0 .. B-1), then per FIFO (B .. B+F-1)
    walks: np.ndarray  # WALK: per FIFO the consumer walk, then per FIFO the producer walk
    hist: np.ndarray  # int64: the FIFOs' occupancy histograms (WALK.hoff)
    gaps: np.ndarray  # int64 (blocks, capacity, 2): long gaps (start_fs, end_fs) between
    # busy instants, per block; ACC.gaps counts them
    rows: np.ndarray  # int64 (2, H + 1): the first frame's row instants (Chip.row_times)
    occ: np.ndarray  # int64 (2 T + 2, R): a ring of R rows (row r at r % R) of the tracked
    # buffers' row instants over the stream, cycles of
    # their block (sim.cycle.buffers): per tile t [2t] the cycle its line buffer took the first
    # pixel of each input row, [2t + 1] the cycle it pushed the last descriptor of each output
    # row; [2T] the cycle the SVA took the first pair of each input row, [2T + 1] the cycle it
    # issued the last word of each output row (its rows read: the row window's release, which
    # the SVA's pops wait on); -1 where not reached
    scratch: np.ndarray  # int64 (tiles per camera, 14): per-tile tables of a kernel call
    cursors: np.ndarray  # int64 (streams,): events up to an instant (the replay's)
    stages: np.ndarray  # STAGE: the SVA's stages in stream order
    frame_fs: np.ndarray  # int64 (3, frames): per frame of the stream the chip took, the
    # instant (fs) of its first pixel (pushed by the left source, or a camera's) and of its last
    # word popped by the sink, and the input frame it is; -1 where not reached
    win: np.ndarray  # WINDOW: the row windows' walks (sim.cycle.buffers), the tiles computed
    # (side-major) then the SVA's
    fbuf: np.ndarray  # int64 (2, frames): with frame buffers, per camera frame whether it was
    # dropped ([0]: 1) and per frame taken the instant (fs) the reader finished it ([1])


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
    """Events each ring keeps: enough for every reader of a stream (the chip's storage -- line
    buffer and SVA row windows, FIFO depths -- bounds how far one stream runs ahead of another);
    a pass that still reads an overwritten event says so and is rerun with larger rings."""
    cfg = plan.cfg
    h, w = plan.shape
    half = max(b.half for b in plan.blocks_of("nna"))
    la = plan.block("sva").lookahead
    depths = sum(f.depth for f in plan.fifos)
    band = max(t.in_shape[0] for t in plan.tiles) if cfg.nna.split == "rows" else 0
    rows = cfg.nna.line_buffer_rows + half + la + 6 + band
    return min(_pow2(scale * (2 * rows * w + 2 * depths + 4096)), _pow2(plan.frames * h * w + 1))


def serialise(plan: ChipPlan, *, sink_stall=None, cap_fs: int = INF, stats: bool = True,
              capacity: int | None = None, gap_capacity: int = 64) -> tuple[Net, dict]:
    """The :class:`Net` of ``plan`` and the names behind its indices."""
    cfg = plan.cfg
    h, w = plan.shape
    n = h * w
    nf = plan.frames
    doms = plan.domains
    block_index = {b.name: i for i, b in enumerate(plan.blocks)}
    fifo_index = {f.name: i for i, f in enumerate(plan.fifos)}
    cap = capacity or ring_capacity(plan)
    parts = plan.parts
    sides = 1 if plan.symmetric else 2
    # streams (of the left side only when the right side's events are the same)
    specs = []  # (kind, side, tile, n, period, block)
    a_id, b_id, e_id, m_id = {}, {}, {}, {}
    for s in range(sides):
        # the block that pushes the pixels: a camera straight into the NNA, or a memory
        # source (reading frames in memory or a camera's frame buffers)
        kind = "camera" if plan.camera_direct else "memory"
        src = next(b for b in plan.blocks if b.kind == kind and b.side == s)
        a_id[s] = len(specs)
        specs.append((S_A, s, -1, nf * n, doms[src.domain].period_fs, block_index[src.name]))
    nna = [b for b in plan.blocks if b.kind == "nna"]
    for b in nna:
        if b.side >= sides:
            continue
        t = plan.tiles.index(b.tile) if parts > 1 else 0
        tile = b.tile
        b_id[b.side, t] = len(specs)
        specs.append((S_B, b.side, t, nf * tile.in_shape[0] * tile.in_shape[1],
                      doms["nna"].period_fs, block_index[b.name]))
        e_id[b.side, t] = len(specs)
        specs.append((S_E, b.side, t, nf * tile.shape[0] * tile.shape[1], doms["nna"].period_fs,
                      block_index[b.name]))
    if parts > 1:
        for s in range(sides):
            m_id[s] = len(specs)
            specs.append((S_M, s, -1, nf * n, doms["nna"].period_fs,
                          block_index[f"merge_{('left', 'right')[s]}"]))
    if sides == 1:
        a_id[1] = a_id[0]
        m_id.update({1: m_id[0]} if parts > 1 else {})
        for t in range(parts):
            b_id[1, t], e_id[1, t] = b_id[0, t], e_id[0, t]
    p_id = len(specs)
    specs.append((S_P, -1, -1, nf * n, doms["sva"].period_fs, block_index["sva"]))
    specs.append((S_O, -1, -1, nf * n, doms["sva"].period_fs, block_index["sva"]))
    specs.append((S_Q, -1, -1, nf * n, doms["sva"].period_fs, block_index["sink"]))
    specs.append((S_T, -1, -1, nf * n, doms["sva"].period_fs, block_index["sva"]))
    d = plan.dram
    r_bursts = nf * -(-n // d.read_pixels) if d is not None and d.reads is not None else 0
    w_bursts = nf * -(-n // d.write_words) if d is not None else 0
    specs.append((S_R, -1, -1, r_bursts, doms[plan.source_domain].period_fs,
                  block_index["sink" if plan.camera_direct else "memory_left"]))
    specs.append((S_W, -1, -1, w_bursts, doms["sva"].period_fs, block_index["sink"]))
    streams = np.zeros(len(specs), STREAM)
    for i, (kind, side, tile, count, period, blk) in enumerate(specs):
        size = min(cap, _pow2(count + 1))
        streams[i] = (kind, side, tile, count, 0, size - 1, 0, period, blk)
    streams["off"][1:] = np.cumsum(streams["mask"] + 1)[:-1]
    ring = np.zeros(int((streams["mask"] + 1).sum()), np.int64)
    # tiles
    tiles = np.zeros(2 * parts, TILE)
    for b in nna:
        t = plan.tiles.index(b.tile) if parts > 1 else 0
        tl = b.tile
        fi = fifo_index[b.inputs[0]]
        fo = fifo_index[b.outputs[0]]
        tiles[b.side * parts + t] = (
            b.side, t, tl.x0, tl.x1, tl.y0, tl.y1, tl.in_x0, tl.in_x1, tl.in_y0, tl.in_y1,
            tl.in_x1 - tl.in_x0, tl.x1 - tl.x0, tl.in_shape[0] * tl.in_shape[1],
            tl.shape[0] * tl.shape[1], tl.top_halo, a_id[b.side], b_id[b.side, t],
            e_id[b.side, t], fi, fo, block_index[b.name])
    # FIFOs
    fifos = np.zeros(len(plan.fifos), FIFO)
    for i, f in enumerate(plan.fifos):
        prod, cons = plan.block(f.producer), plan.block(f.consumer)
        if cons.kind == "nna":
            t = plan.tiles.index(cons.tile) if parts > 1 else 0
            kind, side, push, pop = F_SRC, cons.side, a_id[cons.side], b_id[cons.side, t]
        elif cons.kind == "merge":
            t = plan.tiles.index(prod.tile)
            kind, side, push, pop = F_MERGE, cons.side, e_id[prod.side, t], m_id[prod.side]
        elif cons.kind == "sva":
            t = -1
            side = prod.side
            push = m_id[side] if parts > 1 else e_id[side, 0]
            kind, pop = F_TO_SVA, p_id
        else:
            kind, side, t, push, pop = F_SINK, -1, -1, p_id + 1, p_id + 2
        fifos[i] = (kind, side, t, f.depth, f.data_edges, f.space_edges,
                    doms[f.src].period_fs, doms[f.dst].period_fs, push, pop, f.width_bits,
                    1 if f.crossing else 0, nf * f.beats)
    blocks = np.zeros(len(plan.blocks), BLOCK)
    for i, b in enumerate(plan.blocks):
        t = plan.tiles.index(b.tile) if b.kind == "nna" and parts > 1 else (
            0 if b.kind == "nna" else -1)
        blocks[i] = (KIND_CODES[b.kind], -1 if b.side is None else b.side, t,
                     doms[b.domain].period_fs,
                     a_id[b.side] if b.kind in ("memory", "camera") else -1,
                     fifo_index[b.inputs[0]] if b.inputs else -1,
                     fifo_index[b.inputs[1]] if len(b.inputs) > 1 and b.kind == "sva" else -1,
                     fifo_index[b.outputs[0]] if b.outputs else -1)
    prm = np.zeros(1, PARAMS)
    p = prm[0]
    p["h"], p["w"], p["n"], p["parts"] = h, w, n, parts
    p["sides"] = sides
    p["merge"] = 1 if parts > 1 else 0
    p["camera"] = 1 if plan.camera_direct else 0
    src = plan.blocks_of("camera" if plan.camera_direct else "memory")[0]
    p["line_clocks"] = src.line_clocks
    p["frame_clocks"] = src.frame_clocks
    p["frames"] = nf
    p["pairs"] = plan.pairs
    p["mem_hz"] = round(doms[plan.source_domain].freq_hz)
    p["mem_bps"] = src.bytes_per_s
    sub = plan.blocks_of("nna")[0]
    p["half"], p["rows"], p["cpd"] = sub.half, sub.rows, sub.cycles
    sva = plan.block("sva")
    p["lookahead"], p["pipe_latency"], p["cpp"] = sva.lookahead, sva.latency, sva.cycles
    p["latency"] = cfg.fifo.latency_cycles
    period, phase = (0, 0) if sink_stall is None else sink_stall
    p["stall_period"], p["stall_phase"] = period, phase
    p["per_src"] = doms[plan.source_domain].period_fs
    p["per_nna"], p["per_sva"] = doms["nna"].period_fs, doms["sva"].period_fs
    p["p_max"] = plan.p_max_fs
    p["cap_fs"] = cap_fs
    p["watchdog_fs"] = plan.watchdog_fs
    p["stats"] = 1 if stats else 0
    p["n_stages"] = len(sva.stages)
    p["target"] = nf * n  # words the sink takes to finish (fewer once a camera drops frames)
    p["d_rslot"], p["d_wslot"] = -1, -1
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
    hist = np.zeros(hoff, np.int64)
    gaps = np.zeros((len(plan.blocks), gap_capacity, 2), np.int64)
    rows = np.full((2, h + 1), -1, np.int64)
    rows[:, 0] = 0
    occ = np.full((2 * len(tiles) + 2, _row_ring(plan, cap)), -1, np.int64)
    frame_fs = np.full((3, nf), -1, np.int64)
    if not plan.frame_buffered:
        frame_fs[2] = np.arange(nf)
    fbuf = np.full((2, nf), -1, np.int64)
    win = np.zeros(sides * parts + 1, WINDOW)
    for i, (block, _, _, _, slot, offset, in_rows, out_rows) in enumerate(tracked(plan)):
        if i < sides * parts:  # an NNA tile: its pops and pushes
            tl = tiles[i]
            win[i] = (slot, tl["b"], tl["iw"], tl["e"], tl["ow"], offset, in_rows, out_rows,
                      0, 0, 0, -1)
        elif block == "sva":
            win[-1] = (slot, p_id, w, p_id + 3, w, offset, in_rows, out_rows, 0, 0, 0, -1)
    names = {"streams": specs, "a": a_id, "b": b_id, "e": e_id, "m": m_id, "p": p_id,
             "r": p_id + 4, "w": p_id + 5,
             "block_index": block_index, "fifo_index": fifo_index}
    scratch = np.zeros((parts, 14), np.int64)
    cursors = np.zeros(len(specs), np.int64)
    stages = np.zeros(len(sva.stages), STAGE)
    for i, (st, off) in enumerate(zip(sva.stages, stage_offsets(sva.stages))):
        stages[i] = (off, st.latency, st.slots, 0, 0, 0, -1)
    return Net(prm, streams, ring, tiles, fifos, blocks, acc, walks, hist, gaps, rows, occ,
               scratch, cursors, stages, frame_fs, win, fbuf), names


def seconds(fs: int) -> float:
    return fs / FS_PER_S
