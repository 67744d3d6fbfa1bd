"""The compiled cycle engine: the chip of :mod:`sim.cycle.chip` in one numba loop, cycle for cycle.

:func:`run_cycle_fast` simulates the same chip as :func:`sim.cycle.chip.run_cycle` -- memory or camera
sources, one NNA submodule per camera (census or CNN), the SVA and the sink, joined by the FIFOs
of :mod:`sim.cycle.fifo` with their latency and clock-domain-crossing synchronisers -- and returns the
same output words, the same cycle report and the same kernel statistics. It is exact, not an
estimate: every rule of :mod:`sim.cycle.clock` and :mod:`sim.cycle.fifo` is mirrored on arrays.

* **Steps.** One compiled loop (:func:`_run_steps`, driven by :func:`_run_loop`): ``t`` = the
  earliest next edge over the domains; the domains with an edge at ``t`` tick; every FIFO touched
  by a ticking domain samples its per-cycle statistics (``Fifo._begin_step``); the blocks of the
  ticking domains evaluate from committed state and stage their FIFO pushes and pops; then the
  FIFOs commit. A block's own registers are only read by itself, so it updates them at the end
  of its evaluation.
* **FIFOs.** Per FIFO a ring of ``depth`` items ``(visible-at consumer cycle, payload)`` and a
  ring of freed-slot visibility cycles (``Fifo._items`` / ``Fifo._frees``); neither ever holds
  more than ``depth`` entries (the producer counts a slot free only once its freeing is seen).
* **Data.** Pixels, descriptors and output words travel in the FIFOs. The NNA keeps what it
  popped in its own (H, W) array and computes a descriptor row with
  :func:`descriptor_row_census` / :func:`descriptor_row_cnn` from those pixels only, as soon as
  the row's input rows are in (the readable block does it at the row's first push; the rows it
  reads never change in between, so the bits are the same). The SVA keeps the received
  descriptors and runs the functional streaming kernel (:func:`sva.pipeline._stream` and the
  median kernels) on the rows received so far once the output row in progress is ready and not
  yet final -- exactly what :class:`sva.pipeline.SvaStream` computes.
* **Quiet stretches.** A clock domain whose blocks would report one status edge after edge is
  *parked* and its edges settled in bulk (see the section of that name below); 4.3 M of the
  16.7 M edges of a 720p CNN frame are stepped.

Not covered: frames split over several NNA submodules (``nna.stereo_submodules`` > 2), traces
and shuffled evaluation orders (results cannot depend on the order anyway), and sink stall
functions other than a periodic pattern ``(period, allowed_phase)``: the sink pops only in
cycles with ``cycle % period == allowed_phase``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from nna.census import census_offsets
from nna.conv import _channel_row, _sign_bits_rows_f32, f32_exact
from nna.descriptor import descriptor_bits, layer
from nna.geometry import cycles_per_descriptor, half_window
from sim.config import ChipConfig
from sim.cycle.architecture import nna_to_sva_word_bits, output_word_bits
from sim.cycle.blocks.sources import CameraOverflow
from sim.cycle.clock import (
    ACTIVITIES,
    BudgetExceeded,
    DeadlockError,
    count_instants,
    watchdog_message,
)
from sim.cycle.report import assemble_report, chip_domains, frame_budget
from sim.cycle.schedule import run_schedule
from sim.errors import ConfigError
from sva.median import _median3, _median_network, selection_network
from sva.pipeline import SvaStream, _stream

# ---- indices of the fixed topology (insertion order of sim.cycle.chip.build_chip) --------------------

D_NNA, D_SVA, D_CAM = 0, 1, 2
DOMAIN_NAMES = ("nna", "sva", "camera")
# FIFOs
F_NNA_L, F_SRC_L, F_NNA_R, F_SRC_R, F_SINK = 0, 1, 2, 3, 4
FIFO_NAMES = ("nna_left_to_sva", "src_left_to_nna", "nna_right_to_sva", "src_right_to_nna",
              "sva_to_sink")
# blocks
B_SRC_L, B_NNA_L, B_SRC_R, B_NNA_R, B_SVA, B_SINK = 0, 1, 2, 3, 4, 5
# activities (index into ACTIVITIES: busy, starved, blocked, idle)
A_BUSY, A_STARVED, A_BLOCKED, A_IDLE = 0, 1, 2, 3

# domain table columns
# (parked: 1 while the domain's edges are settled in bulk, see "quiet stretches"; wake: the
# edge at which a parked domain steps again; pbusy: a parked domain's blocks include a busy one)
DC_PERIOD, DC_PHASE, DC_CYCLES, DC_NEXT, DC_LIMIT, DC_PARKED, DC_WAKE, DC_PBUSY = range(8)
N_DC = 8
# FIFO table columns
(FC_DEPTH, FC_DATA_EDGES, FC_SPACE_EDGES, FC_SRC, FC_DST, FC_OFF, FC_HOFF, FC_IHEAD, FC_ICOUNT,
 FC_FHEAD, FC_FCOUNT, FC_PUSHES, FC_POPS, FC_SEEN, FC_MAXOCC, FC_MAXPROD, FC_FULL, FC_EMPTY,
 FC_PUSH_ST, FC_POP_ST, FC_STAGED) = range(21)
N_FC = 21
# block table columns: status, waiting FIFO (-1 none), 4 activity counts, then per-block state
(BC_STATUS, BC_WAIT, BC_BUSY, BC_STARVED, BC_BLOCKED, BC_IDLE, BC_S0, BC_S1, BC_S2, BC_S3,
 BC_S4, BC_S5, BC_S0Y, BC_S0X, BC_S1Y, BC_S1X, BC_PSTATUS, BC_PWAIT) = range(18)
N_BC = 18
# per-block state: sources BC_S0 = pixels sent; NNA S0 received, S1 emitted, S2 MAC phase,
# S3 row of the cached descriptors; SVA S0 received, S1 emitted, S2 last push cycle, S3 ready
# rows, S4 rows checked, S5 rows final; sink S0 received, S1 first cycle, S2 last cycle.
# BC_S0Y/BC_S0X and BC_S1Y/BC_S1X hold the raster (row, column) of the counters S0 and S1, so
# the loop never divides by W; BC_PSTATUS/BC_PWAIT: the status a parked block reports each edge
# global scalars
# (now: the last step's instant; tlp: the instant of the last step with progress)
G_NOW, G_TLP, G_EVENT_A, G_EVENT_B, G_EVENT_C, G_EVENT_D = range(6)
N_G = 6
EV_DONE, EV_DEADLOCK, EV_BUDGET, EV_OVERFLOW, EV_DATA, EV_TRACE = 0, 1, 2, 3, 4, 5
# trace state (see "traces"): TR_* index the int64 control array
TR_ON, TR_START, TR_END, TR_STARTED, TR_COUNT, TR_WORD_MASK, TR_OUT0, TR_OUT1, TR_CLOSED = range(9)
# hold table columns per FIFO: pushed / popped in the last tick of its producer / consumer, the
# last value pushed
H_PUSH, H_POP, H_VALUE = range(3)


# ---- descriptor rows -----------------------------------------------------------------------


@njit(cache=True)
def descriptor_row_census(pixels, y, offsets_a, offsets_b, out):
    """Census descriptors of image row ``y`` of ``pixels`` (uint8 (H, W)) into ``out`` (W,).

    Bit k compares ``pixels[y + offsets_a[k]] > pixels[y + offsets_b[k]]`` (offsets are
    ``(dy, dx)``; for the plain census ``offsets_b`` is all zero, for the symmetric one it is
    ``-offsets_a``), coordinates clamped into the image (replicate border) -- the definition of
    :mod:`nna.census`. Reads rows ``y - h .. y + h`` only.
    """
    h, w = pixels.shape
    n_bits = offsets_a.shape[0]
    for x in range(w):
        out[x] = 0
    for k in range(n_bits):
        ya = min(max(y + offsets_a[k, 0], 0), h - 1)
        yb = min(max(y + offsets_b[k, 0], 0), h - 1)
        dxa = offsets_a[k, 1]
        dxb = offsets_b[k, 1]
        row_a = pixels[ya]
        row_b = pixels[yb]
        mask = np.uint64(1) << np.uint64(k)
        for x in range(w):
            a = row_a[min(max(x + dxa, 0), w - 1)]
            b = row_b[min(max(x + dxb, 0), w - 1)]
            out[x] |= mask if a > b else np.uint64(0)


@njit(cache=True)
def descriptor_row_cnn(pixels, y, w_f32, w_i32, bias, input_offset, out):
    """CNN descriptors of image row ``y`` of ``pixels`` (uint8 (H, W)) into ``out`` (W,).

    ``w_f32`` / ``w_i32`` (C, K, Kp) are the layer's int8 (C, K, K) weights with zero columns up
    to Kp, a multiple of 3 (:func:`cnn_tables`): in float32 when the tap sums are exact in
    float32 (:func:`nna.conv.f32_exact`, every 9x9 layer), else in int32 -- the other one is
    empty; ``bias`` int32 (C,). Bit c is ``bias[c] + sum w[c, ky, kx] * (pixel - input_offset)
    > 0`` with clamped coordinates (:mod:`nna.conv`). Reads rows ``y - K // 2 .. y + K // 2``
    only, and runs the full-frame kernel's inner loop (:func:`nna.conv._channel_row`, three taps
    per pass along the row, in float32 four channels at a time) on those K rows.
    """
    use_f32 = w_f32.shape[0] > 0
    h, w = pixels.shape
    n_ch, k_size, k_cols = w_f32.shape if use_f32 else w_i32.shape
    r = k_size // 2
    # the K input rows, replicate-padded (r left, r + Kp - K right), minus the zero point
    width = w + 2 * r + (k_cols - k_size)
    rows = np.empty((k_size, width), np.int32)
    for ky in range(k_size):
        src = pixels[min(max(y + ky - r, 0), h - 1)]
        dst = rows[ky]
        for x in range(width):
            dst[x] = np.int32(src[min(max(x - r, 0), w - 1)]) - input_offset
    for x in range(w):
        out[x] = 0
    if use_f32:
        masks = np.empty(n_ch, np.uint64)
        for c in range(n_ch):
            masks[c] = np.uint64(1) << np.uint64(c)
        _sign_bits_rows_f32(rows.astype(np.float32), w_f32, bias, masks, 0,
                            np.empty((4, w), np.float32), np.empty(w, np.float32), out)
    else:
        acc_i32 = np.empty(w, np.int32)
        for c in range(n_ch):
            _channel_row(rows, w_i32, bias[c], c, 0, acc_i32)
            mask = np.uint64(1) << np.uint64(c)
            for x in range(w):
                if acc_i32[x] > 0:
                    out[x] |= mask


def census_tables(cfg_census) -> tuple[np.ndarray, np.ndarray]:
    """``(offsets_a, offsets_b)`` int64 (n, 2) of ``(dy, dx)`` for :func:`descriptor_row_census`."""
    offsets = census_offsets(cfg_census.window, cfg_census.kind, cfg_census.stride)
    a = np.array([(dy, dx) for dx, dy in offsets], np.int64).reshape(-1, 2)
    b = np.zeros_like(a) if cfg_census.kind == "plain" else -a
    return a, b


def cnn_tables(weights, bias) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(w_f32, w_i32, bias int32)`` for :func:`descriptor_row_cnn`: the weights with zero
    columns up to Kp, the next multiple of 3 (the taps per pass of the row loop), in float32
    where that is exact (:func:`nna.conv.f32_exact`), else in int32; the other array is empty
    (0, K, Kp)."""
    n_ch, k_size, _ = weights.shape
    k_cols = -(-k_size // 3) * 3
    exact = f32_exact(k_size)
    w_f32 = np.zeros((n_ch if exact else 0, k_size, k_cols), np.float32)
    w_i32 = np.zeros((0 if exact else n_ch, k_size, k_cols), np.int32)
    (w_f32 if exact else w_i32)[:, :, :k_size] = weights
    return w_f32, w_i32, np.ascontiguousarray(bias.astype(np.int32))


# ---- FIFO primitives -----------------------------------------------------------------------


@njit(cache=True, _nrt=False, inline="always")
def _edge_after(dom, tick, d, t):
    """Index of the first edge of domain ``d`` strictly after the current step's instant t.

    ``ClockDomain.first_edge_after(t)`` without a division: the domain's next edge (index
    ``cycles``, at ``phase + cycles * period >= t``) if it does not tick at t, else the one
    after it (``cycles`` is advanced only after the commit). A parked domain's ``cycles`` lags
    behind t: then with the division.
    """
    if dom[d, DC_PARKED]:
        return (t - dom[d, DC_PHASE]) // dom[d, DC_PERIOD] + 1 if t >= dom[d, DC_PHASE] else 0
    return dom[d, DC_CYCLES] + (1 if tick[d] else 0)


@njit(cache=True, _nrt=False, inline="always")
def _wrap(i, depth):
    """``i % depth`` for ``0 <= i < 2 * depth`` (ring indices) without a division."""
    return i - depth if i >= depth else i


@njit(cache=True, _nrt=False, inline="always")
def _can_push(fq, f):
    return fq[f, FC_PUSH_ST] == 0 and fq[f, FC_PUSHES] - fq[f, FC_SEEN] < fq[f, FC_DEPTH]


@njit(cache=True, _nrt=False, inline="always")
def _can_pop(fq, ready, f, cyc):
    return (fq[f, FC_POP_ST] == 0 and fq[f, FC_ICOUNT] > 0
            and ready[fq[f, FC_OFF] + fq[f, FC_IHEAD]] <= cyc)


@njit(cache=True, _nrt=False, inline="always")
def _head(fq, f):
    """Ring index of the head item."""
    return fq[f, FC_OFF] + fq[f, FC_IHEAD]


@njit(cache=True, _nrt=False, inline="always")
def _push(fq, staged_desc, f, value, desc):
    fq[f, FC_PUSH_ST] = 1
    fq[f, FC_STAGED] = value
    staged_desc[f] = desc


@njit(cache=True, _nrt=False, inline="always")
def _begin_step(fq, ready, frees, hist, dom, tick, f):
    """``Fifo._begin_step``: see the frees that reached the producer, sample the statistics."""
    src = fq[f, FC_SRC]
    dst = fq[f, FC_DST]
    depth = fq[f, FC_DEPTH]
    off = fq[f, FC_OFF]
    if tick[src]:
        cyc = dom[src, DC_CYCLES]
        while fq[f, FC_FCOUNT] > 0 and frees[off + fq[f, FC_FHEAD]] <= cyc:
            fq[f, FC_FHEAD] = _wrap(fq[f, FC_FHEAD] + 1, depth)
            fq[f, FC_FCOUNT] -= 1
            fq[f, FC_SEEN] += 1
        if fq[f, FC_PUSHES] - fq[f, FC_SEEN] >= depth:
            fq[f, FC_FULL] += 1
    if tick[dst]:
        cyc = dom[dst, DC_CYCLES]
        hist[fq[f, FC_HOFF] + fq[f, FC_PUSHES] - fq[f, FC_POPS]] += 1
        if fq[f, FC_ICOUNT] == 0 or ready[off + fq[f, FC_IHEAD]] > cyc:
            fq[f, FC_EMPTY] += 1


@njit(cache=True, _nrt=False, inline="always")
def _commit(fq, ready, pay, pay_desc, frees, staged_desc, dom, tick, f, t):
    """``Fifo._commit``: apply the staged push and pop; True if either happened."""
    depth = fq[f, FC_DEPTH]
    off = fq[f, FC_OFF]
    moved = False
    if fq[f, FC_PUSH_ST]:
        pos = off + _wrap(fq[f, FC_IHEAD] + fq[f, FC_ICOUNT], depth)
        ready[pos] = _edge_after(dom, tick, fq[f, FC_DST], t) + fq[f, FC_DATA_EDGES] - 1
        pay[pos] = fq[f, FC_STAGED]
        pay_desc[pos] = staged_desc[f]
        fq[f, FC_ICOUNT] += 1
        fq[f, FC_PUSHES] += 1
        fq[f, FC_PUSH_ST] = 0
        moved = True
    if fq[f, FC_POP_ST]:
        fq[f, FC_IHEAD] = _wrap(fq[f, FC_IHEAD] + 1, depth)
        fq[f, FC_ICOUNT] -= 1
        fq[f, FC_POPS] += 1
        pos = off + _wrap(fq[f, FC_FHEAD] + fq[f, FC_FCOUNT], depth)
        frees[pos] = _edge_after(dom, tick, fq[f, FC_SRC], t) + fq[f, FC_SPACE_EDGES] - 1
        fq[f, FC_FCOUNT] += 1
        fq[f, FC_POP_ST] = 0
        moved = True
    occ = fq[f, FC_PUSHES] - fq[f, FC_POPS]
    if occ > fq[f, FC_MAXOCC]:
        fq[f, FC_MAXOCC] = occ
    seen = fq[f, FC_PUSHES] - fq[f, FC_SEEN]
    if seen > fq[f, FC_MAXPROD]:
        fq[f, FC_MAXPROD] = seen
    return moved


@njit(cache=True, _nrt=False, inline="always")
def _advance(bs, b, counter, col, w):
    """Count one more beat on block ``b``'s raster counter (BC_S0 or BC_S1) and its (row, col)."""
    bs[b, counter] += 1
    x = bs[b, col] + 1
    if x == w:
        bs[b, col] = 0
        bs[b, col - 1] += 1
    else:
        bs[b, col] = x


@njit(cache=True, _nrt=False, inline="always")
def _report(bs, b, status, fifo):
    bs[b, BC_STATUS] = status
    bs[b, BC_WAIT] = fifo
    bs[b, BC_BUSY + status] += 1
    return status == A_BUSY


# ---- blocks --------------------------------------------------------------------------------


@njit(cache=True, _nrt=False, inline="always")
def _memory_eval(bs, fq, staged_desc, b, f, image, cyc, freq_hz, bytes_per_s):
    """``MemorySource.evaluate`` + commit (token bucket, one pixel per cycle)."""
    h, w = image.shape
    sent = bs[b, BC_S0]
    if sent >= h * w:
        return _report(bs, b, A_IDLE, -1)
    # with bytes_per_s >= freq_hz the bucket never limits (sent <= cyc); skipping the products
    # then also keeps them far from int64 overflow
    if bytes_per_s < freq_hz and (sent + 1) * freq_hz > (cyc + 1) * bytes_per_s:
        return _report(bs, b, A_BUSY, -1)
    if not _can_push(fq, f):
        return _report(bs, b, A_BLOCKED, f)
    _push(fq, staged_desc, f, np.int64(image[bs[b, BC_S0Y], bs[b, BC_S0X]]), np.uint64(0))
    _advance(bs, b, BC_S0, BC_S0X, w)
    return _report(bs, b, A_BUSY, -1)


@njit(cache=True, _nrt=False, inline="always")
def _camera_eval(bs, fq, staged_desc, b, f, image, cyc, line_clocks):
    """``CameraSource.evaluate`` + commit; False if the FIFO overflowed (nothing reported)."""
    h, w = image.shape
    line = cyc // line_clocks
    col = cyc % line_clocks
    if line >= h:
        _report(bs, b, A_IDLE, -1)
        return True
    if col < w:
        if not _can_push(fq, f):
            return False
        _push(fq, staged_desc, f, np.int64(image[line, col]), np.uint64(0))
        bs[b, BC_S0] += 1
    _report(bs, b, A_BUSY, -1)
    return True


@njit(cache=True, _nrt=False, inline="always")
def _nna_eval(bs, fq, ready, pay, staged_desc, b, side, cyc, pixels, row_desc, timing):
    """``NnaSubmodule.evaluate`` + commit for a whole-frame submodule of camera ``side``.

    ``pixels`` (2, H, W) and ``row_desc`` (2, W) hold both submodules' line buffers and
    descriptor rows; ``timing`` = (half window, line buffer rows, cycles per descriptor). The
    descriptor row the MAC array works on is computed by :func:`_nna_prepare_row`.
    """
    half, rows, cpd = timing[0], timing[1], timing[2]
    f_in = F_SRC_L if side == 0 else F_SRC_R
    f_out = F_NNA_L if side == 0 else F_NNA_R
    h, w = pixels.shape[1], pixels.shape[2]
    n = h * w
    received = bs[b, BC_S0]
    emitted = bs[b, BC_S1]
    phase = bs[b, BC_S2]
    moved = False
    pop = False
    # line buffer: one pixel per cycle while there is room
    if received < n and _can_pop(fq, ready, f_in, cyc):
        y_in = bs[b, BC_S0Y]
        y_out = bs[b, BC_S1Y]
        if y_out >= h or y_in - max(0, y_out - half) + 1 <= rows:
            pop = True
            fq[f_in, FC_POP_ST] = 1
            moved = True
    # MAC array
    phase_next = phase
    pushed = False
    mac_blocked = False
    if emitted < n:
        y = bs[b, BC_S1Y]
        x = bs[b, BC_S1X]
        if phase == 0 and bs[b, BC_S0Y] - 1 < min(y + half, h - 1):
            pass  # the row's input is not in yet: starved
        else:
            worked = phase < cpd
            if phase + 1 >= cpd:
                if _can_push(fq, f_out):
                    _push(fq, staged_desc, f_out, np.int64(pixels[side, y, x]),
                          row_desc[side, x])
                    pushed = True
                    phase_next = 0
                    moved = True
                else:
                    phase_next = cpd
                    if not worked:
                        mac_blocked = True
                    moved = moved or worked
            else:
                phase_next = phase + 1
                moved = True
    # commit
    if pop:
        pixels[side, bs[b, BC_S0Y], bs[b, BC_S0X]] = pay[_head(fq, f_in)]
        _advance(bs, b, BC_S0, BC_S0X, w)
    if pushed:
        _advance(bs, b, BC_S1, BC_S1X, w)
    bs[b, BC_S2] = phase_next
    if moved:
        return _report(bs, b, A_BUSY, -1)
    if mac_blocked:
        return _report(bs, b, A_BLOCKED, f_out)
    if emitted < n or received < n:
        return _report(bs, b, A_STARVED, f_in)
    return _report(bs, b, A_IDLE, -1)


@njit(cache=True)
def _nna_prepare_row(bs, b, side, pixels, row_desc, nna):
    """Compute the descriptors of the row the MAC array is on once its input rows are in.

    The readable block computes them when the row's first descriptor is pushed; the rows it
    reads (y - h .. y + h) are complete from the moment the row may start and are never written
    again, so computing them then gives the same bits.
    """
    half, rows, cpd, is_cnn, offsets_a, offsets_b, w_f32, w_i32, bias, input_offset = nna
    h, w = pixels.shape[1], pixels.shape[2]
    y = bs[b, BC_S1Y]
    if y >= h or bs[b, BC_S3] == y or bs[b, BC_S0Y] - 1 < min(y + half, h - 1):
        return
    if is_cnn:
        descriptor_row_cnn(pixels[side], y, w_f32, w_i32, bias, input_offset, row_desc[side])
    else:
        descriptor_row_census(pixels[side], y, offsets_a, offsets_b, row_desc[side])
    bs[b, BC_S3] = y


@njit(cache=True)
def _sva_advance(bs, rows_in, sva):
    """``SvaStream.advance(rows_in)`` on the block's state (rows checked S4, rows final S5)."""
    (desc_l, desc_r, img_l, box, sgm, select, checked, q, colsum, box_r, median_k,
     network) = sva
    h = desc_l.shape[0]
    rows_checked = bs[B_SVA, BC_S4]
    rows_final = bs[B_SVA, BC_S5]
    stop = h if rows_in >= h else max(0, rows_in - box_r)
    if stop > rows_checked:
        _stream(desc_l, desc_r, img_l, box, sgm, select, checked, colsum, rows_checked, stop)
        rows_checked = stop
    m = median_k // 2 if median_k > 1 else 0
    final = h if rows_checked >= h else max(0, rows_checked - m)
    if final > rows_final:
        if m:
            lo = max(0, rows_final - m)
            hi = min(h, final + m)
            block = np.empty((hi - lo, checked.shape[1]), np.int32)
            src = np.ascontiguousarray(checked[lo:hi])
            if median_k == 3:
                _median3(src, block)
            else:
                _median_network(src, median_k, network, block)
            for yy in range(rows_final, final):
                q[yy, :] = block[yy - lo]
        rows_final = final
    bs[B_SVA, BC_S4] = rows_checked
    bs[B_SVA, BC_S5] = rows_final


@njit(cache=True, _nrt=False, inline="always")
def _sva_eval(bs, fq, ready, pay, pay_desc, staged_desc, cyc, ready_cycle, received_data, q,
              timing):
    """``SvaBlock.evaluate`` + commit. ``received_data`` = (desc_l, desc_r, img_l); ``q`` the
    stream's output words, made final by :func:`_sva_advance` before a row's first push;
    ``timing`` = (look-ahead rows, pipeline latency, cycles per pixel)."""
    lookahead, latency, cpp = timing[0], timing[1], timing[2]
    desc_l, desc_r, img_l = received_data
    h, w = desc_l.shape
    n = h * w
    received = bs[B_SVA, BC_S0]
    emitted = bs[B_SVA, BC_S1]
    moved = False
    pair = False
    wait = -1
    if received < n and bs[B_SVA, BC_S0Y] <= bs[B_SVA, BC_S1Y] + lookahead + 1:
        can_l = _can_pop(fq, ready, F_NNA_L, cyc)
        if can_l and _can_pop(fq, ready, F_NNA_R, cyc):
            pair = True
            fq[F_NNA_L, FC_POP_ST] = 1
            fq[F_NNA_R, FC_POP_ST] = 1
            moved = True
        else:
            wait = F_NNA_L if not can_l else F_NNA_R
    blocked = False
    pending = False
    pushed = False
    if emitted < n:
        y = bs[B_SVA, BC_S1Y]
        if y < bs[B_SVA, BC_S3]:
            pending = True
            due = max(ready_cycle[y] + latency, bs[B_SVA, BC_S2] + cpp)
            if cyc >= due:
                if _can_push(fq, F_SINK):
                    _push(fq, staged_desc, F_SINK, np.int64(q[y, bs[B_SVA, BC_S1X]]), np.uint64(0))
                    pushed = True
                    moved = True
                else:
                    blocked = True
    # commit
    if pair:
        yy = bs[B_SVA, BC_S0Y]
        xx = bs[B_SVA, BC_S0X]
        hl = _head(fq, F_NNA_L)
        desc_l[yy, xx] = pay_desc[hl]
        img_l[yy, xx] = pay[hl]
        desc_r[yy, xx] = pay_desc[_head(fq, F_NNA_R)]
        _advance(bs, B_SVA, BC_S0, BC_S0X, w)
        if bs[B_SVA, BC_S0X] == 0:
            rows = bs[B_SVA, BC_S0Y]
            n_ready = h if rows >= h else max(0, rows - lookahead)
            for yr in range(bs[B_SVA, BC_S3], n_ready):
                ready_cycle[yr] = cyc + 1
            if n_ready > bs[B_SVA, BC_S3]:
                bs[B_SVA, BC_S3] = n_ready
    if pushed:
        bs[B_SVA, BC_S2] = cyc
        _advance(bs, B_SVA, BC_S1, BC_S1X, w)
    if moved:
        return _report(bs, B_SVA, A_BUSY, -1)
    if blocked:
        return _report(bs, B_SVA, A_BLOCKED, F_SINK)
    if pending:
        return _report(bs, B_SVA, A_BUSY, -1)
    if emitted < n:
        return _report(bs, B_SVA, A_STARVED, wait if wait >= 0 else F_NNA_L)
    return _report(bs, B_SVA, A_IDLE, -1)


@njit(cache=True, _nrt=False, inline="always")
def _sink_eval(bs, fq, ready, pay, cyc, words, stall_period, stall_phase):
    """``Sink.evaluate`` + commit; the optional stall refuses cycles off the periodic pattern."""
    h, w = words.shape
    received = bs[B_SINK, BC_S0]
    if received >= h * w:
        return _report(bs, B_SINK, A_IDLE, -1)
    if stall_period > 0 and cyc % stall_period != stall_phase:
        return _report(bs, B_SINK, A_IDLE, -1)
    if not _can_pop(fq, ready, F_SINK, cyc):
        return _report(bs, B_SINK, A_STARVED, F_SINK)
    fq[F_SINK, FC_POP_ST] = 1
    words[bs[B_SINK, BC_S0Y], bs[B_SINK, BC_S0X]] = pay[_head(fq, F_SINK)]
    _advance(bs, B_SINK, BC_S0, BC_S0X, w)
    if bs[B_SINK, BC_S1] < 0:
        bs[B_SINK, BC_S1] = cyc
    bs[B_SINK, BC_S2] = cyc
    return _report(bs, B_SINK, A_BUSY, -1)


# ---- quiet stretches -----------------------------------------------------------------------
#
# A domain whose blocks would repeat their last activity edge after edge -- the NNA counting
# MAC cycles, the SVA starved, a camera in blanking -- is *parked*: its edges are not stepped
# one by one but settled in bulk (:func:`_settle`) when something can change what they do: the
# domain's own next event (its *wake* edge: a MAC phase ending, a FIFO head becoming visible, a
# free slot being seen, a pending output falling due, a throttle or blanking ending, the cycle
# budget), or a push or pop committed by another domain on a FIFO the parked domain touches
# (settled first, up to and including that instant, so the commit sees the cycle counts the
# step-by-step engine would have; the domain then parks again at once if it still can). Settling
# adds per edge exactly what a step would: the blocks' activity counts, the NNA's MAC phase, the
# FIFOs' histogram, empty and full counts, the free slots the producer sees. The predictions
# below read the state after a step's commit and mirror the evaluations above: what each block
# would report at every edge from the next one until the wake edge, at which it may act.

INF = 1 << 62


@njit(cache=True, _nrt=False, inline="always")
def _edge_time(dom, d, k):
    """Instant of edge ``k`` of domain ``d`` (INF for INF)."""
    if k >= INF:
        return INF
    return dom[d, DC_PHASE] + k * dom[d, DC_PERIOD]


@njit(cache=True, _nrt=False, inline="always")
def _ready_at(fq, ready, f):
    """Consumer cycle from which FIFO ``f``'s head item is visible (INF if it is empty)."""
    if fq[f, FC_ICOUNT] == 0:
        return INF
    return ready[fq[f, FC_OFF] + fq[f, FC_IHEAD]]


@njit(cache=True, _nrt=False, inline="always")
def _space_at(fq, frees, f, c1):
    """Producer cycle (>= c1) from which FIFO ``f`` has a slot the producer sees (INF: not
    before a pop that has not happened)."""
    if fq[f, FC_PUSHES] - fq[f, FC_SEEN] < fq[f, FC_DEPTH]:
        return c1
    if fq[f, FC_FCOUNT] == 0:
        return INF
    return max(frees[fq[f, FC_OFF] + fq[f, FC_FHEAD]], c1)


@njit(cache=True, _nrt=False, inline="always")
def _memory_quiet(bs, fq, frees, b, f, c1, n, freq_hz, bytes_per_s):
    """(status, waited FIFO, wake cycle) of a memory source from cycle c1 on; wake <= c1: it
    acts at c1."""
    sent = bs[b, BC_S0]
    if sent >= n:
        return A_IDLE, -1, INF
    if bytes_per_s < freq_hz and (sent + 1) * freq_hz > (c1 + 1) * bytes_per_s:
        # the bucket allows the next pixel from cycle ceil((sent + 1) * f / bw) - 1 on
        return A_BUSY, -1, ((sent + 1) * freq_hz + bytes_per_s - 1) // bytes_per_s - 1
    return A_BLOCKED, f, _space_at(fq, frees, f, c1)


@njit(cache=True, _nrt=False, inline="always")
def _camera_quiet(c1, line_clocks, h, w):
    line = c1 // line_clocks
    if line >= h:
        return A_IDLE, -1, INF
    if c1 - line * line_clocks < w:
        return A_BUSY, -1, c1  # an active pixel: it pushes
    return A_BUSY, -1, (line + 1) * line_clocks  # blanking until the next line


@njit(cache=True, _nrt=False, inline="always")
def _nna_quiet(bs, fq, ready, frees, b, side, c1, h, w, timing):
    half, rows, cpd = timing[0], timing[1], timing[2]
    f_in = F_SRC_L if side == 0 else F_SRC_R
    f_out = F_NNA_L if side == 0 else F_NNA_R
    n = h * w
    received = bs[b, BC_S0]
    emitted = bs[b, BC_S1]
    phase = bs[b, BC_S2]
    wake = INF
    if received < n:
        y_out = bs[b, BC_S1Y]
        if y_out >= h or bs[b, BC_S0Y] - max(0, y_out - half) + 1 <= rows:
            wake = _ready_at(fq, ready, f_in)  # the line buffer pops from then on
    if emitted < n:
        y = bs[b, BC_S1Y]
        if phase == 0 and bs[b, BC_S0Y] - 1 < min(y + half, h - 1):
            return A_STARVED, f_in, wake
        if phase + 1 >= cpd:
            if phase < cpd:
                return A_BUSY, -1, c1  # a push attempt
            return A_BLOCKED, f_out, min(wake, _space_at(fq, frees, f_out, c1))
        return A_BUSY, -1, min(wake, c1 + cpd - 1 - phase)
    if received < n:
        return A_STARVED, f_in, wake
    return A_IDLE, -1, INF


@njit(cache=True, _nrt=False, inline="always")
def _sva_quiet(bs, fq, ready, frees, c1, ready_cycle, h, w, timing):
    lookahead, latency, cpp = timing[0], timing[1], timing[2]
    n = h * w
    wake = INF
    wait = -1
    if bs[B_SVA, BC_S0] < n and bs[B_SVA, BC_S0Y] <= bs[B_SVA, BC_S1Y] + lookahead + 1:
        r_l = _ready_at(fq, ready, F_NNA_L)
        r_r = _ready_at(fq, ready, F_NNA_R)
        if r_l <= c1 and r_r <= c1:
            return A_BUSY, -1, c1  # pops a pair
        wait = F_NNA_L if r_l > c1 else F_NNA_R
        if r_l > c1:
            wake = min(wake, r_l)
        if r_r > c1:
            wake = min(wake, r_r)
    if bs[B_SVA, BC_S1] < n:
        y = bs[B_SVA, BC_S1Y]
        if y < bs[B_SVA, BC_S3]:
            due = max(ready_cycle[y] + latency, bs[B_SVA, BC_S2] + cpp)
            if c1 < due:
                return A_BUSY, -1, min(wake, due)
            return A_BLOCKED, F_SINK, min(wake, _space_at(fq, frees, F_SINK, c1))
        return A_STARVED, (wait if wait >= 0 else F_NNA_L), wake
    return A_IDLE, -1, wake


@njit(cache=True, _nrt=False, inline="always")
def _sink_quiet(bs, fq, ready, c1, total):
    if bs[B_SINK, BC_S0] >= total:
        return A_IDLE, -1, INF
    return A_STARVED, F_SINK, max(_ready_at(fq, ready, F_SINK), c1)


@njit(cache=True, _nrt=False, inline="always")
def _try_park(d, dom, fq, rings, bs, bdom, h, w, nna_timing, sva_timing, ready_cycle,
              src_params, stall_period):
    """Park domain ``d`` (after a step or a settlement) if each of its blocks would report one
    status edge after edge, acting at none, for at least its next edge; True if parked."""
    is_camera, freq_hz, bytes_per_s, line_clocks = (src_params[0], src_params[1],
                                                    src_params[2], src_params[3])
    ready, frees = rings[0], rings[3]
    c1 = dom[d, DC_CYCLES]
    wake = INF
    busy = False
    for b in range(6):
        if bdom[b] != d:
            continue
        if b == B_SRC_L or b == B_SRC_R:
            if is_camera:
                st, wt, wk = _camera_quiet(c1, line_clocks, h, w)
            else:
                st, wt, wk = _memory_quiet(bs, fq, frees, b, F_SRC_L if b == B_SRC_L else F_SRC_R,
                                           c1, h * w, freq_hz, bytes_per_s)
        elif b == B_NNA_L or b == B_NNA_R:
            st, wt, wk = _nna_quiet(bs, fq, ready, frees, b, 0 if b == B_NNA_L else 1, c1, h, w,
                                    nna_timing)
        elif b == B_SVA:
            st, wt, wk = _sva_quiet(bs, fq, ready, frees, c1, ready_cycle, h, w, sva_timing)
        else:
            if stall_period > 0:
                return False
            st, wt, wk = _sink_quiet(bs, fq, ready, c1, h * w)
        if wk <= c1:
            return False
        bs[b, BC_PSTATUS] = st
        bs[b, BC_PWAIT] = wt
        wake = min(wake, wk)
        busy = busy or st == A_BUSY
    for f in range(fq.shape[0]):
        # a producer that sees its FIFO full counts 'full' per edge until a free slot shows
        if fq[f, FC_SRC] == d and fq[f, FC_PUSHES] - fq[f, FC_SEEN] >= fq[f, FC_DEPTH]:
            wake = min(wake, _space_at(fq, frees, f, c1))
    if dom[d, DC_LIMIT] >= 0:
        wake = min(wake, dom[d, DC_LIMIT])
    if wake <= c1:
        return False
    dom[d, DC_PARKED] = 1
    dom[d, DC_WAKE] = wake
    dom[d, DC_PBUSY] = 1 if busy else 0
    return True


@njit(cache=True, _nrt=False)
def _settle(d, t_lim, g, dom, fq, rings, bs, bdom, hold):
    """Run parked domain ``d``'s edges before the instant ``t_lim`` in bulk and unpark it
    (``hold``: the trace's push/pop flags, cleared: a parked domain moves nothing)."""
    dom[d, DC_PARKED] = 0
    nxt = dom[d, DC_NEXT]
    if t_lim <= nxt:
        return
    ready, frees, hist = rings[0], rings[3], rings[4]
    per = dom[d, DC_PERIOD]
    n = (t_lim - nxt + per - 1) // per
    c0 = dom[d, DC_CYCLES]
    c_last = c0 + n - 1
    t_last = nxt + (n - 1) * per
    for b in range(6):
        if bdom[b] == d:
            st = bs[b, BC_PSTATUS]
            bs[b, BC_STATUS] = st
            bs[b, BC_WAIT] = bs[b, BC_PWAIT]
            bs[b, BC_BUSY + st] += n
            if (b == B_NNA_L or b == B_NNA_R) and st == A_BUSY:
                bs[b, BC_S2] += n  # MAC phases
    for f in range(fq.shape[0]):
        depth = fq[f, FC_DEPTH]
        off = fq[f, FC_OFF]
        if fq[f, FC_SRC] == d:
            hold[f, H_PUSH] = 0
            if fq[f, FC_PUSHES] - fq[f, FC_SEEN] >= depth:
                fq[f, FC_FULL] += n  # (no free slot shows before the wake edge)
            while fq[f, FC_FCOUNT] > 0 and frees[off + fq[f, FC_FHEAD]] <= c_last:
                fq[f, FC_FHEAD] = _wrap(fq[f, FC_FHEAD] + 1, depth)
                fq[f, FC_FCOUNT] -= 1
                fq[f, FC_SEEN] += 1
        if fq[f, FC_DST] == d:
            hold[f, H_POP] = 0
            hist[fq[f, FC_HOFF] + fq[f, FC_PUSHES] - fq[f, FC_POPS]] += n
            if fq[f, FC_ICOUNT] == 0:
                fq[f, FC_EMPTY] += n
            else:
                fq[f, FC_EMPTY] += min(n, max(0, ready[off + fq[f, FC_IHEAD]] - c0))
    dom[d, DC_CYCLES] = c0 + n
    dom[d, DC_NEXT] = nxt + n * per
    if t_last > g[G_NOW]:
        g[G_NOW] = t_last
    if dom[d, DC_PBUSY] and t_last > g[G_TLP]:
        g[G_TLP] = t_last


@njit(cache=True, _nrt=False)
def _settle_all(t_lim, g, dom, fq, rings, bs, bdom, hold):
    for d in range(dom.shape[0]):
        if dom[d, DC_PARKED]:
            _settle(d, t_lim, g, dom, fq, rings, bs, bdom, hold)


# ---- traces --------------------------------------------------------------------------------


@njit(cache=True, _nrt=False, inline="always")
def _status_code(st):
    """Block status as traced: 0 idle, 1 busy, 2 starved, 3 blocked (ACTIVITIES index + 1 mod 4;
    never clocked: idle)."""
    return np.uint64(0) if st < 0 else np.uint64((st + 1) % 4)


@njit(cache=True, _nrt=False)
def _trace_sample(vals, bs, fq, hold, hold_desc, h, half, word_mask):
    """The traced signals' values, in the order of :func:`trace_signals`."""
    i = 0
    for b in (B_SRC_L, B_SRC_R):
        vals[i] = _status_code(bs[b, BC_STATUS])
        vals[i + 1] = bs[b, BC_S0]
        i += 2
    for side in range(2):
        b = B_NNA_L if side == 0 else B_NNA_R
        f = F_NNA_L if side == 0 else F_NNA_R
        y_in = min(bs[b, BC_S0Y], h)
        vals[i] = _status_code(bs[b, BC_STATUS])
        vals[i + 1] = y_in
        vals[i + 2] = max(0, y_in - max(0, bs[b, BC_S1Y] - half))
        vals[i + 3] = bs[b, BC_S2]
        vals[i + 4] = min(bs[b, BC_S1Y], h)
        vals[i + 5] = bs[b, BC_S1X]
        vals[i + 6] = hold[f, H_PUSH]
        vals[i + 7] = hold_desc[f]
        i += 8
    for f in range(fq.shape[0]):
        occ = fq[f, FC_PUSHES] - fq[f, FC_POPS]
        vals[i] = occ
        vals[i + 1] = hold[f, H_PUSH]
        vals[i + 2] = hold[f, H_POP]
        vals[i + 3] = 1 if fq[f, FC_PUSHES] - fq[f, FC_SEEN] >= fq[f, FC_DEPTH] else 0
        vals[i + 4] = 1 if occ == 0 else 0
        i += 5
    vals[i] = _status_code(bs[B_SVA, BC_STATUS])
    vals[i + 1] = min(bs[B_SVA, BC_S0Y], h)
    vals[i + 2] = bs[B_SVA, BC_S0X]
    vals[i + 3] = bs[B_SVA, BC_S3]
    vals[i + 4] = min(bs[B_SVA, BC_S1Y], h)
    vals[i + 5] = bs[B_SVA, BC_S1X]
    vals[i + 6] = hold[F_SINK, H_PUSH]
    vals[i + 7] = np.uint64(hold[F_SINK, H_VALUE] & word_mask)
    vals[i + 8] = 1 if hold[F_SINK, H_PUSH] and hold[F_SINK, H_VALUE] < 0 else 0
    i += 9
    vals[i] = _status_code(bs[B_SINK, BC_STATUS])
    vals[i + 1] = bs[B_SINK, BC_S0]
    vals[i + 2] = hold[F_SINK, H_POP]


@njit(cache=True, _nrt=False, inline="always")
def _trace_record(t, tr):
    """Append the signals that changed since the last record, at instant ``t``."""
    ctl, vals, last, log_t, log_id, log_v = tr[0], tr[1], tr[2], tr[5], tr[6], tr[7]
    n = ctl[TR_COUNT]
    for k in range(vals.shape[0]):
        if vals[k] != last[k]:
            last[k] = vals[k]
            log_t[n] = t
            log_id[n] = k
            log_v[n] = vals[k]
            n += 1
    ctl[TR_COUNT] = n


# ---- the loop ------------------------------------------------------------------------------


@njit(cache=True)
def _run_loop(g, dom, fq, rings, bs, images, nna_data, sva_data, sink_data, src_params, tr):
    """Step until the sink holds the frame or an event stops the run; returns the event code.

    ``g`` global scalars, ``dom`` the domain table, ``fq``/``rings`` the FIFOs, ``bs`` the block
    table; ``src_params`` = (is_camera, freq_hz, bytes_per_s, line_clocks, watchdog).

    The steps run in :func:`_run_steps`, compiled without numba's reference counting (an atomic
    update per array per call made it six times slower) and therefore without allocations; it
    returns whenever the data kernels, which allocate, must run: a new NNA descriptor row or
    SVA output rows to finish. Both may run at any moment after their input rows are complete
    (those rows never change again), so running them between steps is exact.
    """
    pixels, row_desc, nna = nna_data[0], nna_data[1], nna_data[2]
    sva = sva_data[0]
    while True:
        event = _run_steps(g, dom, fq, rings, bs, images, nna_data, sva_data, sink_data,
                           src_params, tr)
        if event != EV_DATA:
            return event
        for side in range(2):
            _nna_prepare_row(bs, B_NNA_L if side == 0 else B_NNA_R, side, pixels, row_desc, nna)
        y = bs[B_SVA, BC_S1Y]
        if y < bs[B_SVA, BC_S3] and y >= bs[B_SVA, BC_S5]:
            _sva_advance(bs, bs[B_SVA, BC_S0Y], sva)


@njit(cache=True, _nrt=False)
def _run_steps(g, dom, fq, rings, bs, images, nna_data, sva_data, sink_data, src_params, tr):
    """The steps of :func:`_run_loop`; returns an event code (EV_DATA: run the kernels,
    EV_TRACE: the trace buffers need room)."""
    is_camera, freq_hz, bytes_per_s, line_clocks, watchdog = src_params
    left, right = images
    pixels, row_desc, nna, nna_timing = nna_data
    half = nna[0]
    sva, ready_cycle, sva_timing, scratch = sva_data
    received_data = (sva[0], sva[1], sva[2])
    q = sva[7]
    tick, staged_desc, bdom, touched = scratch
    words, stall_period, stall_phase = sink_data
    ready, pay, pay_desc, frees, hist = rings
    n_dom = dom.shape[0]
    n_fifo = fq.shape[0]
    h, w = words.shape
    total = h * w
    src_dom = D_CAM if is_camera else D_NNA
    p_max = dom[0, DC_PERIOD]
    for d in range(1, n_dom):
        p_max = max(p_max, dom[d, DC_PERIOD])
    quiet_limit = watchdog * p_max
    ctl, tr_vals, tr_last, hold, hold_desc, row_times = tr[0], tr[1], tr[2], tr[3], tr[4], tr[8]
    tracing = ctl[TR_ON] == 1
    n_sig = tr_vals.shape[0]
    word_mask = ctl[TR_WORD_MASK]
    while bs[B_SINK, BC_S0] < total:
        if tracing and ctl[TR_COUNT] + n_sig > tr[5].shape[0]:
            return EV_TRACE
        # the data kernels this state needs (their conditions as in _nna_prepare_row and
        # SvaStream.advance)
        for b in (B_NNA_L, B_NNA_R):
            y = bs[b, BC_S1Y]
            if y < h and bs[b, BC_S3] != y and bs[b, BC_S0Y] - 1 >= min(y + half, h - 1):
                return EV_DATA
        y = bs[B_SVA, BC_S1Y]
        if y < bs[B_SVA, BC_S3] and y >= bs[B_SVA, BC_S5]:
            return EV_DATA
        # the next instant: an active domain's edge or a parked domain's wake edge
        t = INF
        any_parked = False
        busy_parked = False
        for d in range(n_dom):
            if dom[d, DC_PARKED]:
                any_parked = True
                busy_parked = busy_parked or dom[d, DC_PBUSY] == 1
                t = min(t, _edge_time(dom, d, dom[d, DC_WAKE]))
            else:
                t = min(t, dom[d, DC_NEXT])
        if any_parked and not busy_parked and watchdog > 0 and t >= g[G_TLP] + quiet_limit:
            # the instant the watchdog would fire if nothing progresses (the first edge at or
            # after x; none before t unless t >= x): step it for real
            x = g[G_TLP] + quiet_limit
            t_dog = INF
            for d in range(n_dom):
                nxt = dom[d, DC_NEXT]
                per = dom[d, DC_PERIOD]
                t_dog = min(t_dog, nxt if nxt >= x else nxt + (x - nxt + per - 1) // per * per)
            if t_dog <= t:
                t = t_dog
                _settle_all(t, g, dom, fq, rings, bs, bdom, hold)
        if tracing and ctl[TR_STARTED] == 0 and t >= ctl[TR_START]:
            # the window opens: every domain steps edge by edge until it closes
            _settle_all(ctl[TR_START], g, dom, fq, rings, bs, bdom, hold)
            t = INF
            for d in range(n_dom):
                t = min(t, dom[d, DC_NEXT])
            _trace_sample(tr_vals, bs, fq, hold, hold_desc, h, half, word_mask)
            # the values at the window's start: every signal once, at the start instant
            n = ctl[TR_COUNT]
            for k in range(n_sig):
                tr_last[k] = tr_vals[k]
                tr[5][n + k] = ctl[TR_START]
                tr[6][n + k] = k
                tr[7][n + k] = tr_vals[k]
            ctl[TR_COUNT] = n + n_sig
            ctl[TR_STARTED] = 1
            ctl[TR_OUT0] = fq[F_SINK, FC_PUSHES]  # output words produced before the window
        if tracing and ctl[TR_STARTED] == 1 and ctl[TR_CLOSED] == 0 and t >= ctl[TR_END]:
            ctl[TR_OUT1] = fq[F_SINK, FC_PUSHES]  # ... and before its end
            ctl[TR_CLOSED] = 1
        in_window = tracing and ctl[TR_STARTED] == 1 and t < ctl[TR_END]
        for d in range(n_dom):
            if dom[d, DC_PARKED] and _edge_time(dom, d, dom[d, DC_WAKE]) == t:
                _settle(d, t, g, dom, fq, rings, bs, bdom, hold)
        for d in range(n_dom):
            tick[d] = dom[d, DC_PARKED] == 0 and dom[d, DC_NEXT] == t
            if tick[d] and dom[d, DC_LIMIT] >= 0 and dom[d, DC_CYCLES] >= dom[d, DC_LIMIT]:
                _settle_all(t, g, dom, fq, rings, bs, bdom, hold)
                g[G_EVENT_A] = d
                return EV_BUDGET
        g[G_NOW] = t
        for f in range(n_fifo):
            if tick[fq[f, FC_SRC]] or tick[fq[f, FC_DST]]:
                _begin_step(fq, ready, frees, hist, dom, tick, f)
        progress = False
        if tick[src_dom]:
            cyc = dom[src_dom, DC_CYCLES]
            if is_camera:
                if not _camera_eval(bs, fq, staged_desc, B_SRC_L, F_SRC_L, left, cyc,
                                    line_clocks):
                    g[G_EVENT_A] = 0
                elif not _camera_eval(bs, fq, staged_desc, B_SRC_R, F_SRC_R, right, cyc,
                                      line_clocks):
                    g[G_EVENT_A] = 1
                else:
                    g[G_EVENT_A] = -1
                if g[G_EVENT_A] >= 0:
                    g[G_EVENT_B] = cyc % line_clocks
                    g[G_EVENT_C] = cyc // line_clocks
                    g[G_EVENT_D] = cyc
                    return EV_OVERFLOW
                if bs[B_SRC_L, BC_STATUS] == A_BUSY or bs[B_SRC_R, BC_STATUS] == A_BUSY:
                    progress = True
            else:
                if _memory_eval(bs, fq, staged_desc, B_SRC_L, F_SRC_L, left, cyc, freq_hz,
                                bytes_per_s):
                    progress = True
                if _memory_eval(bs, fq, staged_desc, B_SRC_R, F_SRC_R, right, cyc, freq_hz,
                                bytes_per_s):
                    progress = True
        if tick[D_NNA]:
            cyc = dom[D_NNA, DC_CYCLES]
            for side in range(2):
                b = B_NNA_L if side == 0 else B_NNA_R
                if _nna_eval(bs, fq, ready, pay, staged_desc, b, side, cyc, pixels, row_desc,
                             nna_timing):
                    progress = True
        if tick[D_SVA]:
            cyc = dom[D_SVA, DC_CYCLES]
            if _sva_eval(bs, fq, ready, pay, pay_desc, staged_desc, cyc, ready_cycle,
                         received_data, q, sva_timing):
                progress = True
            if _sink_eval(bs, fq, ready, pay, cyc, words, stall_period, stall_phase):
                progress = True
        # a parked domain at the other end of a FIFO that moves is settled up to and including
        # this instant before the commit (and parks again after it if it can)
        for d in range(n_dom):
            touched[d] = tick[d]
        for f in range(n_fifo):
            if fq[f, FC_PUSH_ST] and dom[fq[f, FC_DST], DC_PARKED]:
                touched[fq[f, FC_DST]] = True
                _settle(fq[f, FC_DST], t + 1, g, dom, fq, rings, bs, bdom, hold)
            # (a pop only frees a slot: a parked producer that does not see its FIFO full
            # neither acts on it nor counts it before its wake; it sees the slot when settled)
            if (fq[f, FC_POP_ST] and dom[fq[f, FC_SRC], DC_PARKED]
                    and fq[f, FC_PUSHES] - fq[f, FC_SEEN] >= fq[f, FC_DEPTH]):
                touched[fq[f, FC_SRC]] = True
                _settle(fq[f, FC_SRC], t + 1, g, dom, fq, rings, bs, bdom, hold)
        if tracing:
            for f in range(n_fifo):
                if tick[fq[f, FC_SRC]]:
                    hold[f, H_PUSH] = fq[f, FC_PUSH_ST]
                    if fq[f, FC_PUSH_ST]:
                        hold[f, H_VALUE] = fq[f, FC_STAGED]
                        hold_desc[f] = staged_desc[f]
                if tick[fq[f, FC_DST]]:
                    hold[f, H_POP] = fq[f, FC_POP_ST]
        for f in range(n_fifo):
            if tick[fq[f, FC_SRC]] or tick[fq[f, FC_DST]]:
                if _commit(fq, ready, pay, pay_desc, frees, staged_desc, dom, tick, f, t):
                    progress = True
        for d in range(n_dom):
            if tick[d]:
                dom[d, DC_CYCLES] += 1
                dom[d, DC_NEXT] = t + dom[d, DC_PERIOD]
        if progress:
            g[G_TLP] = t
        elif watchdog > 0 and t - g[G_TLP] >= quiet_limit and bs[B_SINK, BC_S0] < total:
            busy_parked = False
            for d in range(n_dom):
                busy_parked = busy_parked or (dom[d, DC_PARKED] == 1 and dom[d, DC_PBUSY] == 1)
            if not busy_parked:
                _settle_all(t + 1, g, dom, fq, rings, bs, bdom, hold)
                return EV_DEADLOCK
        # row times (for windows given in rows): the instant the left line buffer reaches row
        # r, and the instant the sink holds row r - 1 complete
        y_in = bs[B_NNA_L, BC_S0Y]
        if y_in <= h and row_times[0, y_in] < 0:
            row_times[0, y_in] = t
        y_out = bs[B_SINK, BC_S0Y]
        if y_out <= h and row_times[1, y_out] < 0:
            row_times[1, y_out] = t
        if in_window:
            _trace_sample(tr_vals, bs, fq, hold, hold_desc, h, half, word_mask)
            _trace_record(t, tr)
            continue
        for d in range(n_dom):
            if touched[d]:
                _try_park(d, dom, fq, rings, bs, bdom, h, w, nna_timing, sva_timing,
                          ready_cycle, src_params, stall_period)
    _settle_all(g[G_NOW] + 1, g, dom, fq, rings, bs, bdom, hold)
    if tracing and ctl[TR_STARTED] == 1 and ctl[TR_CLOSED] == 0:
        ctl[TR_OUT1] = fq[F_SINK, FC_PUSHES]
        ctl[TR_CLOSED] = 1
    return EV_DONE


# ---- the Python side -----------------------------------------------------------------------


class _Setup:
    """Names, domains and constants of one run, as :func:`sim.cycle.chip.build_chip` would build."""

    def __init__(self, shape, cfg: ChipConfig):
        self.shape = tuple(shape)
        self.camera = cfg.source.kind == "camera"
        self.domains = chip_domains(cfg)
        src = "camera" if self.camera else "memory"
        self.block_names = (f"{src}_left", "nna_left", f"{src}_right", "nna_right", "sva",
                            "sink")
        bits = descriptor_bits(cfg.nna)
        self.bits = bits
        desc_bits = nna_to_sva_word_bits(cfg)
        word_bits = self.word_bits = output_word_bits(cfg)
        f = cfg.fifo
        src_dom = D_CAM if self.camera else D_NNA
        # name -> (depth, width, src domain, dst domain), in FIFO index order
        self.fifos = (
            (f.nna_to_sva_depth, desc_bits, D_NNA, D_SVA),
            (f.source_to_nna_depth, 8, src_dom, D_NNA),
            (f.nna_to_sva_depth, desc_bits, D_NNA, D_SVA),
            (f.source_to_nna_depth, 8, src_dom, D_NNA),
            (f.sva_to_sink_depth, word_bits, D_SVA, D_SVA),
        )
        self.budget = frame_budget(shape, cfg, self.domains)


def _sva_arrays(shape, cfg: ChipConfig, setup: _Setup):
    # uint64 for every descriptor width (the readable block uses uint32 up to 32 bits): the
    # values and so every Hamming cost are the same, and the loop compiles once
    desc_l = np.zeros(shape, np.uint64)
    desc_r = np.zeros(shape, np.uint64)
    img_l = np.zeros(shape, np.uint8)
    # SvaStream validates the configuration and builds the arguments of sva.pipeline._stream
    stream = SvaStream(desc_l, desc_r, img_l, cfg.sva, setup.bits)
    box, sgm_args, select, colsum = stream.kernel_state()
    k = cfg.sva.median
    network = selection_network(k) if k > 3 else np.zeros((0, 2), np.int64)
    return (desc_l, desc_r, img_l, box, sgm_args, select, stream.checked,
            stream.q, colsum, cfg.sva.box_size // 2, k, network)


def _nna_tables(cfg: ChipConfig):
    n = cfg.nna
    half = half_window(n)
    if n.descriptor == "census":
        offsets_a, offsets_b = census_tables(n.census)
        w_f32 = np.zeros((0, 1, 3), np.float32)
        w_i32 = np.zeros((0, 1, 3), np.int32)
        bias = np.zeros(1, np.int32)
        offset = 0
    else:
        weights, bias8, offset = layer(n)
        w_f32, w_i32, bias = cnn_tables(weights, bias8)
        offsets_a = offsets_b = np.zeros((0, 2), np.int64)
    return (np.int64(half), np.int64(n.line_buffer_rows), np.int64(cycles_per_descriptor(n)),
            n.descriptor == "cnn", offsets_a, offsets_b, w_f32, w_i32, bias, np.int32(offset))


def trace_signals(shape, cfg: ChipConfig) -> list[tuple[str, int, str]]:
    """The signals the engine traces, ``(path, width, domain)`` in the order of
    :func:`_trace_sample`: per block its status (0 idle, 1 busy, 2 starved, 3 blocked) and
    counters, per FIFO occupancy / push / pop / full (as the producer sees it) / empty, the
    descriptors and disparities with their valid pulses. A pulse or a pushed value belongs to the
    last edge of its producer's (push) or consumer's (pop) domain."""
    setup = _Setup(shape, cfg)
    h, w = shape

    def nb(n):
        return max(1, int(n).bit_length())

    src = "camera" if setup.camera else "memory"
    src_dom = "camera" if setup.camera else "nna"
    cpd = cycles_per_descriptor(cfg.nna)
    word_bits = setup.word_bits
    out = []
    for side in ("left", "right"):
        out += [(f"top.{src}_{side}.status", 2, src_dom),
                (f"top.{src}_{side}.sent", nb(h * w), src_dom)]
    for side in ("left", "right"):
        p = f"top.nna.{side}.sub0"
        out += [(f"{p}.status", 2, "nna"), (f"{p}.line_buffer.row_in", nb(h), "nna"),
                (f"{p}.line_buffer.fill", nb(cfg.nna.line_buffer_rows), "nna"),
                (f"{p}.mac.phase", nb(cpd), "nna"), (f"{p}.mac.row", nb(h), "nna"),
                (f"{p}.mac.col", nb(w), "nna"), (f"{p}.out.valid", 1, "nna"),
                (f"{p}.out.descriptor", setup.fifos[0][1], "nna")]
    for f, name in enumerate(FIFO_NAMES):
        depth, _, s_dom, d_dom = setup.fifos[f]
        dn = DOMAIN_NAMES[d_dom]
        out += [(f"top.fifo.{name}.occupancy", nb(depth), dn),
                (f"top.fifo.{name}.push", 1, DOMAIN_NAMES[s_dom]), (f"top.fifo.{name}.pop", 1, dn),
                (f"top.fifo.{name}.full", 1, DOMAIN_NAMES[s_dom]), (f"top.fifo.{name}.empty", 1, dn)]
    out += [("top.sva.status", 2, "sva"), ("top.sva.input.row", nb(h), "sva"),
            ("top.sva.input.col", nb(w), "sva"), ("top.sva.input.rows_ready", nb(h), "sva"),
            ("top.sva.output.row", nb(h), "sva"), ("top.sva.output.col", nb(w), "sva"),
            ("top.sva.output.valid", 1, "sva"), ("top.sva.output.disparity", word_bits, "sva"),
            ("top.sva.lr_check.reject", 1, "sva"),
            ("top.sink.status", 2, "sva"), ("top.sink.count", nb(h * w), "sva"),
            ("top.sink.valid", 1, "sva")]
    return out


def _trace_state(n_sig, n_fifo, window, word_bits, capacity, h):
    ctl = np.zeros(9, np.int64)
    if window is not None:
        ctl[TR_ON], ctl[TR_START], ctl[TR_END] = 1, window[0], window[1]
    ctl[TR_WORD_MASK] = (1 << word_bits) - 1
    row_times = np.full((2, h + 1), -1, np.int64)
    row_times[:, 0] = 0
    return (ctl, np.zeros(n_sig, np.uint64), np.zeros(n_sig, np.uint64),
            np.zeros((n_fifo, 3), np.int64), np.zeros(n_fifo, np.uint64),
            np.zeros(capacity, np.int64), np.zeros(capacity, np.int32),
            np.zeros(capacity, np.uint64), row_times)


def run_cycle_fast(left: np.ndarray, right: np.ndarray, cfg: ChipConfig, *,
                   sink_stall: tuple[int, int] | None = None,
                   trace_window: tuple[int, int] | None = None,
                   trace_out: dict | None = None,
                   method: str = "auto") -> tuple[np.ndarray, dict, dict]:
    """Simulate one frame on the compiled engine: ``(words (H, W) int32, cycle report, stats)``.

    ``method``: ``"auto"`` computes an untraced frame with the schedule engine
    (:mod:`sim.cycle.schedule`: every beat's cycle from closed-form recurrences) and steps edge by edge
    (this module's loop) only where that engine does not answer -- a traced window, or a run that
    stops early (overflow, deadlock, budget, watchdog), which the steps report exactly;
    ``"steps"`` always steps. Both give the same result wherever both answer.

    Equal to :func:`sim.cycle.chip.run_cycle` in the words, in the report (:func:`sim.cycle.chip.cycle_report`)
    and in ``chip.sim.stats()``; raises the same :class:`~sim.cycle.blocks.sources.CameraOverflow`,
    :class:`~sim.cycle.clock.DeadlockError` and :class:`~sim.cycle.clock.BudgetExceeded`. ``sink_stall``:
    ``(period, allowed_phase)`` -- the sink pops only in cycles ``c`` with
    ``c % period == allowed_phase`` (``Sink(stall=lambda c: c % period != allowed_phase)``).

    ``trace_window=(start_fs, end_fs)``: record the signals of :func:`trace_signals` over that
    window (every edge in it is stepped) into ``trace_out``: ``signals``, ``initial`` (values at
    ``start_fs``), ``times_fs``, ``ids``, ``values`` (changes, in time order), ``domains`` (name,
    period, phase). Tracing changes nothing else: the words, the report and the statistics are
    the same with and without it.
    """
    if cfg.nna.stereo_submodules != 2:
        raise ConfigError(
            f"the compiled steps model one NNA submodule per camera; nna.stereo_submodules="
            f"{cfg.nna.stereo_submodules} runs on sim.cycle.chip.simulate (sim.engine=auto: the "
            "schedule engine) or sim.engine=readable"
        )
    if method not in ("auto", "steps"):
        raise ConfigError(f"method must be 'auto' or 'steps'; got {method!r}")
    left = np.ascontiguousarray(left, np.uint8)
    right = np.ascontiguousarray(right, np.uint8)
    shape = left.shape
    h, w = shape
    if right.shape != shape:
        raise ConfigError(f"left {shape} and right {right.shape} images differ in shape")
    stall_period, stall_phase = (0, 0) if sink_stall is None else sink_stall
    if sink_stall is not None and not (stall_period >= 1 and 0 <= stall_phase < stall_period):
        raise ConfigError(
            f"sink_stall must be (period >= 1, 0 <= allowed_phase < period); got {sink_stall!r}"
        )
    if method == "auto" and trace_window is None:
        done = run_schedule(left, right, cfg, sink_stall=sink_stall, trace_out=trace_out)
        if done is not None:
            return done
    setup = _Setup(shape, cfg)
    names = list(setup.domains)
    dom = np.zeros((len(names), N_DC), np.int64)
    for i, name in enumerate(names):
        d = setup.domains[name]
        dom[i, :DC_PARKED] = (d.period_fs, d.phase_fs, 0, d.phase_fs,
                              setup.budget.get(name, -1))
    n_f = len(setup.fifos)
    fq = np.zeros((n_f, N_FC), np.int64)
    off = hoff = 0
    for i, (depth, _, src, dst) in enumerate(setup.fifos):
        crossing = src != dst
        fq[i, FC_DEPTH] = depth
        fq[i, FC_DATA_EDGES] = cfg.fifo.latency_cycles + (
            cfg.fifo.sync_cycles - 1 if crossing else 0)
        fq[i, FC_SPACE_EDGES] = cfg.fifo.sync_cycles if crossing else 1
        fq[i, FC_SRC], fq[i, FC_DST] = src, dst
        fq[i, FC_OFF], fq[i, FC_HOFF] = off, hoff
        off += depth
        hoff += depth + 1
    rings = (np.zeros(off, np.int64), np.zeros(off, np.int64), np.zeros(off, np.uint64),
             np.zeros(off, np.int64), np.zeros(hoff, np.int64))
    bs = np.zeros((6, N_BC), np.int64)
    bs[:, BC_STATUS] = -1
    bs[:, BC_WAIT] = -1
    bs[B_NNA_L, BC_S3] = bs[B_NNA_R, BC_S3] = -1
    bs[B_SVA, BC_S2] = -(1 << 40)
    bs[B_SINK, BC_S1] = bs[B_SINK, BC_S2] = -1
    g = np.zeros(N_G, np.int64)
    # the watchdog counts from one slowest period before the first edge (sim.cycle.clock.run)
    g[G_TLP] = int(dom[:, DC_PHASE].min() - dom[:, DC_PERIOD].max())
    nna = _nna_tables(cfg)
    nna_data = (np.zeros((2, h, w), np.uint8), np.zeros((2, w), np.uint64), nna,
                np.array(nna[:3], np.int64))
    sva = _sva_arrays(shape, cfg, setup)
    lookahead = cfg.sva.box_size // 2 + (cfg.sva.median // 2 if cfg.sva.median > 1 else 0)
    timing = np.array([lookahead, cfg.sva.pipeline_latency, cfg.sva.cycles_per_pixel], np.int64)
    # the loop allocates nothing (it runs without numba's reference counting)
    src_dom = D_CAM if setup.camera else D_NNA
    block_domain = np.array([src_dom, D_NNA, src_dom, D_NNA, D_SVA, D_SVA], np.int64)
    scratch = (np.zeros(len(names), np.bool_), np.zeros(n_f, np.uint64), block_domain,
               np.zeros(len(names), np.bool_))
    sva_data = (sva, np.full(h, -1, np.int64), timing, scratch)
    words = np.full(shape, -1, np.int32)
    sink_data = (words, np.int64(stall_period), np.int64(stall_phase))
    src_freq = setup.domains["camera" if setup.camera else "nna"].freq_hz
    src_params = (setup.camera, np.int64(round(src_freq)),
                  np.int64(round(cfg.source.memory_gbps * 1e9)),
                  np.int64(w + cfg.source.camera_hblank), np.int64(cfg.sim.watchdog_cycles))
    # (the signal table only when tracing: an untraced run samples nothing)
    signals = trace_signals(shape, cfg) if trace_window is not None else []
    tr = _trace_state(len(signals), n_f, trace_window, setup.word_bits,
                      1 << 16 if trace_window is not None else 0, h)
    while True:
        event = _run_loop(g, dom, fq, rings, bs, (left, right), nna_data, sva_data, sink_data,
                          src_params, tr)
        if event != EV_TRACE:
            break
        n_log = int(tr[0][TR_COUNT])
        grown = [np.zeros(2 * a.shape[0] + len(signals), a.dtype) for a in tr[5:8]]
        for new, old in zip(grown, tr[5:8]):
            new[:n_log] = old[:n_log]
        tr = (*tr[:5], *grown, tr[8])
    if trace_out is not None:
        trace_out["row_times"] = tr[8].copy()
    if trace_window is not None and trace_out is not None:
        n_log = int(tr[0][TR_COUNT])
        n_sig = len(signals)
        started = bool(tr[0][TR_STARTED])
        trace_out.update(
            signals=signals, started=started,
            outputs_in_window=int(tr[0][TR_OUT1] - tr[0][TR_OUT0]),
            initial=tr[7][:n_sig].copy() if started else None,
            times_fs=tr[5][n_sig:n_log].copy(), ids=tr[6][n_sig:n_log].copy(),
            values=tr[7][n_sig:n_log].copy(),
            domains=[(n, setup.domains[n].period_fs, setup.domains[n].phase_fs)
                     for n in setup.domains])
    state = _State(setup, cfg, g, dom, fq, rings, bs)
    if event == EV_OVERFLOW:
        side = "left" if g[G_EVENT_A] == 0 else "right"
        raise CameraOverflow(
            f"camera '{setup.block_names[2 * g[G_EVENT_A]]}' overflowed FIFO src_{side}_to_nna "
            f"at pixel ({g[G_EVENT_B]}, {g[G_EVENT_C]}), cycle {g[G_EVENT_D]}: the NNA does not "
            "keep up with the camera; use a slower camera, more NNA throughput (clocks.nna_mhz, "
            "nna.macs) or a deeper fifo.source_to_nna_depth"
        )
    if event == EV_DEADLOCK:
        raise state.stop(DeadlockError, "deadlock",
                         watchdog_message(int(g[G_NOW] - g[G_TLP]), int(dom[:, DC_PERIOD].max())))
    if event == EV_BUDGET:
        d = names[g[G_EVENT_A]]
        raise state.stop(
            BudgetExceeded, "cycle budget exceeded",
            f"{d} ran its budget of {setup.budget[d]} cycles before the until condition held: "
            "raise budget_cycles or check the until condition",
        )
    stats = state.stats()
    return words, fast_report(state, stats), stats


class _State:
    """The engine's arrays after a run, read back as the readable engine's dicts."""

    def __init__(self, setup: _Setup, cfg: ChipConfig, g, dom, fq, rings, bs):
        self.setup, self.cfg, self.g, self.dom, self.fq, self.rings, self.bs = (
            setup, cfg, g, dom, fq, rings, bs)

    def cycles(self) -> dict[str, int]:
        return {name: int(self.dom[i, DC_CYCLES]) for i, name in enumerate(self.setup.domains)}

    def activity(self, b: int) -> dict[str, int]:
        return {a: int(self.bs[b, BC_BUSY + ACTIVITIES.index(a)]) for a in sorted(ACTIVITIES)}

    def fifo_stats(self, f: int) -> dict:
        fq = self.fq
        depth, width, _, _ = self.setup.fifos[f]
        hist = self.rings[4][fq[f, FC_HOFF]:fq[f, FC_HOFF] + depth + 1]
        return {
            "bits_transferred": int(fq[f, FC_POPS]) * width,
            "cycles_empty": int(fq[f, FC_EMPTY]),
            "cycles_full": int(fq[f, FC_FULL]),
            "depth": depth,
            "max_occupancy": int(fq[f, FC_MAXOCC]),
            "max_producer_occupancy": int(fq[f, FC_MAXPROD]),
            "occupancy_histogram": [int(v) for v in hist],
            "pops": int(fq[f, FC_POPS]),
            "pushes": int(fq[f, FC_PUSHES]),
            "width_bits": width,
        }

    def stats(self) -> dict:
        """The shape of ``Simulator.stats()``."""
        names = self.setup.block_names
        return {
            "blocks": {n: self.activity(names.index(n)) for n in sorted(names)},
            "cycles": dict(sorted(self.cycles().items())),
            "end_time_fs": int(self.g[G_NOW]),
            "fifos": {n: self.fifo_stats(FIFO_NAMES.index(n)) for n in sorted(FIFO_NAMES)},
            "steps": count_instants([(int(p), int(per), int(n)) for per, p, n in
                                     self.dom[:, [DC_PERIOD, DC_PHASE, DC_CYCLES]]]),
        }

    def stop(self, cls, head: str, tail: str):
        """The exception ``Simulator._stop`` would raise, from the engine's state."""
        fq, bs = self.fq, self.bs
        fifos = {}
        fifo_words = []
        for f, name in enumerate(FIFO_NAMES):
            occ, depth = int(fq[f, FC_PUSHES] - fq[f, FC_POPS]), int(fq[f, FC_DEPTH])
            fifos[name] = {"occupancy": occ, "depth": depth}
            tag = " full" if occ >= depth else " empty" if occ == 0 else ""
            fifo_words.append(f"{name} {occ}/{depth}{tag}")
        blocks = {}
        block_words = []
        for b, name in enumerate(self.setup.block_names):
            status = ACTIVITIES[bs[b, BC_STATUS]] if bs[b, BC_STATUS] >= 0 else None
            waiting = None
            if bs[b, BC_WAIT] >= 0:
                waiting = (FIFO_NAMES[bs[b, BC_WAIT]],
                           "full" if status == "blocked" else "empty")
            blocks[name] = {"status": status, "waiting_on": waiting}
            if waiting is not None:
                block_words.append(f"{name} {status} on {waiting[0]} ({waiting[1]})")
            else:
                block_words.append(f"{name} {status or 'never clocked'}")
        now = int(self.g[G_NOW])
        cyc = ", ".join(f"{d} {n}" for d, n in self.cycles().items())
        msg = (f"{head} at t={now} fs (cycles run: {cyc}): fifo {', '.join(fifo_words)}; "
               f"blocks: {', '.join(block_words)}; {tail}")
        return cls(msg, time_fs=now, cycles=dict(sorted(self.cycles().items())), fifos=fifos,
                   blocks=blocks)


def fast_report(state: _State, stats: dict) -> dict:
    """The dict of :func:`sim.cycle.chip.cycle_report`, from the engine's arrays."""
    setup, cfg, bs = state.setup, state.cfg, state.bs
    src_domain = setup.domains["camera" if setup.camera else "nna"]
    nna, sva = setup.domains["nna"], setup.domains["sva"]
    cpd = cycles_per_descriptor(cfg.nna)
    h, w = state.setup.shape
    if setup.camera:  # a camera's frame period, vertical blanking included (CameraSource)
        src_work = (h + cfg.source.camera_vblank) * (w + cfg.source.camera_hblank)
        src_l = src_r = src_work
    else:
        src_l, src_r = int(bs[B_SRC_L, BC_BUSY]), int(bs[B_SRC_R, BC_BUSY])
    work = {
        B_SRC_L: (src_l, src_domain.freq_hz),
        B_NNA_L: (int(bs[B_NNA_L, BC_S1]) * cpd, nna.freq_hz),
        B_SRC_R: (src_r, src_domain.freq_hz),
        B_NNA_R: (int(bs[B_NNA_R, BC_S1]) * cpd, nna.freq_hz),
        B_SVA: (int(bs[B_SVA, BC_S1]) * cfg.sva.cycles_per_pixel, sva.freq_hz),
    }
    return assemble_report(sva, int(bs[B_SINK, BC_S1]), int(bs[B_SINK, BC_S2]),
                           {setup.block_names[b]: v for b, v in work.items()}, stats)
