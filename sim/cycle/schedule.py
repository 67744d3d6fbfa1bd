"""The schedule engine: the cycle of every beat of a frame from closed-form recurrences.

The chip of :mod:`sim.cycle.chip` is a pipeline whose timing does not depend on the data: when a beat
moves is decided by counters, FIFO occupancies and clocks, never by a pixel value. So instead
of stepping clock edges, this engine computes for every beat ``k`` of the raster the cycle of
each event directly, as the readable kernel's rules
(:mod:`sim.cycle.clock`, :mod:`sim.cycle.fifo` and the blocks' ``evaluate``) imply:

============  ==========================================================================
``a[k]``      the source pushes pixel k (memory: ``max(a[k-1] + 1, throttle(k), free(k))``;
              camera: fixed by the raster, an overflow if no slot is free then)
``b[k]``      the line buffer pops it: ``max(b[k-1] + 1, visible(a[k]), room(row of k))``
``e[j]``      the MAC array pushes descriptor j: started at ``s = max(e[j-1] + 1,
              rows_in(row of j))``, pushed at ``max(s + cpd - 1, free(j))``
``p[j]``      the SVA pops pair j: ``max(p[j-1] + 1, visible(eL[j]), visible(eR[j]),
              row window(row of j))``
``o[j]``      the SVA pushes word j: ``max(ready(row of j) + latency, o[j-1] + cpp,
              free(j))``
``q[j]``      the sink pops it: the first allowed cycle ``>= max(q[j-1] + 1, visible(o[j]))``
============  ==========================================================================

with a FIFO's rules: an item pushed in producer cycle c is visible from consumer cycle
``(c P) // Q + data_edges`` (periods P, Q in fs, all clocks start at 0), a slot freed in consumer
cycle c is seen by the producer from cycle ``(c Q) // P + space_edges``; in one domain that is
``c + latency`` and ``c + 1``. Each event depends only on earlier events of its own stream and
on events of other streams that precede it in time, so the streams are advanced in turn, each
as far as what it depends on is known (:func:`_advance`), until the sink has the frame. A frame
split over several submodules per camera adds the joint source push, the tiles and the merge
(:func:`_advance_split`, section "frames split over several submodules").

The statistics the readable kernel accumulates edge by edge follow from the event cycles:
every block's busy / starved / blocked / idle count (:func:`_mac_activity`,
:func:`_sva_activity` and counts kept on the way), every FIFO's
occupancy histogram over its consumer's edges, its empty and full counts and its largest
occupancies (:func:`_level_walk`). The result is the same report and the same statistics, to
the cycle, as :func:`sim.cycle.chip.run_cycle`; tests/sim/test_schedule.py holds the three engines
equal.

The engine answers only for runs that complete: it reports ``None`` (and the caller runs the
step engine of :mod:`sim.cycle.fast`, or for split frames the readable kernel, which stops where the
run stops and says why) when
a camera would overflow, when the streams wait on each other (a deadlock), when a domain would
exceed its cycle budget, or when the watchdog could fire -- it checks that the FIFO events of
three streams leave no gap of half the watchdog's time without one, which a completing run at
the default watchdog always meets.

Data: the engine computes no data path of its own. The output words are those of the
functional kernels (:func:`nna.descriptor.compute_descriptor`, :func:`sva.pipeline.sva_stream`)
applied to the frames -- the beats leave every block in raster order and the chip's arithmetic
does not depend on when they move, so these are the words the cycle-by-cycle engines assemble
beat by beat (tested equal).
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit

from nna.descriptor import compute_descriptor, descriptor_bits
from nna.geometry import cycles_per_descriptor, half_window, split_frame
from sim.cycle.architecture import nna_to_sva_word_bits, output_word_bits
from sim.cycle.clock import count_instants
from sim.cycle.report import assemble_report, chip_domains, frame_budget
from sva.pipeline import sva_stream

INF = 1 << 62
NEVER = -(1 << 40)  # the SVA's "last push" before the first one (SvaBlock.last_push)

# ---- parameter vector (int64) --------------------------------------------------------------
(P_H, P_W, P_CAMERA, P_LINE_CLOCKS, P_MEM_HZ, P_MEM_BPS, P_HALF, P_ROWS, P_CPD, P_LA,
 P_PIPE_LAT, P_CPP, P_D_SRC, P_D_NS, P_D_SK, P_DE_SRC, P_SE_SRC, P_DE_NS, P_SE_NS, P_LATENCY,
 P_PER_SRC, P_PER_N, P_PER_S, P_STALL_PERIOD, P_STALL_PHASE, P_LIMIT_SRC, P_LIMIT_N, P_LIMIT_S,
 P_WATCHDOG) = range(29)
N_P = 29

# ---- event-time rows of the (N_T, H * W) array ---------------------------------------------
# per camera side s: T_A + 4 s (source push), T_B + 4 s (line-buffer pop), T_E + 4 s (MAC push,
# nna cycles), T_VE + 4 s (the SVA cycle from which that descriptor is visible)
T_A, T_B, T_E, T_VE = 0, 1, 2, 3
T_P, T_FP, T_O, T_Q = 8, 9, 10, 11  # SVA pop, the nna cycle its free slot is seen, push, sink pop
N_T = 12

# ---- counters and accumulators (int64) ------------------------------------------------------
# C_B + s / C_E + s: pixels popped / descriptors pushed so far on side s; C_P, C_O: SVA pairs
# popped, words pushed (and popped by the sink); the rest accumulate statistics on the way
(C_B, C_B1, C_E, C_E1, C_P, C_O, C_SRC_BLOCKED, C_SRC_BLOCKED1, C_EMPTY_SRC, C_EMPTY_SRC1,
 C_EMPTY_NS, C_EMPTY_NS1, C_EMPTY_SK, C_STOP, C_STOP_AT) = range(15)
N_C = 15
STOP_NONE, STOP_OVERFLOW, STOP_DEADLOCK, STOP_BUDGET = 0, 1, 2, 3


@njit(cache=True, inline="always")
def _cross(c, per_from, per_to, edges):
    """The cycle of the other domain from which an event of cycle c counts there: the first
    edge strictly after instant ``c * per_from`` plus ``edges - 1`` (one domain: c + edges)."""
    if per_from == per_to:
        return c + edges
    return (c * per_from) // per_to + edges


@njit(cache=True, inline="always")
def _next_in_raster(x, y, w):
    """The raster position (x, y) after (x, y) in rows of w pixels."""
    x += 1
    if x == w:
        return 0, y + 1
    return x, y


@njit(cache=True, inline="always")
def _source_push(prm, k, y, x, a_prev, free):
    """(cycle, cycles blocked before it) of the source's push of pixel k = (x, y), the previous
    push in ``a_prev``, a slot seen free from cycle ``free``; cycle -1: a camera that overflows
    (it cannot wait). A memory source waits for its token bucket (busy) and the slot
    (blocked)."""
    if prm[P_CAMERA] == 1:
        a = y * prm[P_LINE_CLOCKS] + x
        return (-1 if free > a else a), 0
    lo = a_prev + 1
    hz, bps = prm[P_MEM_HZ], prm[P_MEM_BPS]
    if bps < hz:
        lo = max(lo, ((k + 1) * hz + bps - 1) // bps - 1)
    a = max(lo, free)
    return a, a - lo


# ---- the recurrences -----------------------------------------------------------------------


@njit(cache=True)
def _src_and_pops(side, prm, t, cnt):
    """Source pushes and line-buffer pops of camera ``side``, as far as the MAC array's
    progress (the line buffer's room) allows. True if it advanced."""
    h, w = prm[P_H], prm[P_W]
    n = h * w
    k = cnt[C_B + side]
    if k >= n:
        return False
    a_t, b_t, e_t = t[T_A + 4 * side], t[T_B + 4 * side], t[T_E + 4 * side]
    ke = cnt[C_E + side]
    rows, half = prm[P_ROWS], prm[P_HALF]
    depth, de, se = prm[P_D_SRC], prm[P_DE_SRC], prm[P_SE_SRC]
    per_src, per_n = prm[P_PER_SRC], prm[P_PER_N]
    y = k // w
    x = k - y * w
    a_prev = a_t[k - 1] if k > 0 else -1
    b_prev = b_t[k - 1] if k > 0 else -1
    start = k
    room = 0
    room_row = -1
    blocked = 0
    empty = 0
    while k < n:
        if y != room_row:
            # NnaSubmodule._room_for_input: row y fits beside the rows output row y_out still
            # needs once y_out >= y + 1 - rows + half, i.e. after the push of the last
            # descriptor of the row before that
            if y >= rows:
                need = (y + 1 - rows + half) * w
                if ke < need:
                    break
                room = e_t[need - 1] + 1
            else:
                room = 0
            room_row = y
        free = 0
        if k >= depth:
            free = _cross(b_t[k - depth], per_n, per_src, se)
        a, waited = _source_push(prm, k, y, x, a_prev, free)
        if a < 0:
            cnt[C_STOP] = STOP_OVERFLOW
            cnt[C_STOP_AT] = k
            break
        blocked += waited
        vis = _cross(a, per_src, per_n, de)
        b = max(b_prev + 1, vis, room)
        empty += max(0, vis - b_prev - 1)
        a_t[k] = a
        b_t[k] = b
        a_prev = a
        b_prev = b
        k += 1
        x, y = _next_in_raster(x, y, w)
    cnt[C_B + side] = k
    cnt[C_SRC_BLOCKED + side] += blocked
    cnt[C_EMPTY_SRC + side] += empty
    return k > start


@njit(cache=True)
def _mac_pushes(side, prm, t, cnt):
    """Descriptor pushes of camera ``side``'s MAC array, as far as its input rows and the SVA's
    pops (free slots) allow. True if it advanced."""
    h, w = prm[P_H], prm[P_W]
    n = h * w
    j = cnt[C_E + side]
    if j >= n:
        return False
    b_t, e_t, ve_t, fp_t = t[T_B + 4 * side], t[T_E + 4 * side], t[T_VE + 4 * side], t[T_FP]
    kb = cnt[C_B + side]
    kp = cnt[C_P]
    half, cpd = prm[P_HALF], prm[P_CPD]
    depth, de = prm[P_D_NS], prm[P_DE_NS]
    per_n, per_s = prm[P_PER_N], prm[P_PER_S]
    y = j // w
    x = j - y * w
    e_prev = e_t[j - 1] if j > 0 else -1
    start = j
    rows_in = 0
    rows_row = -1
    while j < n:
        if y != rows_row:
            # NnaSubmodule._row_ready: input rows up to min(y + half, H - 1) are in
            need = min(y + half + 1, h) * w
            if kb < need:
                break
            rows_in = b_t[need - 1] + 1
            rows_row = y
        free = 0
        if j >= depth:
            if kp <= j - depth:
                break
            free = fp_t[j - depth]
        s = max(e_prev + 1, rows_in)
        e = max(s + cpd - 1, free)
        e_t[j] = e
        ve_t[j] = _cross(e, per_n, per_s, de)
        e_prev = e
        j += 1
        x, y = _next_in_raster(x, y, w)
    cnt[C_E + side] = j
    return j > start


@njit(cache=True)
def _sva_pops(prm, t, cnt):
    """The SVA's joint pops, as far as both descriptor streams and its row window allow."""
    h, w = prm[P_H], prm[P_W]
    n = h * w
    j = cnt[C_P]
    if j >= n:
        return False
    vl_t, vr_t, p_t, fp_t, o_t = t[T_VE], t[T_VE + 4], t[T_P], t[T_FP], t[T_O]
    k_ready = min(cnt[C_E], cnt[C_E1])
    ko = cnt[C_O]
    la = prm[P_LA]
    se = prm[P_SE_NS]
    per_n, per_s = prm[P_PER_N], prm[P_PER_S]
    y = j // w
    x = j - y * w
    p_prev = p_t[j - 1] if j > 0 else -1
    start = j
    window = 0
    window_row = -1
    empty_l = 0
    empty_r = 0
    while j < k_ready:
        if y != window_row:
            # SvaBlock: input row y is taken while y <= y_out + la + 1
            if y > la + 1:
                need = (y - la - 1) * w
                if ko < need:
                    break
                window = o_t[need - 1] + 1
            else:
                window = 0
            window_row = y
        vl = vl_t[j]
        vr = vr_t[j]
        p = max(p_prev + 1, vl, vr, window)
        empty_l += max(0, vl - p_prev - 1)
        empty_r += max(0, vr - p_prev - 1)
        p_t[j] = p
        fp_t[j] = _cross(p, per_s, per_n, se)
        p_prev = p
        j += 1
        x, y = _next_in_raster(x, y, w)
    cnt[C_P] = j
    cnt[C_EMPTY_NS] += empty_l
    cnt[C_EMPTY_NS1] += empty_r
    return j > start


@njit(cache=True)
def _sva_pushes_and_sink(prm, t, cnt):
    """The SVA's word pushes and the sink's pops, as far as the SVA's ready rows allow."""
    h, w = prm[P_H], prm[P_W]
    n = h * w
    j = cnt[C_O]
    if j >= n:
        return False
    p_t, o_t, q_t = t[T_P], t[T_O], t[T_Q]
    kp = cnt[C_P]
    la, lat, cpp = prm[P_LA], prm[P_PIPE_LAT], prm[P_CPP]
    depth, latency = prm[P_D_SK], prm[P_LATENCY]
    period, phase = prm[P_STALL_PERIOD], prm[P_STALL_PHASE]
    limit = prm[P_LIMIT_S]
    y = j // w
    x = j - y * w
    o_prev = o_t[j - 1] if j > 0 else NEVER
    q_prev = q_t[j - 1] if j > 0 else -1
    start = j
    ready = 0
    ready_row = -1
    empty = 0
    while j < n:
        if y != ready_row:
            # SvaBlock: output row y is ready the cycle after input row min(y + la, H - 1)
            need = min(y + la + 1, h) * w
            if kp < need:
                break
            ready = p_t[need - 1] + 1
            ready_row = y
        free = q_t[j - depth] + 1 if j >= depth else 0
        o = max(ready + lat, o_prev + cpp, free)
        vis = o + latency
        q = max(q_prev + 1, vis)
        if period > 0:
            q += (phase - q) % period  # the sink's next allowed cycle
        if q >= limit:
            cnt[C_STOP] = STOP_BUDGET
            break
        empty += max(0, vis - q_prev - 1)
        o_t[j] = o
        q_t[j] = q
        o_prev = o
        q_prev = q
        j += 1
        x, y = _next_in_raster(x, y, w)
    cnt[C_O] = j
    cnt[C_EMPTY_SK] += empty
    return j > start


@njit(cache=True)
def _advance(prm, t, cnt):
    """Advance every stream in turn until the sink has the frame or nothing can move."""
    n = prm[P_H] * prm[P_W]
    while cnt[C_O] < n:
        moved = False
        for side in range(2):
            moved |= _src_and_pops(side, prm, t, cnt)
            if cnt[C_STOP] != STOP_NONE:
                return
        for side in range(2):
            moved |= _mac_pushes(side, prm, t, cnt)
        moved |= _sva_pops(prm, t, cnt)
        moved |= _sva_pushes_and_sink(prm, t, cnt)
        if cnt[C_STOP] != STOP_NONE:
            return
        if not moved:
            cnt[C_STOP] = STOP_DEADLOCK
            return


# ---- frames split over several submodules per camera -----------------------------------------
#
# With k > 1 submodules per camera (column tiles or row bands, :func:`nna.geometry.split_frame`)
# the source pushes each pixel to every tile whose input region holds it, in one joint push;
# each tile's line buffer and MAC array follow the rules above within its regions; a merge
# block per camera moves the descriptors back into raster order (pop from the owner tile's
# FIFO and push to the SVA's in one cycle). The rows T_E + 4 s and T_VE + 4 s then hold the
# merge's pushes and their SVA visibility, and counter C_E + s its progress, so the SVA's
# streams are those of the whole-frame chip. Per-tile pops and pushes live in ``tt`` at
# ``off[s, t, 0]`` (input region) and ``off[s, t, 1]`` (output region). ``cnt2[s]`` counts the
# source pushes (X_A), then per tile t its pops (1 + 2 t) and pushes (2 + 2 t); ``st2[s]`` holds
# the merge's starved and blocked cycles (0, 1), then per tile t the empty counts of its source
# FIFO (2 + 2 t) and of its merge FIFO (3 + 2 t).
G_X0, G_X1, G_Y0, G_Y1, G_IX0, G_IX1, G_IY0, G_IY1 = range(8)
X_A = 0


@njit(cache=True)
def _joint_pushes(side, prm, geom, t, tt, off, cnt, cnt2):
    """Source pushes of camera ``side`` to every tile that takes the pixel (a joint push waits
    until each target sees a free slot). True if it advanced."""
    h, w = prm[P_H], prm[P_W]
    n = h * w
    k = cnt2[side, X_A]
    if k >= n:
        return False
    a_t = t[T_A + 4 * side]
    n_tiles = geom.shape[0]
    depth, se = prm[P_D_SRC], prm[P_SE_SRC]
    per_src, per_n = prm[P_PER_SRC], prm[P_PER_N]
    y = k // w
    x = k - y * w
    a_prev = a_t[k - 1] if k > 0 else -1
    start = k
    blocked = 0
    while k < n:
        free = 0
        ok = True
        for tile in range(n_tiles):
            g = geom[tile]
            if g[G_IX0] <= x < g[G_IX1] and g[G_IY0] <= y < g[G_IY1]:
                i = (y - g[G_IY0]) * (g[G_IX1] - g[G_IX0]) + x - g[G_IX0]
                if i >= depth:
                    if cnt2[side, 1 + 2 * tile] <= i - depth:
                        ok = False
                        break
                    free = max(free, _cross(tt[off[side, tile, 0] + i - depth], per_n,
                                            per_src, se))
        if not ok:
            break
        a, waited = _source_push(prm, k, y, x, a_prev, free)
        if a < 0:
            cnt[C_STOP] = STOP_OVERFLOW
            cnt[C_STOP_AT] = k
            break
        blocked += waited
        a_t[k] = a
        a_prev = a
        k += 1
        x, y = _next_in_raster(x, y, w)
    cnt2[side, X_A] = k
    cnt[C_SRC_BLOCKED + side] += blocked
    return k > start


@njit(cache=True)
def _tile_pops(side, tile, prm, geom, t, tt, off, cnt2, st2):
    """Line-buffer pops of one tile, as far as the source and its MAC array allow."""
    w = prm[P_W]
    g = geom[tile]
    iw = g[G_IX1] - g[G_IX0]
    n_in = (g[G_IY1] - g[G_IY0]) * iw
    i = cnt2[side, 1 + 2 * tile]
    if i >= n_in:
        return False
    ow, oh = g[G_X1] - g[G_X0], g[G_Y1] - g[G_Y0]
    top_halo = g[G_Y0] - g[G_IY0]
    a_t = t[T_A + 4 * side]
    b0, e0 = off[side, tile, 0], off[side, tile, 1]
    k_a = cnt2[side, X_A]
    k_e = cnt2[side, 2 + 2 * tile]
    rows, half = prm[P_ROWS], prm[P_HALF]
    de = prm[P_DE_SRC]
    per_src, per_n = prm[P_PER_SRC], prm[P_PER_N]
    r = i // iw
    c = i - r * iw
    b_prev = tt[b0 + i - 1] if i > 0 else -1
    start = i
    room = 0
    room_row = -1
    empty = 0
    while i < n_in:
        if r != room_row:
            # NnaSubmodule._room_for_input in tile rows: input row r fits once output row
            # r + 1 - rows + half - top_halo (at most the last) has started
            need = 0
            if r + 1 > rows:
                need = min(r + 1 - rows + half - top_halo, oh) * ow
            if need > 0:
                if k_e < need:
                    break
                room = tt[e0 + need - 1] + 1
            else:
                room = 0
            room_row = r
        k = (g[G_IY0] + r) * w + g[G_IX0] + c
        if k_a <= k:
            break
        vis = _cross(a_t[k], per_src, per_n, de)
        b = max(b_prev + 1, vis, room)
        empty += max(0, vis - b_prev - 1)
        tt[b0 + i] = b
        b_prev = b
        i += 1
        c, r = _next_in_raster(c, r, iw)
    cnt2[side, 1 + 2 * tile] = i
    st2[side, 2 + 2 * tile] += empty
    return i > start


@njit(cache=True)
def _tile_pushes(side, tile, prm, geom, t, tt, off, cnt, cnt2):
    """Descriptor pushes of one tile's MAC array into its merge FIFO."""
    h, w = prm[P_H], prm[P_W]
    g = geom[tile]
    ow, oh = g[G_X1] - g[G_X0], g[G_Y1] - g[G_Y0]
    iw = g[G_IX1] - g[G_IX0]
    n_out = oh * ow
    j = cnt2[side, 2 + 2 * tile]
    if j >= n_out:
        return False
    mg_t = t[T_E + 4 * side]
    b0, e0 = off[side, tile, 0], off[side, tile, 1]
    k_b = cnt2[side, 1 + 2 * tile]
    k_m = cnt[C_E + side]
    half, cpd, depth = prm[P_HALF], prm[P_CPD], prm[P_D_NS]
    r = j // ow
    c = j - r * ow
    e_prev = tt[e0 + j - 1] if j > 0 else -1
    start = j
    rows_in = 0
    rows_row = -1
    while j < n_out:
        if r != rows_row:
            # input rows up to min(y + half, H - 1) are in (image row y = y0 + r)
            need = (min(g[G_Y0] + r + half, h - 1) - g[G_IY0] + 1) * iw
            if k_b < need:
                break
            rows_in = tt[b0 + need - 1] + 1
            rows_row = r
        free = 0
        if j >= depth:
            jj = j - depth
            rr = jj // ow
            m = (g[G_Y0] + rr) * w + g[G_X0] + jj - rr * ow  # its raster index
            if k_m <= m:
                break
            free = mg_t[m] + 1
        s = max(e_prev + 1, rows_in)
        e = max(s + cpd - 1, free)
        tt[e0 + j] = e
        e_prev = e
        j += 1
        c, r = _next_in_raster(c, r, ow)
    cnt2[side, 2 + 2 * tile] = j
    return j > start


@njit(cache=True)
def _merge_moves(side, prm, geom, t, tt, off, cnt, cnt2, st2, last_pop):
    """The merge of camera ``side``: descriptor m (raster order) moves from its owner tile's
    FIFO to the SVA's in one cycle, once visible there and with a free slot."""
    h, w = prm[P_H], prm[P_W]
    n = h * w
    m = cnt[C_E + side]
    if m >= n:
        return False
    mg_t, ve_t, fp_t = t[T_E + 4 * side], t[T_VE + 4 * side], t[T_FP]
    n_tiles = geom.shape[0]
    kp = cnt[C_P]
    lat, depth = prm[P_LATENCY], prm[P_D_NS]
    de = prm[P_DE_NS]
    per_n, per_s = prm[P_PER_N], prm[P_PER_S]
    y = m // w
    x = m - y * w
    mg_prev = mg_t[m - 1] if m > 0 else -1
    start = m
    starved = 0
    blocked = 0
    while m < n:
        owner = 0
        for tile in range(n_tiles):
            g = geom[tile]
            if g[G_X0] <= x < g[G_X1] and g[G_Y0] <= y < g[G_Y1]:
                owner = tile
                break
        g = geom[owner]
        ow = g[G_X1] - g[G_X0]
        j = (y - g[G_Y0]) * ow + x - g[G_X0]
        if cnt2[side, 2 + 2 * owner] <= j:
            break
        free = 0
        if m >= depth:
            if kp <= m - depth:
                break
            free = fp_t[m - depth]
        vis = tt[off[side, owner, 1] + j] + lat
        mg = max(mg_prev + 1, vis, free)
        starved += max(0, vis - mg_prev - 1)
        blocked += mg - max(vis, mg_prev + 1)
        # the owner's merge FIFO: consumer cycles since its last pop without a visible head
        st2[side, 3 + 2 * owner] += max(0, vis - last_pop[side, owner] - 1)
        last_pop[side, owner] = mg
        mg_t[m] = mg
        ve_t[m] = _cross(mg, per_n, per_s, de)
        mg_prev = mg
        m += 1
        x, y = _next_in_raster(x, y, w)
    cnt[C_E + side] = m
    st2[side, 0] += starved
    st2[side, 1] += blocked
    return m > start


@njit(cache=True)
def _advance_split(prm, geom, t, tt, off, cnt, cnt2, st2, last_pop):
    """:func:`_advance` for split frames: sources, tiles and merges, then the SVA's streams."""
    n = prm[P_H] * prm[P_W]
    n_tiles = geom.shape[0]
    while cnt[C_O] < n:
        moved = False
        for side in range(2):
            moved |= _joint_pushes(side, prm, geom, t, tt, off, cnt, cnt2)
            if cnt[C_STOP] != STOP_NONE:
                return
            for tile in range(n_tiles):
                moved |= _tile_pops(side, tile, prm, geom, t, tt, off, cnt2, st2)
            for tile in range(n_tiles):
                moved |= _tile_pushes(side, tile, prm, geom, t, tt, off, cnt, cnt2)
            moved |= _merge_moves(side, prm, geom, t, tt, off, cnt, cnt2, st2, last_pop)
        moved |= _sva_pops(prm, t, cnt)
        moved |= _sva_pushes_and_sink(prm, t, cnt)
        if cnt[C_STOP] != STOP_NONE:
            return
        if not moved:
            cnt[C_STOP] = STOP_DEADLOCK
            return


# ---- statistics ----------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _first_at_or_after(arr, lo, i):
    """The first index >= i of the increasing ``arr`` with ``arr[index] >= lo`` (galloping from
    i, then bisecting: cheap when the answer is near i)."""
    n = arr.shape[0]
    if i >= n or arr[i] >= lo:
        return i
    step = 1
    hi = i + 1
    while hi < n and arr[hi] < lo:
        i = hi
        step *= 2
        hi = i + step
    hi = min(hi, n)
    # arr[i] < lo, answer in (i, hi]
    while hi - i > 1:
        mid = (i + hi) // 2
        if arr[mid] < lo:
            i = mid
        else:
            hi = mid
    return hi


@njit(cache=True, inline="always")
def _count_in(arr, lo, hi, i):
    """(how many of the increasing ``arr`` lie in [lo, hi), the index of the first >= hi),
    searching from index i (every earlier entry is below lo)."""
    i = _first_at_or_after(arr, lo, i)
    k = _first_at_or_after(arr, hi, i)
    return k - i, k


@njit(cache=True)
def _mac_activity(b_t, e_t, rows_out, cols_out, cols_in, top_halo, last_row, half, cpd):
    """(starved, blocked) cycles of an NNA submodule from its pops ``b_t`` and pushes ``e_t``:
    the MAC array's waits for its input rows and for a free slot, less the cycles in which the
    line buffer pops (busy). Output row r needs input rows up to ``min(r + top_halo + half,
    last_row)`` of its input region (``cols_in`` wide); the whole frame: top_halo 0, last_row
    H - 1."""
    starved = 0
    blocked = 0
    i = 0
    e_prev = -1
    j = 0
    for r in range(rows_out):
        rows_in = b_t[(min(r + top_halo + half, last_row) + 1) * cols_in - 1] + 1
        for _ in range(cols_out):
            e = e_t[j]
            s = max(e_prev + 1, rows_in)
            if s > e_prev + 1:  # waiting for the row's input, phase 0
                c, i = _count_in(b_t, e_prev + 1, s, i)
                starved += s - e_prev - 1 - c
            done = s + cpd - 1
            if e > done + 1:  # the finished descriptor held for a free slot
                c, i = _count_in(b_t, done + 1, e, i)
                blocked += e - done - 1 - c
            e_prev = e
            j += 1
    return starved, blocked


@njit(cache=True)
def _sva_activity(prm, t):
    """(starved, blocked) cycles of the SVA: output words waiting for their row to be ready
    (starved) or for a free slot in the sink FIFO (blocked), less the cycles in which it pops a
    pair (busy)."""
    h, w = prm[P_H], prm[P_W]
    p_t, o_t = t[T_P], t[T_O]
    la, lat, cpp = prm[P_LA], prm[P_PIPE_LAT], prm[P_CPP]
    starved = 0
    blocked = 0
    i = 0
    o_prev = NEVER
    j = 0
    for y in range(h):
        ready = p_t[min(y + la + 1, h) * w - 1] + 1
        for _ in range(w):
            o = o_t[j]
            lo = max(o_prev + 1, 0)
            if ready > lo:  # nothing pending: the row is not ready yet
                c, i = _count_in(p_t, lo, ready, i)
                starved += ready - lo - c
            due = max(ready + lat, o_prev + cpp)
            if o > due:
                c, i = _count_in(p_t, due, o, i)
                blocked += o - due - c
            o_prev = o
            j += 1
    return starved, blocked


@njit(cache=True)
def _level_walk(inc, inc_conv, dec, dec_conv, c_end, depth, hist):
    """Walk a FIFO's level over the edges ``0 .. c_end - 1`` of one of its domains.

    An event of ``inc`` (or ``dec``) at cycle c of its own domain counts from the edge
    ``_cross(c, *conv)`` on, ``conv = (period_from, period_to, edges)``; both arrays are
    increasing and each ``dec`` event counts no earlier than its ``inc``. The level at an edge
    is the ``inc`` events counted minus the ``dec`` events counted. Adds to ``hist[level]`` the
    edges at each level (unless ``hist`` is empty) and returns (the largest level just after an
    ``inc`` event, the ``dec`` events of that same edge not yet counted; the number of edges
    with a level >= depth).
    """
    n = inc.shape[0]
    keep = hist.shape[0] > 0
    ip, iq, ie = inc_conv[0], inc_conv[1], inc_conv[2]
    dp, dq, de = dec_conv[0], dec_conv[1], dec_conv[2]
    i = 0
    m = 0
    c = 0
    level = 0
    top = 0
    at_depth = 0
    ti = _cross(inc[0], ip, iq, ie) if n > 0 else INF
    td = _cross(dec[0], dp, dq, de) if n > 0 else INF
    while c < c_end:
        nxt = min(ti, td, c_end)
        if nxt > c:
            if keep:
                hist[level] += nxt - c
            if level >= depth:
                at_depth += nxt - c
            c = nxt
            if c >= c_end:
                break
        if ti == c:
            level += 1
            top = max(top, level)
            i += 1
            ti = _cross(inc[i], ip, iq, ie) if i < n else INF
        else:
            level -= 1
            m += 1
            td = _cross(dec[m], dp, dq, de) if m < n else INF
    return top, at_depth


@njit(cache=True)
def _watchdog_safe(t, rows, periods, t_end, p_max, watchdog):
    """True if the events in the rows ``rows`` of ``t`` (event cycles; ``periods``: the period
    of each row's domain) leave no gap
    of ``watchdog * p_max`` fs without an event between one slowest period before 0 and
    ``t_end``: then the readable kernel's watchdog cannot fire (every FIFO event is progress).
    Buckets of half that span must each hold an event."""
    span = (watchdog * p_max) // 2
    if span < 1:
        return False
    n_buckets = (t_end + p_max) // span + 1
    if n_buckets > 1 << 24:
        return False
    seen = np.zeros(n_buckets, np.bool_)
    seen[0] = True
    seen[n_buckets - 1] = True
    for r in range(rows.shape[0]):
        row = t[rows[r]]
        per = periods[r]
        n = row.shape[0]
        k = 0
        while k < n:
            tt = row[k] * per + p_max
            bucket = tt // span
            seen[bucket] = True
            # skip to the first event of a later bucket
            k = _first_at_or_after(row, ((bucket + 1) * span - p_max + per - 1) // per, k + 1)
    for b in range(n_buckets):
        if not seen[b]:
            return False
    return True


# ---- the Python side -----------------------------------------------------------------------


def schedule_params(setup, cfg, sink_stall) -> np.ndarray:
    """The parameter vector of one run (``setup``: a :class:`_Layout`)."""
    h, w = setup.shape
    prm = np.zeros(N_P, np.int64)
    dom = setup.domains
    src = dom["camera" if setup.camera else "nna"]
    f = cfg.fifo
    crossing_src = setup.camera
    prm[P_H], prm[P_W] = h, w
    prm[P_CAMERA] = 1 if setup.camera else 0
    prm[P_LINE_CLOCKS] = w + cfg.source.camera_hblank
    prm[P_MEM_HZ] = round(src.freq_hz)
    prm[P_MEM_BPS] = round(cfg.source.memory_gbps * 1e9)
    prm[P_HALF] = half_window(cfg.nna)
    prm[P_ROWS] = cfg.nna.line_buffer_rows
    prm[P_CPD] = cycles_per_descriptor(cfg.nna)
    prm[P_LA] = cfg.sva.box_size // 2 + (cfg.sva.median // 2 if cfg.sva.median > 1 else 0)
    prm[P_PIPE_LAT] = cfg.sva.pipeline_latency
    prm[P_CPP] = cfg.sva.cycles_per_pixel
    prm[P_D_SRC] = f.source_to_nna_depth
    prm[P_D_NS] = f.nna_to_sva_depth
    prm[P_D_SK] = f.sva_to_sink_depth
    prm[P_DE_SRC] = f.latency_cycles + (f.sync_cycles - 1 if crossing_src else 0)
    prm[P_SE_SRC] = f.sync_cycles if crossing_src else 1
    prm[P_DE_NS] = f.latency_cycles + f.sync_cycles - 1
    prm[P_SE_NS] = f.sync_cycles
    prm[P_LATENCY] = f.latency_cycles
    prm[P_PER_SRC] = src.period_fs
    prm[P_PER_N] = dom["nna"].period_fs
    prm[P_PER_S] = dom["sva"].period_fs
    period, phase = (0, 0) if sink_stall is None else sink_stall
    prm[P_STALL_PERIOD], prm[P_STALL_PHASE] = period, phase
    prm[P_LIMIT_SRC] = setup.budget["camera" if setup.camera else "nna"]
    prm[P_LIMIT_N] = setup.budget["nna"]
    prm[P_LIMIT_S] = setup.budget["sva"]
    prm[P_WATCHDOG] = cfg.sim.watchdog_cycles
    return prm


class _Layout:
    """The domains, blocks, FIFOs and tiles of one run, named as :func:`sim.cycle.chip.build_chip`
    names them."""

    def __init__(self, shape, cfg):
        self.shape = tuple(shape)
        self.camera = cfg.source.kind == "camera"
        self.domains = chip_domains(cfg)
        self.src_domain = "camera" if self.camera else "nna"
        self.budget = frame_budget(shape, cfg, self.domains)
        self.bits = descriptor_bits(cfg.nna)
        self.desc_bits = nna_to_sva_word_bits(cfg)
        self.word_bits = output_word_bits(cfg)
        self.parts = cfg.nna.stereo_submodules // 2
        tiles = split_frame(shape, self.parts, cfg.nna.split, cfg.nna)
        self.geom = np.array([[tl.x0, tl.x1, tl.y0, tl.y1, tl.in_x0, tl.in_x1, tl.in_y0,
                               tl.in_y1] for tl in tiles], np.int64)
        src = "camera" if self.camera else "memory"
        self.sides = ("left", "right")
        self.sources = tuple(f"{src}_{side}" for side in self.sides)
        if self.parts == 1:
            self.nnas = tuple((f"nna_{side}",) for side in self.sides)
            self.src_fifos = tuple((f"src_{side}_to_nna",) for side in self.sides)
            self.merge_fifos = ((), ())
        else:
            self.nnas = tuple(tuple(f"nna_{side}{t}" for t in range(self.parts))
                              for side in self.sides)
            self.src_fifos = tuple(tuple(f"src_{side}_to_nna{t}" for t in range(self.parts))
                                   for side in self.sides)
            self.merge_fifos = tuple(tuple(f"nna_{side}{t}_to_merge"
                                           for t in range(self.parts)) for side in self.sides)


def _conv(per_from: int, per_to: int, edges: int) -> np.ndarray:
    return np.array([per_from, per_to, edges], np.int64)


SAME = _conv(1, 1, 1)  # an event of cycle c counts from cycle c + 1 of its own domain


def _fifo_stats(inc, inc_conv, dec, dec_conv, c_q, producer_walk, empty, depth, width):
    """One FIFO's statistics (the keys of ``Fifo.stats``) from its push and pop cycles.

    ``inc``/``dec`` with their conversions count the pushes and pops in the consumer's timeline
    (``c_q`` edges); ``producer_walk`` = ``(inc, conv, dec, conv, c_p)`` the same in the
    producer's timeline for a FIFO that crosses domains (None: one domain, the same walk);
    ``empty``: the consumer cycles before the last pop without a visible head."""
    n = inc.shape[0]
    hist = np.zeros(depth + 1, np.int64)
    top, full = _level_walk(inc, inc_conv, dec, dec_conv, c_q, depth, hist)
    if producer_walk is not None:
        p_inc, p_inc_conv, p_dec, p_dec_conv, c_p = producer_walk
        top, full = _level_walk(p_inc, p_inc_conv, p_dec, p_dec_conv, c_p, depth,
                                np.zeros(0, np.int64))
    return {
        "bits_transferred": n * width,
        "cycles_empty": int(empty + c_q - 1 - int(dec[n - 1])),
        "cycles_full": int(full),
        "depth": depth,
        "max_occupancy": int(np.flatnonzero(hist).max()),
        "max_producer_occupancy": int(top),
        "occupancy_histogram": [int(v) for v in hist],
        "pops": n,
        "pushes": n,
        "width_bits": width,
    }


def _activity(busy, starved, blocked, idle) -> dict:
    return {"blocked": int(blocked), "busy": int(busy), "idle": int(idle),
            "starved": int(starved)}


def _tile_indices(g, w) -> tuple[np.ndarray, np.ndarray]:
    """Raster indices of a tile's input region and of its output region, in their order."""
    ix0, ix1, iy0, iy1 = g[G_IX0], g[G_IX1], g[G_IY0], g[G_IY1]
    x0, x1, y0, y1 = g[G_X0], g[G_X1], g[G_Y0], g[G_Y1]
    inp = (np.arange(iy0, iy1)[:, None] * w + np.arange(ix0, ix1)[None, :]).ravel()
    out = (np.arange(y0, y1)[:, None] * w + np.arange(x0, x1)[None, :]).ravel()
    return inp, out


def run_schedule(left: np.ndarray, right: np.ndarray, cfg, *, sink_stall=None,
                 trace_out: dict | None = None, timings: dict | None = None):
    """One frame on the schedule engine: ``(words, cycle report, stats)`` equal to
    :func:`sim.cycle.chip.run_cycle`'s, or ``None`` when the run does not complete cleanly (a camera
    overflow, a deadlock, a budget or a watchdog that could fire): the step engine (or, for
    split frames, the readable kernel) then tells where and why it stops. ``sink_stall``:
    ``(period, allowed_phase)`` as in :func:`sim.cycle.fast.run_cycle_fast`. ``trace_out`` (a dict)
    receives ``row_times`` as the step engine records it (whole frames only): the instants at
    which the left line buffer has received r rows and the sink has received r rows,
    r = 0 .. H (for trace windows given in rows). ``timings`` (a dict) receives the CPU seconds
    of the event cycles and statistics (``schedule_s``), the NNA's descriptors
    (``nna_kernels_s``) and the SVA's stream (``sva_kernels_s``)."""
    t0 = time.process_time()
    h, w = left.shape
    n = h * w
    lay = _Layout(left.shape, cfg)
    prm = schedule_params(lay, cfg, sink_stall)
    t = np.empty((N_T, n), np.int64)
    cnt = np.zeros(N_C, np.int64)
    split = lay.parts > 1
    if split:
        sizes = [(int((g[G_IY1] - g[G_IY0]) * (g[G_IX1] - g[G_IX0])),
                  int((g[G_Y1] - g[G_Y0]) * (g[G_X1] - g[G_X0]))) for g in lay.geom]
        off = np.zeros((2, lay.parts, 2), np.int64)
        pos = 0
        for side in range(2):
            for tile, (n_in, n_out) in enumerate(sizes):
                off[side, tile] = pos, pos + n_in
                pos += n_in + n_out
        tt = np.empty(pos, np.int64)
        cnt2 = np.zeros((2, 1 + 2 * lay.parts), np.int64)
        st2 = np.zeros((2, 2 + 2 * lay.parts), np.int64)
        last_pop = np.full((2, lay.parts), -1, np.int64)
        _advance_split(prm, lay.geom, t, tt, off, cnt, cnt2, st2, last_pop)
    else:
        _advance(prm, t, cnt)
    if cnt[C_STOP] != STOP_NONE:
        return None
    doms = lay.domains
    per = {name: d.period_fs for name, d in doms.items()}
    q_last = int(t[T_Q, n - 1])
    t_end = q_last * per["sva"]
    cycles = {name: t_end // per[name] + 1 for name in doms}
    if any(cycles[name] > lay.budget[name] for name in doms):
        return None
    p_max = max(per.values())
    rows = np.array([T_A, T_E, T_Q], np.int64)
    periods = np.array([per[lay.src_domain], per["nna"], per["sva"]], np.int64)
    if not _watchdog_safe(t, rows, periods, t_end, p_max, cfg.sim.watchdog_cycles):
        return None

    f = cfg.fifo
    c_src, c_n, c_s = cycles[lay.src_domain], cycles["nna"], cycles["sva"]
    p_src, p_n = per[lay.src_domain], per["nna"]
    src_q = _conv(p_src, p_n, 1)  # a source push counts from the first nna edge after it
    src_p = _conv(p_n, p_src, f.sync_cycles) if lay.camera else SAME  # a pop's free slot
    half, cpd = int(prm[P_HALF]), int(prm[P_CPD])
    blocks, fifos, work = {}, {}, {}
    for side in range(2):
        src = lay.sources[side]
        if lay.camera:
            busy = min(c_src, h * (w + cfg.source.camera_hblank))
            blocks[src] = _activity(busy, 0, 0, c_src - busy)
            work[src] = ((h + cfg.source.camera_vblank) * (w + cfg.source.camera_hblank),
                         doms[lay.src_domain].freq_hz)
        else:
            active = int(t[T_A + 4 * side, n - 1]) + 1
            blocked = int(cnt[C_SRC_BLOCKED + side])
            blocks[src] = _activity(active - blocked, 0, blocked, c_src - active)
            work[src] = (active - blocked, doms[lay.src_domain].freq_hz)
        a_t = t[T_A + 4 * side]
        for tile in range(lay.parts):
            g = lay.geom[tile]
            if split:
                b0, e0 = off[side, tile]
                n_in, n_out = sizes[tile]
                b_t, e_t = tt[b0:b0 + n_in], tt[e0:e0 + n_out]
                idx_in, idx_out = _tile_indices(g, w)
                pushes = a_t[idx_in]
                src_empty = int(st2[side, 2 + 2 * tile])
            else:
                b_t, e_t, pushes = t[T_B + 4 * side], t[T_E + 4 * side], a_t
                n_out = n
                src_empty = int(cnt[C_EMPTY_SRC + side])
            starved, blocked = _mac_activity(
                b_t, e_t, g[G_Y1] - g[G_Y0], g[G_X1] - g[G_X0], g[G_IX1] - g[G_IX0],
                g[G_Y0] - g[G_IY0], h - 1 - g[G_IY0], half, cpd)
            active = int(e_t[n_out - 1]) + 1
            name = lay.nnas[side][tile]
            blocks[name] = _activity(active - starved - blocked, starved, blocked,
                                     c_n - active)
            work[name] = (n_out * cpd, doms["nna"].freq_hz)
            fifos[lay.src_fifos[side][tile]] = _fifo_stats(
                pushes, src_q, b_t, SAME, c_n,
                (pushes, SAME, b_t, src_p, c_src) if lay.camera else None,
                src_empty, f.source_to_nna_depth, 8)
            if split:
                pops = t[T_E + 4 * side][idx_out]
                fifos[lay.merge_fifos[side][tile]] = _fifo_stats(
                    e_t, SAME, pops, SAME, c_n, None,
                    int(st2[side, 3 + 2 * tile]), f.nna_to_sva_depth,
                    lay.desc_bits)
        if split:
            name = f"merge_{lay.sides[side]}"
            starved, blocked = st2[side, 0], st2[side, 1]
            blocks[name] = _activity(n, starved, blocked,
                                     c_n - int(t[T_E + 4 * side, n - 1]) - 1)
            work[name] = (n, doms["nna"].freq_hz)
        fifos[f"nna_{lay.sides[side]}_to_sva"] = _fifo_stats(
            t[T_VE + 4 * side], _conv(1, 1, 1 - int(prm[P_DE_NS])), t[T_P], SAME, c_s,
            (t[T_E + 4 * side], SAME, t[T_FP], _conv(1, 1, 0), c_n),
            int(cnt[C_EMPTY_NS + side]), f.nna_to_sva_depth, lay.desc_bits)
    starved, blocked = _sva_activity(prm, t)
    active = int(t[T_O, n - 1]) + 1
    blocks["sva"] = _activity(active - starved - blocked, starved, blocked, c_s - active)
    work["sva"] = (n * cfg.sva.cycles_per_pixel, doms["sva"].freq_hz)
    period, phase = (0, 0) if sink_stall is None else sink_stall
    allowed = c_s if period == 0 else (q_last - phase) // period + 1 if q_last >= phase else 0
    blocks["sink"] = _activity(n, allowed - n, 0, c_s - allowed)
    fifos["sva_to_sink"] = _fifo_stats(t[T_O], SAME, t[T_Q], SAME, c_s, None,
                                       int(cnt[C_EMPTY_SK]), f.sva_to_sink_depth,
                                       lay.word_bits)
    stats = {
        "blocks": {b: blocks[b] for b in sorted(blocks)},
        "cycles": {name: int(cycles[name]) for name in sorted(cycles)},
        "end_time_fs": int(t_end),
        "fifos": {name: fifos[name] for name in sorted(fifos)},
        "steps": count_instants([(0, per[name], cycles[name]) for name in doms]),
    }
    report = assemble_report(doms["sva"], int(t[T_Q, 0]), q_last, work, stats)
    if trace_out is not None and not split:
        row_times = np.zeros((2, h + 1), np.int64)
        row_times[0, 1:] = t[T_B, w - 1::w] * per["nna"]
        row_times[1, 1:] = t[T_Q, w - 1::w] * per["sva"]
        trace_out["row_times"] = row_times
    del t
    t1 = time.process_time()
    desc_l = compute_descriptor(left, cfg.nna)
    desc_r = compute_descriptor(right, cfg.nna)
    t2 = time.process_time()
    words = sva_stream(desc_l, desc_r, left, cfg.sva, lay.bits)
    if timings is not None:
        timings.update(schedule_s=t1 - t0, nna_kernels_s=t2 - t1,
                       sva_kernels_s=time.process_time() - t2)
    return words, report, stats
