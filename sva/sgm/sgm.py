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

Integer definition (the chip's), each rule written once in plain Python beside the kernels:
- the penalty step, :func:`path_step`: L_r(p, .) from L_r(p - r, .) and A(p, .), the terms
  d - 1 < 0 and d + 1 >= D absent from the minimum, L_r saturating at 2^path_bits - 1 (unsigned);
  where p - r lies outside the image the path starts from an all-zero predecessor, which gives
  L_r(p, d) = min(A(p, d), 2^path_bits - 1);
- S saturates at 2^sum_bits - 1 (unsigned);
- with ``p2_adaptive`` the P2 of the step from p - r to p is :func:`lowered_p2` of the left grey
  image's two pixels (lower where the image steps in intensity, never below P1); else P2.
"""

from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, register_jitable

from stereosim.core.config import PATH_BITS_MAX, PENALTY_MAX, SUM_BITS_MAX, SvaConfig
from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit
from stereosim.quant.vectors import U16_LANES, VectorCode, aligned_full, contiguous_rows

# (dx, dy) of the predecessor p - r, in the order ``sva.paths`` enables them.
PATHS = ((-1, 0), (0, -1), (-1, -1), (1, -1))
PATH_NAMES = ("left_to_right", "top_to_bottom", "topleft_to_bottomright", "topright_to_bottomleft")


# the default slope of the adaptive P2: the configuration's (sva.p2_slope)
DEFAULT_P2_SLOPE = SvaConfig().p2_slope


@register_jitable
def lowered_p2(p1, p2, slope, i_p, i_prev):
    """The adaptive P2 of a step from a pixel of grey ``i_prev`` to one of grey ``i_p``:
    P2 lowered by slope |I(p) - I(p - r)| sixteenths (the product shifted right by four bits,
    rounded down), never below P1; int64. Plain Python, and inlined into the kernels
    (:func:`_pens`) as it is: the one place of this rule."""
    diff = np.int64(i_p) - np.int64(i_prev)
    return max(np.int64(p1), np.int64(p2) - ((np.int64(slope) * abs(diff)) >> 4))


def effective_p2(p1: int, p2: int, adaptive: bool, slope: int, i_p: int, i_prev: int) -> int:
    """The P2 used on one path step: :func:`lowered_p2` with ``adaptive``, else P2."""
    return int(lowered_p2(p1, p2, slope, i_p, i_prev)) if adaptive else p2


def path_step(c, prev, p1: int, p2: int, cap: int) -> list[int]:
    """The SGM penalty step of one path at one pixel, the chip's integer eq. 13 -- its one
    description, in plain Python: from the path's costs ``prev`` = L' at the predecessor
    (minimum m) and the pixel's aggregated costs ``c`` (both of length D),

        L(d) = min(c(d) + min(L'(d), L'(d - 1) + P1, L'(d + 1) + P1, m + P2) - m, cap)

    with the terms d - 1 < 0 and d + 1 >= D absent; ``p2`` is the step's P2
    (:func:`effective_p2`), ``cap`` the path cap 2^path_bits - 1. A path starts from an all-zero
    predecessor: L = min(c, cap). :func:`sgm_ref` runs it pixel by pixel; the kernel's vector
    code (:func:`_step_loop`) computes the same in uint16 lanes, and tests/sva/sgm/test_sgm.py holds
    it against this function."""
    prev = [int(v) for v in prev]
    m = min(prev)
    dn = len(prev)
    out = []
    for d in range(dn):
        best = min(prev[d], m + p2)
        if d > 0:
            best = min(best, prev[d - 1] + p1)
        if d < dn - 1:
            best = min(best, prev[d + 1] + p1)
        out.append(min(int(c[d]) + best - m, cap))
    return out


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
    p2_slope: int = DEFAULT_P2_SLOPE,
) -> np.ndarray:
    """Naive reference: S (H, W, D) as uint16, one path at a time, each pixel
    :func:`path_step` (a path start: from an all-zero predecessor)."""
    h, w, dn = agg.shape
    path_cap = (1 << path_bits) - 1
    sum_cap = (1 << sum_bits) - 1
    total = np.zeros((h, w, dn), np.int64)
    start = np.zeros(dn, np.int64)
    for dx, dy in PATHS[:paths]:
        lr = np.zeros((h, w, dn), np.int64)
        for y in range(h):
            for x in range(w):
                px, py = x + dx, y + dy
                inside = 0 <= px < w and 0 <= py < h
                pen2 = p2
                if inside and img is not None:
                    pen2 = effective_p2(p1, p2, p2_adaptive, p2_slope, img[y, x], img[py, px])
                lr[y, x] = path_step(agg[y, x], lr[py, px] if inside else start, p1, pen2,
                                     path_cap)
        total += lr
    return np.minimum(total, sum_cap).astype(np.uint16)


# Sentinel for the absent neighbours d - 1 < 0 and d + 1 >= D: above every legal path cost
# (path_bits <= 14), and sentinel + P1 still fits in uint16 (P1 <= 2^15 - 1). With
# path_bits <= 14 the sum of four paths also fits uint16 before the sum saturates.
ABSENT = 0x7FFF


class PathState(NamedTuple):
    """The streaming SGM's state (:func:`new_path_buffers`): ``buf`` the path rows, ``mins``
    their minima, ``phase`` the ring offsets of the row in progress, ``pens`` each path's P2
    into each pixel of that row."""

    buf: np.ndarray
    mins: np.ndarray
    phase: np.ndarray
    pens: np.ndarray


class SgmParams(NamedTuple):
    """The SGM's registers as the kernels read them (:func:`sgm_params`): the number of
    ``paths`` and the ``slope`` (int64), ``p1``, ``p2``, the path cap ``path_cap`` and the sum
    cap ``sum_cap`` (uint16), ``adaptive`` (the adaptive P2 on)."""

    paths: np.int64
    p1: np.uint16
    p2: np.uint16
    adaptive: bool
    slope: np.int64
    path_cap: np.uint16
    sum_cap: np.uint16


class PathRows(NamedTuple):
    """One pixel's rows of :func:`new_path_buffers`' ``buf`` for :func:`_step`: path k reads row
    ``pred[k]`` (its predecessor), writes row ``out[k]`` and steps with the P2 ``p2[k]``."""

    pred: tuple
    out: tuple
    p2: tuple


def new_path_buffers(width: int, disparities: int) -> PathState:
    """State of the streaming SGM: a :class:`PathState` ``(buf, mins, phase, pens)``.

    ``buf`` (3 W + 6, >= D + 2) uint16 holds every path row the kernel reads or writes, laid out
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

    ``mins`` (3 W + 6,) uint16: the minimum over d of each row. Costs live at [1, D];
    entries 0 and D + 1 and the rest of a row stay ABSENT so the d-loop has no branches. A
    row is D + 2 rounded up to a whole number of LANES entries, and entry 1 of every row lies
    on a 64-byte boundary: each chunk of a row's output and of the middle of its predecessor
    is one aligned vector (an unaligned one straddles two cache lines). ``phase`` (2,) int64:
    the ring offsets of the row in progress, y mod (W + 1) and 2 y mod (W + 2); ``pens`` (4,
    W) uint16: the P2 of each path's step into each pixel of that row (both set by
    :func:`sgm_row_start`).
    """
    buf = aligned_full((3 * width + 6, -(-(disparities + 2) // LANES) * LANES), np.uint16,
                       ABSENT, first=1)
    buf[3 * width + 5, 1:disparities + 1] = 0
    return PathState(buf=buf, mins=np.zeros(3 * width + 6, np.uint16),
                     phase=np.zeros(2, np.int64), pens=np.zeros((4, width), np.uint16))


@njit(cache=True, inline="always")
def _pens(params, row, prev, dst):
    """dst[x] = the P2 of a step from a pixel of grey ``prev[x]`` to one of grey ``row[x]``
    (:func:`effective_p2`): a branch-free pass over x, the adaptive switch outside it."""
    if not params.adaptive:
        for x in range(dst.shape[0]):
            dst[x] = params.p2
        return
    for x in range(dst.shape[0]):
        dst[x] = np.uint16(lowered_p2(params.p1, params.p2, params.slope, row[x], prev[x]))


@njit(cache=True)
def sgm_row_start(y, img_row, img_prev, state, params):
    """Before the first :func:`sgm_pixel` of row ``y``: the ring offsets, and each path's P2
    into every pixel of the row from ``img_row`` (row y of the grey image) and ``img_prev``
    (row y - 1; any row at y = 0, where no top path has a predecessor): one pass per path over
    the row instead of four branchy evaluations at every pixel; ``params`` the
    :class:`SgmParams`."""
    phase, pens = state.phase, state.pens
    w = img_row.shape[0]
    phase[0] = y % (w + 1)
    phase[1] = (2 * y) % (w + 2)
    # path 0 from (x - 1, y); path 1 from (x, y - 1); path 2 from (x - 1, y - 1); path 3 from
    # (x + 1, y - 1); at the borders the predecessor is clamped into the row (its step then
    # starts from the zero row, where P2 does not matter, but it is defined all the same)
    _pens(params, img_row[1:], img_row[:-1], pens[0, 1:])
    _pens(params, img_row[:1], img_row[:1], pens[0, :1])
    _pens(params, img_row, img_prev, pens[1])
    _pens(params, img_row[1:], img_prev[:-1], pens[2, 1:])
    _pens(params, img_row[:1], img_prev[:1], pens[2, :1])
    _pens(params, img_row[:-1], img_prev[1:], pens[3, :-1])
    _pens(params, img_row[w - 1:], img_prev[w - 1:], pens[3, w - 1:])


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
def sgm_pixel(c, x, y, state, params, s_out, diag, box=None):
    """Every enabled path at pixel (x, y) of a raster scan; S into ``s_out``; returns (min S,
    the first d holding it) as uint16, WTA's winner (:func:`sva.wta.wta.wta_select`).

    ``c`` (D,) uint16: the aggregated cost, already clamped to the path cap. ``state`` is
    :func:`new_path_buffers`, set by :func:`sgm_row_start` for row y; ``params`` the
    :class:`SgmParams` (:func:`sgm_params`). Pixels must come in raster order (x = 0..W-1 per row).
    ``s_out[d]`` = min(sum of the enabled paths' L_r(p, d), sum_cap). ``diag`` = (best,
    best_d, base): S is also offered to the right view's diagonal search
    (:func:`sva.lr.lr_check.diagonal_update`'s arrays; right pixel x - d at index base + d).
    ``box`` = (column in, column out, cap), the fused SVA's horizontal box step
    (:func:`sva.box.aggregation.box_step`): ``c`` is then the window sum, the cost min(c, cap),
    and c slides on by + column in - column out in the same pass.

    Here only the rows: each path's predecessor and output row of ``buf`` (scalar arithmetic
    on the ring offsets); :func:`_step` reads every predecessor and writes every output row,
    S, the rows' minima, the winner and the diagonal search in one pass over d, in uint16
    lanes.
    """
    phase, pens = state.phase, state.pens
    w = pens.shape[1]
    top_left = w + 1
    top_right = 2 * w + 3
    left = 3 * w + 3
    zero = 3 * w + 5
    # path 0: left to right, predecessor (x - 1, y)
    pred0 = zero if x == 0 else left + 1 - (x & 1)
    out0 = left + (x & 1)
    # path 1: top to bottom, predecessor (x, y - 1)
    out1, pred1 = _ring_slots(x, phase[0], w + 1)
    pred1 = pred1 if y > 0 else zero
    # path 2: top-left to bottom-right, predecessor (x - 1, y - 1)
    out2, pred2 = _ring_slots(x, phase[1], w + 2)
    out2 += top_left
    pred2 = top_left + pred2 if y > 0 and x > 0 else zero
    # path 3: top-right to bottom-left, predecessor (x + 1, y - 1)
    out3 = top_right + x
    pred3 = top_right + x + 1 if y > 0 and x < w - 1 else zero
    rows = PathRows((pred0, pred1, pred2, pred3), (out0, out1, out2, out3),
                    (pens[0, x], pens[1, x], pens[2, x], pens[3, x]))
    return _step(c, state, rows, s_out, params, diag, box)


# disparities of one step of :func:`_step`: the uint16 lanes of a vector
LANES = U16_LANES


def _step_loop(code, rows, scalars, paths: int):
    """The d-loop of :func:`_step` for ``paths`` paths: per chunk of LANES disparities, for
    each path k, :func:`path_step` from its predecessor row L' (minimum m) as
    L_k(d) = min(c(d) + min(L'(d), min(L'(d-1), L'(d+1)) + P1, m + P2) - m, cap), the absent
    neighbours ABSENT, stored; S(d) = min(their sum, sum cap),
    stored; the running minima kept in vectors, S's with the first d of each lane holding it
    (strict <: d grows); and the diagonal search (:func:`sva.lr.lr_check.diagonal_update`): where
    S(d) is below the right pixel's best, it becomes the best and d its d. The last D mod
    LANES disparities by the same code under a mask of lanes. Returns (min S, the first d
    holding it); the rows' minima go to ``mins``.

    Exact in uint16: L'(d +- 1) + P1 <= ABSENT + P1 < 2^16; the inner minimum lies in m ..
    m + P2, and c <= cap < 2^14 (the callers clamp it), so c + (best - m) < 2^16; the sum of
    four paths is at most 4 (2^14 - 1) < 2^16 before it saturates."""
    b = code.builder
    c_p, s_p, buf_p, stride, mins_p, dn = rows["c"], rows["s"], rows["buf"], rows["stride"], \
        rows["mins"], rows["dn"]
    preds = [b.gep(buf_p, [b.mul(rows["pred"][k], stride)]) for k in range(paths)]
    outs = [b.gep(buf_p, [b.mul(rows["out"][k], stride)]) for k in range(paths)]
    low = [b.load(b.gep(mins_p, [rows["pred"][k]])) for k in range(paths)]
    p1, cap, scap = (code.splat(v) for v in scalars["p1_cap_scap"])
    mins = [code.splat(m) for m in low]
    jumps = [code.splat(b.add(m, pen)) for m, pen in zip(low, scalars["pens"])]
    acc = [cgutils.alloca_once_value(b, code.full(0xFFFF)) for _ in range(paths + 1)]
    first = cgutils.alloca_once_value(b, code.full(0xFFFF))

    def chunk(d, mask):
        def load(ptr, plus=0):
            return code.load(ptr, d, plus) if mask is None else \
                code.load_masked(ptr, d, mask, plus)

        def store(value, ptr, plus=0):
            if mask is None:
                code.store(value, ptr, d, plus)
            else:
                code.store_masked(value, ptr, d, mask, plus)

        def keep(vec):  # masked-off lanes must not lower a minimum
            return vec if mask is None else b.select(mask, vec, code.full(0xFFFF))

        cd = load(c_p)
        if "box" in rows:  # c is the window sum: the cost is its clamp, then it slides on
            col_in, col_out, agg_cap = rows["box"]
            store(b.sub(b.add(cd, load(col_in)), load(col_out)), c_p)
            cd = code.umin(cd, code.splat(agg_cap))
        total = None
        for k in range(paths):
            below, here, above = (load(preds[k], j) for j in range(3))
            best = code.umin(code.umin(here, b.add(code.umin(below, above), p1)), jumps[k])
            v = code.umin(b.add(cd, b.sub(best, mins[k])), cap)
            store(v, outs[k], 1)
            b.store(code.umin(b.load(acc[k]), keep(v)), acc[k])
            total = v if total is None else b.add(total, v)
        sv = keep(code.umin(total, scap))
        store(sv, s_p)
        s_low = b.load(acc[paths])
        dv = code.index(d)
        b.store(b.select(code.ult(sv, s_low), dv, b.load(first)), first)
        b.store(code.umin(s_low, sv), acc[paths])
        old = load(rows["diag"][0])
        store(b.select(code.ult(sv, old), dv, load(rows["diag"][1])), rows["diag"][1])
        store(code.umin(sv, old), rows["diag"][0])

    lanes = ir.Constant(dn.type, LANES)
    full = b.udiv(dn, lanes)
    with code.chunks(full) as d:
        chunk(d, None)
    done = b.mul(full, lanes)
    rest = b.sub(dn, done)
    with b.if_then(b.icmp_signed(">", rest, ir.Constant(rest.type, 0))):
        chunk(done, code.lanes_below(b.trunc(rest, code.lane)))
    for k in range(paths):
        b.store(code.reduce_min(b.load(acc[k])), b.gep(mins_p, [rows["out"][k]]))
    s1 = code.reduce_min(b.load(acc[paths]))
    holds = b.icmp_unsigned("==", b.load(acc[paths]), code.splat(s1))
    return s1, code.reduce_min(b.select(holds, b.load(first), code.full(0xFFFF)))


def _field(builder, value, ty, name):
    """The field ``name`` of a NamedTuple argument ``value`` (its numba type ``ty``)."""
    return builder.extract_value(value, ty.fields.index(name))


def _field_type(ty, name):
    """The numba type of the field ``name`` of the NamedTuple type ``ty``."""
    return ty.types[ty.fields.index(name)]


def _step_codegen(context, builder, signature, args):
    c_v, state_v, rows_v, s_v, params_v, diag_v, box_v = args
    c_t, state_t, rows_t, s_t, params_t, diag_t, box_t = signature.args
    code = VectorCode(context, builder, 16, LANES)
    c_a = context.make_array(c_t)(context, builder, c_v)
    buf_a = context.make_array(_field_type(state_t, "buf"))(
        context, builder, _field(builder, state_v, state_t, "buf"))
    mins = code.data(_field_type(state_t, "mins"), _field(builder, state_v, state_t, "mins"))

    def row_part(name):
        part = _field(builder, rows_v, rows_t, name)
        return [builder.extract_value(part, k) for k in range(4)]

    rows = {
        "c": c_a.data, "s": code.data(s_t, s_v), "buf": buf_a.data,
        "stride": cgutils.unpack_tuple(builder, buf_a.shape, 2)[1], "mins": mins,
        "dn": cgutils.unpack_tuple(builder, c_a.shape, 1)[0],
        "pred": row_part("pred"), "out": row_part("out"),
        "diag": [builder.gep(code.data(diag_t[k], builder.extract_value(diag_v, k)),
                             [builder.extract_value(diag_v, 2)]) for k in range(2)],
    }
    if box_t != types.none:
        rows["box"] = [code.data(box_t[k], builder.extract_value(box_v, k)) for k in range(2)]
        rows["box"].append(builder.extract_value(box_v, 2))
    scalars = {"pens": row_part("p2"),
               "p1_cap_scap": [_field(builder, params_v, params_t, name)
                               for name in ("p1", "path_cap", "sum_cap")]}
    paths_v = _field(builder, params_v, params_t, "paths")
    result = [cgutils.alloca_once_value(builder, ir.Constant(code.lane, 0xFFFF))
              for _ in range(2)]
    for paths in range(1, len(PATHS) + 1):  # one loop per path count, chosen once a pixel
        with builder.if_then(builder.icmp_signed("==", paths_v,
                                                 ir.Constant(paths_v.type, paths))):
            for r, v in zip(result, _step_loop(code, rows, scalars, paths)):
                builder.store(v, r)
    return context.make_tuple(builder, signature.return_type, [builder.load(r) for r in result])


@intrinsic
def _step(typingctx, c, state, rows, s_out, params, diag, box):
    """One pixel of every enabled path (the first ``params.paths`` of :data:`PATHS`), in
    explicit vectors (:func:`_step_loop`): with ``rows`` a :class:`PathRows`, path k reads row
    ``rows.pred[k]`` of ``state.buf`` (its predecessor, minimum ``state.mins[rows.pred[k]]``)
    and writes row ``rows.out[k]`` (its minimum to ``state.mins[rows.out[k]]``), with the P2
    ``rows.p2[k]``; S goes to ``s_out`` and to the diagonal search ``diag`` = (best, best_d,
    base); returns (min S, the first d holding it).
    With ``box`` = (column in, column out, cap) (None: ``c`` is the cost), ``c`` is the
    horizontal box window's sum: the cost is min(c, cap) and c becomes c + in - out.
    ``params`` the :class:`SgmParams` (P1 and the caps read); ``state`` the
    :class:`PathState`, its ``buf`` :func:`new_path_buffers`'s (C-contiguous, rows of at least
    D + 2 with the ABSENT borders); ``c``, ``s_out`` and the two ``diag`` arrays contiguous
    uint16, ``diag``'s from index base on at least D long.

    The rows are distinct, as :func:`new_path_buffers` lays them out. numba vectorised its own
    loop over them too, but behind runtime overlap checks of every loaded row against every
    stored one: a long run of scalar compares at every pixel; and taking each row out of
    ``buf`` as an array, for every path count, cost more scalar work than the vectors'
    (docs/performance.md)."""
    u16 = types.uint16
    if not (_named(state, PathState) and _named(rows, PathRows) and _named(params, SgmParams)):
        return None
    buf = _field_type(state, "buf")
    if not (contiguous_rows(u16, c, _field_type(state, "mins"), s_out, *diag.types[:2])
            and isinstance(buf, types.Array) and buf.ndim == 2 and buf.layout == "C"
            and buf.dtype == u16 and _field_type(rows, "pred") == types.UniTuple(types.int64, 4)
            and _field_type(rows, "out") == types.UniTuple(types.int64, 4)
            and _field_type(rows, "p2") == types.UniTuple(u16, 4)
            and all(_field_type(params, k) == u16 for k in ("p1", "path_cap", "sum_cap"))
            and _field_type(params, "paths") == types.int64):
        return None
    if box != types.none and not (contiguous_rows(u16, *box.types[:2]) and box[2] == u16):
        return None
    sig = types.UniTuple(u16, 2)(c, state, rows, s_out, params, diag, box)
    return sig, _step_codegen


def _named(ty, cls) -> bool:
    """Whether the numba type ``ty`` is a NamedTuple of class ``cls``."""
    return isinstance(ty, (types.NamedTuple, types.NamedUniTuple)) and ty.instance_class is cls


@njit(cache=True)
def sgm_row(agg_row, img_row, img_prev, y, state, params, s_row):
    """One image row of every enabled path; S of the row into ``s_row`` (W, D) uint16.

    ``agg_row`` is clamped to the path cap; ``state``/``params`` as for :func:`sgm_pixel`.
    """
    sgm_row_start(y, img_row, img_prev, state, params)
    w, dn = agg_row.shape
    scratch = np.empty(w + dn - 1, np.uint16)  # the diagonal search, read by nobody here
    for x in range(w):
        sgm_pixel(agg_row[x], x, y, state, params, s_row[x], (scratch, scratch, w - 1 - x))


def sgm_params(
    paths: int, p1: int, p2: int, adaptive: bool, slope: int, path_bits: int, sum_bits: int
) -> SgmParams:
    """The :class:`SgmParams` of :func:`sgm_pixel` with the kernel's dtypes."""
    return SgmParams(
        paths=np.int64(paths),
        p1=np.uint16(p1),
        p2=np.uint16(p2),
        adaptive=bool(adaptive),
        slope=np.int64(slope),
        path_cap=np.uint16((1 << path_bits) - 1),
        sum_cap=np.uint16((1 << sum_bits) - 1),
    )


@njit(cache=True)
def _sgm_volume(agg, img, state, params, out):
    for y in range(agg.shape[0]):
        img_prev = img[y - 1] if y > 0 else img[0]
        sgm_row(agg[y], img[y], img_prev, y, state, params, out[y])


def sgm(agg, *, p1, p2, paths, path_bits, sum_bits, img=None, p2_adaptive=False,
        p2_slope=DEFAULT_P2_SLOPE):
    """S (H, W, D) uint16 with the numba row kernel; same arguments as :func:`sgm_ref`.

    The uint16 lanes of the kernel bound the registers: path_bits <= 14 (so four paths and the
    ABSENT sentinel fit), sum_bits <= 16 and P1, P2 < 2^15 -- the bounds of the configuration's
    keys too (:data:`core.config.schema.PATH_BITS_MAX`, ``SUM_BITS_MAX``, ``PENALTY_MAX``).
    """
    if not isinstance(agg, np.ndarray) or agg.ndim != 3 or agg.dtype not in (np.uint8, np.uint16):
        raise InputError("the aggregated volume must be a uint8 or uint16 array (H, W, D)")
    h, w, dn = agg.shape
    if not 1 <= paths <= len(PATHS):
        raise InputError(f"the number of SGM paths must be 1..{len(PATHS)}, got {paths}")
    if not 1 <= path_bits <= PATH_BITS_MAX:
        raise InputError(f"the path cost width must be 1..{PATH_BITS_MAX} bits, got {path_bits}")
    if not 1 <= sum_bits <= SUM_BITS_MAX:
        raise InputError(f"the summed cost width must be 1..{SUM_BITS_MAX} bits, got {sum_bits}")
    for name, value in (("P1", p1), ("P2", p2)):
        if not 0 <= value <= PENALTY_MAX:
            raise InputError(f"{name} must be in 0..{PENALTY_MAX}, got {value}")
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
