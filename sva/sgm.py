"""Semi-Global Matching over the causal raster-scan paths -- the third SVA stage.

Hirschmueller (2008), eq. 13, along a path direction r:

    L_r(p, d) = A(p, d) + min( L_r(p-r, d),
                               L_r(p-r, d-1) + P1,
                               L_r(p-r, d+1) + P1,
                               min_k L_r(p-r, k) + P2 )  -  min_k L_r(p-r, k)

    S(p, d) = sum_r L_r(p, d)

A chip that receives pixels in raster order can only use the directions whose predecessor p - r
has already arrived: left-to-right, top-to-bottom, top-left-to-bottom-right and
top-right-to-bottom-left. ``sva.paths`` = n uses the first n of :data:`PATHS` in that order.

Integer definition (the chip's):
- where p - r lies outside the image, L_r(p, d) = A(p, d) (the path starts there);
- terms d - 1 < 0 and d + 1 >= D are absent from the minimum;
- L_r saturates at 2^path_bits - 1 and S at 2^sum_bits - 1 (both unsigned);
- with ``p2_adaptive`` the P2 used on the step from p - r to p is
  max(P1, P2 - ((p2_slope * |I(p) - I(p-r)|) >> 4)), I the left grey image.
"""

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from stereosim.quant.vectors import VectorCode, contiguous_rows
from stereosim.sim.errors import InputError
from stereosim.sim.kernel_cache import njit

# (dx, dy) of the predecessor p - r, in the order ``sva.paths`` enables them.
PATHS = ((-1, 0), (0, -1), (-1, -1), (1, -1))
PATH_NAMES = ("left_to_right", "top_to_bottom", "topleft_to_bottomright", "topright_to_bottomleft")


def effective_p2(p1: int, p2: int, adaptive: bool, slope: int, i_p: int, i_prev: int) -> int:
    """The P2 used on one path step (see the module docstring)."""
    if not adaptive:
        return p2
    return max(p1, p2 - ((slope * abs(int(i_p) - int(i_prev))) >> 4))


def sgm_ref(
    agg,
    *,
    p1: int,
    p2: int,
    paths: int,
    path_bits: int,
    sum_bits: int,
    img=None,
    p2_adaptive: bool = False,
    p2_slope: int = 16,
) -> np.ndarray:
    """Naive reference: S (H, W, D) as uint16, one path at a time, exactly as the equation."""
    h, w, dn = agg.shape
    path_cap = (1 << path_bits) - 1
    sum_cap = (1 << sum_bits) - 1
    total = np.zeros((h, w, dn), np.int64)
    for dx, dy in PATHS[:paths]:
        lr = np.zeros((h, w, dn), np.int64)
        for y in range(h):
            for x in range(w):
                px, py = x + dx, y + dy
                if not (0 <= px < w and 0 <= py < h):
                    for d in range(dn):
                        lr[y, x, d] = min(int(agg[y, x, d]), path_cap)
                    continue
                prev = lr[py, px]
                m = int(prev.min())
                pen2 = p2
                if img is not None:
                    pen2 = effective_p2(p1, p2, p2_adaptive, p2_slope, img[y, x], img[py, px])
                for d in range(dn):
                    best = int(prev[d])
                    if d > 0:
                        best = min(best, int(prev[d - 1]) + p1)
                    if d < dn - 1:
                        best = min(best, int(prev[d + 1]) + p1)
                    best = min(best, m + pen2)
                    lr[y, x, d] = min(int(agg[y, x, d]) + best - m, path_cap)
        total += lr
    return np.minimum(total, sum_cap).astype(np.uint16)


# Sentinel for the absent neighbours d - 1 < 0 and d + 1 >= D: above every legal path cost
# (path_bits <= 14), and sentinel + P1 still fits in uint16 (P1 <= 2^15 - 1). With
# path_bits <= 14 the sum of four paths also fits uint16 before the sum saturates.
ABSENT = 0x7FFF


def new_path_buffers(width: int, disparities: int):
    """State of the streaming SGM: ``(buf, mins, phase)``.

    ``buf`` (3 W + 6, D + 2) uint16 holds every path row the kernel reads or writes, laid out
    so that a pixel's predecessor rows and output rows are always different rows: the d-loop
    of :func:`sgm_pixel` then reads every predecessor and writes every output in one pass
    (no copies, no in-place hazard), and the choice of rows is scalar arithmetic:

    - rows 0 .. W: the top path, a ring of W + 1 slots, entry (y, x) in slot (x - y) mod
      (W + 1): pixel (y, x) reads (y - 1, x) one slot ahead and overwrites (y - 1, x - 1),
      which pixel x - 1 has consumed;
    - rows W + 1 .. 2 W + 2: the top-left path, a ring of W + 2 slots, (y, x) in slot
      (x - 2 y) mod (W + 2): it reads (y - 1, x - 1) one slot ahead and overwrites
      (y - 1, x - 2), consumed by pixel x - 1;
    - rows 2 W + 3 .. 3 W + 2: the top-right path, (y, x) in slot x: it reads (y - 1, x + 1)
      and overwrites (y - 1, x), consumed by pixel x - 1;
    - 3 W + 3, 3 W + 4: the left path's ping-pong;
    - 3 W + 5: all-zero costs, the predecessor of a path start: from a zero predecessor
      (minimum 0) the step gives min(A + min(0, ABSENT + P1, P2), cap) = min(A, cap).

    ``mins`` (3 W + 7,) uint16: the minimum over d of each row, and a last entry nobody
    reads (see :func:`_paths4`). Costs live at [1, D]; entries 0 and D + 1 stay ABSENT so
    the d-loop has no branches. ``phase`` (2,) int64: the ring offsets of the row in
    progress, y mod (W + 1) and 2 y mod (W + 2) (:func:`sgm_row_start`).
    """
    buf = np.full((3 * width + 6, disparities + 2), ABSENT, np.uint16)
    buf[3 * width + 5, 1:-1] = 0
    return buf, np.zeros(3 * width + 7, np.uint16), np.zeros(2, np.int64)


@njit(cache=True, inline="always")
def _p2_at(p1, p2, adaptive, slope, i_p, i_prev):
    if not adaptive:
        return np.uint16(p2)
    diff = np.int64(i_p) - np.int64(i_prev)
    if diff < 0:
        diff = -diff
    pen2 = np.int64(p2) - ((np.int64(slope) * diff) >> 4)
    return np.uint16(max(p1, pen2))


@njit(cache=True, inline="always")
def _lane(c, below, here, above, p1, jump, mp, cap):
    """One d of one path step: min(c + min(L(d), min(L(d-1), L(d+1)) + P1, m + P2) - m, cap).

    Exact in uint16: L(d +- 1) + P1 <= ABSENT + P1 < 2^16; the inner minimum ``best`` lies
    in m .. m + P2, and c <= cap < 2^14 (the callers clamp it), so c + (best - m) < 2^16."""
    best = min(here, np.uint16(min(below, above) + p1))
    best = min(best, jump)
    return min(np.uint16(c + np.uint16(best - mp)), cap)


@njit(cache=True)
def sgm_row_start(y, state):
    """Set the ring offsets of row ``y`` (call before its first :func:`sgm_pixel`)."""
    buf = state[0]
    phase = state[2]
    w = (buf.shape[0] - 6) // 3
    phase[0] = y % (w + 1)
    phase[1] = (2 * y) % (w + 2)


@njit(cache=True, inline="always")
def _ring_slots(x, offset, n):
    """(slot of the entry written at x, slot of its predecessor one ahead) in a ring of n:
    (x - offset) mod n and (x - offset + 1) mod n, 0 <= offset < n, without a division."""
    out = x - offset
    out += n if out < 0 else 0
    pred = out + 1
    pred -= n if pred >= n else 0
    return out, pred


@njit(cache=True, inline="always")
def sgm_pixel(c, x, y, img_row, img_prev, state, params, s_out):
    """Every enabled path at pixel (x, y) of a raster scan; S into ``s_out``, returns min S.

    ``c`` (D,) uint16: the aggregated cost, already clamped to the path cap. ``state`` is
    :func:`new_path_buffers` (ring offsets set by :func:`sgm_row_start` for row y),
    ``params`` = (paths, p1, p2, adaptive, slope, path_cap, sum_cap) with p1, p2 and the caps
    as uint16 (:func:`sgm_params`). Pixels must come in raster order (x = 0..W-1 per row).
    ``s_out[d]`` = min(sum of the enabled paths' L_r(p, d), sum_cap).

    One d-loop computes every enabled path, their minima, S and its minimum, so each
    predecessor row is read and each output row written once, in uint16 lanes (:func:`_lanes`
    in explicit vectors of LANES disparities, a scalar loop for the rest).
    """
    _, mins, phase = state
    paths, p1, p2, adaptive, slope, _, _ = params
    w = img_row.shape[0]
    top_left = w + 1
    top_right = 2 * w + 3
    left = 3 * w + 3
    zero = 3 * w + 5
    i_p = img_row[x]
    # path 0: left to right, predecessor (x - 1, y)
    pred0 = zero if x == 0 else left + 1 - (x & 1)
    out0 = left + (x & 1)
    pen0 = _p2_at(p1, p2, adaptive, slope, i_p, img_row[max(x - 1, 0)])
    # path 1: top to bottom, predecessor (x, y - 1)
    out1, pred1 = _ring_slots(x, phase[0], w + 1)
    pred1 = pred1 if y > 0 else zero
    pen1 = _p2_at(p1, p2, adaptive, slope, i_p, img_prev[x])
    # path 2: top-left to bottom-right, predecessor (x - 1, y - 1)
    out2, pred2 = _ring_slots(x, phase[1], w + 2)
    out2 += top_left
    pred2 = top_left + pred2 if y > 0 and x > 0 else zero
    pen2 = _p2_at(p1, p2, adaptive, slope, i_p, img_prev[max(x - 1, 0)])
    # path 3: top-right to bottom-left, predecessor (x + 1, y - 1)
    out3 = top_right + x
    pred3 = top_right + x + 1 if y > 0 and x < w - 1 else zero
    pen3 = _p2_at(p1, p2, adaptive, slope, i_p, img_prev[min(x + 1, w - 1)])
    # (predecessor rows, output rows, m + P2 per path)
    step = (
        (pred0, pred1, pred2, pred3),
        (out0, out1, out2, out3),
        (
            np.uint16(mins[pred0] + pen0),
            np.uint16(mins[pred1] + pen1),
            np.uint16(mins[pred2] + pen2),
            np.uint16(mins[pred3] + pen3),
        ),
    )
    # one d-loop per path count, each run over D or 0 disparities (a loop cannot skip a path
    # without a branch per d); with 0, _lanes skips its work and the rest is scalar
    dn = c.shape[0]
    s1 = _paths4(c, state, step, params, s_out, dn if paths == 4 else 0)
    s1 = min(s1, _paths3(c, state, step, params, s_out, dn if paths == 3 else 0))
    s1 = min(s1, _paths2(c, state, step, params, s_out, dn if paths == 2 else 0))
    s1 = min(s1, _paths1(c, state, step, params, s_out, dn if paths == 1 else 0))
    return s1


# uint16 lanes of one step of :func:`_lanes` (512 bits)
LANES = 32


def _lanes_codegen(paths: int):
    """The code of :func:`_lanes` for ``paths`` paths: per chunk of LANES disparities, the
    operations of :func:`_lane` on every path (:class:`~quant.vectors.VectorCode`), each path's
    new row stored, their running minima and S's kept in vectors and reduced once at the end;
    nothing at all when there is no chunk."""

    def codegen(context, builder, signature, args):
        c_v, pred_v, out_v, s_v, scal_v, chunks = args
        c_t, pred_t, out_t, s_t = signature.args[:4]
        code = VectorCode(context, builder, 16, LANES)
        c_p, s_p = code.data(c_t, c_v), code.data(s_t, s_v)
        preds = [code.data(pred_t.dtype, builder.extract_value(pred_v, k)) for k in range(paths)]
        outs = [code.data(out_t.dtype, builder.extract_value(out_v, k)) for k in range(paths)]
        results = [cgutils.alloca_once_value(builder, ir.Constant(code.lane, 0xFFFF))
                   for _ in range(paths + 1)]
        with builder.if_then(builder.icmp_signed(">", chunks, ir.Constant(chunks.type, 0))):
            scal = [code.splat(builder.extract_value(scal_v, k)) for k in range(2 * paths + 3)]
            p1, jumps, mins = scal[0], scal[1:1 + paths], scal[1 + paths:1 + 2 * paths]
            cap, scap = scal[2 * paths + 1], scal[2 * paths + 2]
            acc = [cgutils.alloca_once_value(builder, code.full(0xFFFF))
                   for _ in range(paths + 1)]
            with code.chunks(chunks) as d:
                cd = code.load(c_p, d)
                total = None
                for k in range(paths):
                    below, here, above = (code.load(preds[k], d, j) for j in range(3))
                    best = code.umin(code.umin(here, builder.add(code.umin(below, above), p1)),
                                     jumps[k])
                    v = code.umin(builder.add(cd, builder.sub(best, mins[k])), cap)
                    code.store(v, outs[k], d, 1)
                    builder.store(code.umin(builder.load(acc[k]), v), acc[k])
                    total = v if total is None else builder.add(total, v)
                sv = code.umin(total, scap)
                code.store(sv, s_p, d)
                builder.store(code.umin(builder.load(acc[paths]), sv), acc[paths])
            for a, r in zip(acc, results):
                builder.store(code.reduce_min(builder.load(a)), r)
        return context.make_tuple(builder, signature.return_type,
                                  [builder.load(r) for r in results])

    return codegen


@intrinsic
def _lanes(typingctx, c, preds, outs, s_out, scalars, chunks):
    """The d-loop of :func:`_paths4` .. :func:`_paths1` over d < LANES * ``chunks`` in
    explicit vectors: for each path k and d, outs[k][d + 1] = :func:`_lane` (c[d],
    preds[k][d .. d + 2], P1, m_k + P2, m_k, cap), and s_out[d] = min(their sum, sum cap).
    ``preds`` / ``outs``: each path's predecessor row and output row (rows of
    :func:`new_path_buffers`, with the ABSENT borders); ``scalars`` = (P1, m_k + P2 per path,
    m_k per path, cap, sum cap), uint16. Returns (the minimum of each path's new row, the
    minimum of S) over those d (0xFFFF without a chunk). Contiguous uint16 arrays only.

    The rows are distinct, as :func:`new_path_buffers` lays them out. numba vectorised its own
    loop over them too, but behind runtime overlap checks of every loaded row against every
    stored one: a long run of scalar compares at every pixel (docs/performance.md)."""
    if not contiguous_rows(types.uint16, c, s_out, *preds, *outs) or len(preds) != len(outs):
        return None
    paths = len(preds)
    sig = types.UniTuple(types.uint16, paths + 1)(c, preds, outs, s_out, scalars, chunks)
    return sig, _lanes_codegen(paths)


@njit(cache=True, inline="always")
def _paths4(c, state, step, params, s_out, n):
    """The d-loop of :func:`sgm_pixel` with all four paths over d < n (n = D, or 0 when
    another path count is configured); returns min S (0xFFFF if n = 0). ``step`` =
    (predecessor rows, output rows, m + P2) per path."""
    buf, mins = state[0], state[1]
    pred, out, jump = step
    p1, cap, scap = params[1], params[5], params[6]
    unused = mins.shape[0] - 1  # where a loop that did not run writes its minima
    l0, l1, l2, l3 = buf[pred[0]], buf[pred[1]], buf[pred[2]], buf[pred[3]]
    o0, o1, o2, o3 = buf[out[0]], buf[out[1]], buf[out[2]], buf[out[3]]
    m0, m1, m2, m3 = mins[pred[0]], mins[pred[1]], mins[pred[2]], mins[pred[3]]
    j0, j1, j2, j3 = jump
    n0, n1, n2, n3, s1 = _lanes(c, (l0, l1, l2, l3), (o0, o1, o2, o3), s_out,
                                (p1, j0, j1, j2, j3, m0, m1, m2, m3, cap, scap), n // LANES)
    for d in range(n // LANES * LANES, n):  # the last D mod LANES disparities
        cd = c[d]
        v0 = _lane(cd, l0[d], l0[d + 1], l0[d + 2], p1, j0, m0, cap)
        v1 = _lane(cd, l1[d], l1[d + 1], l1[d + 2], p1, j1, m1, cap)
        v2 = _lane(cd, l2[d], l2[d + 1], l2[d + 2], p1, j2, m2, cap)
        v3 = _lane(cd, l3[d], l3[d + 1], l3[d + 2], p1, j3, m3, cap)
        o0[d + 1] = v0
        o1[d + 1] = v1
        o2[d + 1] = v2
        o3[d + 1] = v3
        n0 = min(n0, v0)
        n1 = min(n1, v1)
        n2 = min(n2, v2)
        n3 = min(n3, v3)
        # at most 4 * (2^14 - 1) < 2^16: no wrap before the sum saturates
        sv = min(np.uint16(v0 + v1 + v2 + v3), scap)
        s_out[d] = sv
        s1 = min(s1, sv)
    mins[out[0] if n else unused] = n0
    mins[out[1] if n else unused] = n1
    mins[out[2] if n else unused] = n2
    mins[out[3] if n else unused] = n3
    return s1


@njit(cache=True, inline="always")
def _paths3(c, state, step, params, s_out, n):
    """:func:`_paths4` with paths 0..2."""
    buf, mins = state[0], state[1]
    pred, out, jump = step
    p1, cap, scap = params[1], params[5], params[6]
    unused = mins.shape[0] - 1  # where a loop that did not run writes its minima
    l0, l1, l2 = buf[pred[0]], buf[pred[1]], buf[pred[2]]
    o0, o1, o2 = buf[out[0]], buf[out[1]], buf[out[2]]
    m0, m1, m2 = mins[pred[0]], mins[pred[1]], mins[pred[2]]
    j0, j1, j2 = jump[0], jump[1], jump[2]
    n0, n1, n2, s1 = _lanes(c, (l0, l1, l2), (o0, o1, o2), s_out,
                            (p1, j0, j1, j2, m0, m1, m2, cap, scap), n // LANES)
    for d in range(n // LANES * LANES, n):
        cd = c[d]
        v0 = _lane(cd, l0[d], l0[d + 1], l0[d + 2], p1, j0, m0, cap)
        v1 = _lane(cd, l1[d], l1[d + 1], l1[d + 2], p1, j1, m1, cap)
        v2 = _lane(cd, l2[d], l2[d + 1], l2[d + 2], p1, j2, m2, cap)
        o0[d + 1] = v0
        o1[d + 1] = v1
        o2[d + 1] = v2
        n0 = min(n0, v0)
        n1 = min(n1, v1)
        n2 = min(n2, v2)
        sv = min(np.uint16(v0 + v1 + v2), scap)
        s_out[d] = sv
        s1 = min(s1, sv)
    mins[out[0] if n else unused] = n0
    mins[out[1] if n else unused] = n1
    mins[out[2] if n else unused] = n2
    return s1


@njit(cache=True, inline="always")
def _paths2(c, state, step, params, s_out, n):
    """:func:`_paths4` with paths 0 and 1."""
    buf, mins = state[0], state[1]
    pred, out, jump = step
    p1, cap, scap = params[1], params[5], params[6]
    unused = mins.shape[0] - 1  # where a loop that did not run writes its minima
    l0, l1 = buf[pred[0]], buf[pred[1]]
    o0, o1 = buf[out[0]], buf[out[1]]
    m0, m1 = mins[pred[0]], mins[pred[1]]
    j0, j1 = jump[0], jump[1]
    n0, n1, s1 = _lanes(c, (l0, l1), (o0, o1), s_out, (p1, j0, j1, m0, m1, cap, scap),
                        n // LANES)
    for d in range(n // LANES * LANES, n):
        cd = c[d]
        v0 = _lane(cd, l0[d], l0[d + 1], l0[d + 2], p1, j0, m0, cap)
        v1 = _lane(cd, l1[d], l1[d + 1], l1[d + 2], p1, j1, m1, cap)
        o0[d + 1] = v0
        o1[d + 1] = v1
        n0 = min(n0, v0)
        n1 = min(n1, v1)
        sv = min(np.uint16(v0 + v1), scap)
        s_out[d] = sv
        s1 = min(s1, sv)
    mins[out[0] if n else unused] = n0
    mins[out[1] if n else unused] = n1
    return s1


@njit(cache=True, inline="always")
def _paths1(c, state, step, params, s_out, n):
    """:func:`_paths4` with the left path only."""
    buf, mins = state[0], state[1]
    pred, out, jump = step
    p1, cap, scap = params[1], params[5], params[6]
    unused = mins.shape[0] - 1  # where a loop that did not run writes its minima
    l0 = buf[pred[0]]
    o0 = buf[out[0]]
    m0 = mins[pred[0]]
    j0 = jump[0]
    n0, s1 = _lanes(c, (l0,), (o0,), s_out, (p1, j0, m0, cap, scap), n // LANES)
    for d in range(n // LANES * LANES, n):
        v0 = _lane(c[d], l0[d], l0[d + 1], l0[d + 2], p1, j0, m0, cap)
        o0[d + 1] = v0
        n0 = min(n0, v0)
        sv = min(v0, scap)
        s_out[d] = sv
        s1 = min(s1, sv)
    mins[out[0] if n else unused] = n0
    return s1


@njit(cache=True)
def sgm_row(agg_row, img_row, img_prev, y, state, params, s_row):
    """One image row of every enabled path; S of the row into ``s_row`` (W, D) uint16.

    ``agg_row`` is clamped to the path cap; ``state``/``params`` as for :func:`sgm_pixel`.
    """
    sgm_row_start(y, state)
    for x in range(agg_row.shape[0]):
        sgm_pixel(agg_row[x], x, y, img_row, img_prev, state, params, s_row[x])


def sgm_params(
    paths: int, p1: int, p2: int, adaptive: bool, slope: int, path_bits: int, sum_bits: int
):
    """The ``params`` tuple of :func:`sgm_pixel` with the kernel's dtypes."""
    return (
        np.int64(paths),
        np.uint16(p1),
        np.uint16(p2),
        bool(adaptive),
        np.int64(slope),
        np.uint16((1 << path_bits) - 1),
        np.uint16((1 << sum_bits) - 1),
    )


@njit(cache=True)
def _sgm_volume(agg, img, state, params, out):
    for y in range(agg.shape[0]):
        img_prev = img[y - 1] if y > 0 else img[0]
        sgm_row(agg[y], img[y], img_prev, y, state, params, out[y])


def sgm(agg, *, p1, p2, paths, path_bits, sum_bits, img=None, p2_adaptive=False, p2_slope=16):
    """S (H, W, D) uint16 with the numba row kernel; same arguments as :func:`sgm_ref`.

    The uint16 lanes of the kernel bound the registers: path_bits <= 14 (so four paths and the
    ABSENT sentinel fit), sum_bits <= 16 and P1, P2 < 2^15.
    """
    if not isinstance(agg, np.ndarray) or agg.ndim != 3 or agg.dtype not in (np.uint8, np.uint16):
        raise InputError("the aggregated volume must be a uint8 or uint16 array (H, W, D)")
    h, w, dn = agg.shape
    if not 1 <= paths <= len(PATHS):
        raise InputError(f"the number of SGM paths must be 1..{len(PATHS)}, got {paths}")
    if not 1 <= path_bits <= 14:
        raise InputError(f"the path cost width must be 1..14 bits, got {path_bits}")
    if not 1 <= sum_bits <= 16:
        raise InputError(f"the summed cost width must be 1..16 bits, got {sum_bits}")
    for name, value in (("P1", p1), ("P2", p2)):
        if not 0 <= value <= 32767:
            raise InputError(f"{name} must be in 0..32767, got {value}")
    if p2_slope < 0:
        raise InputError(f"the adaptive P2 slope must be >= 0, got {p2_slope}")
    if img is None:
        img = np.zeros((h, w), np.uint8)
        p2_adaptive = False
    elif not isinstance(img, np.ndarray) or img.shape != (h, w) or img.dtype != np.uint8:
        raise InputError(f"the grey image must be uint8 {h}x{w} like the volume")
    path_cap = (1 << path_bits) - 1
    # min(A + x, cap) == min(min(A, cap) + x, cap) for x >= 0: clamping first is exact and keeps
    # every intermediate of the kernel inside uint16 for any input.
    agg = np.minimum(agg, path_cap).astype(np.uint16)
    out = np.empty((h, w, dn), np.uint16)
    params = sgm_params(paths, p1, p2, p2_adaptive, p2_slope, path_bits, sum_bits)
    _sgm_volume(agg, np.ascontiguousarray(img), new_path_buffers(w, dn), params, out)
    return out
