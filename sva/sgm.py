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
from numba import njit

from sim.errors import InputError

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
# path_bits <= 14 the sum of four paths also fits the uint16 accumulator before saturation.
ABSENT = 0x7FFF


def new_path_buffers(width: int, disparities: int):
    """State of the streaming SGM: ``(buf, mins)``.

    ``buf`` (3 W + 7, D + 2) uint16 holds every path row the kernel reads or writes, so that
    a path step is always "row ``pred`` of buf -> row ``out`` of buf" and the choice between
    rows is scalar arithmetic, never a branch around array code (a branch there would cost
    per-pixel reference counting in numba):

    - rows k W + x, k = 0, 1, 2: the most recent row of the top, top-left and top-right paths,
      overwritten in place pixel by pixel -- one row per path, not two: the top path copies
      its predecessor aside first, the top-left path keeps the overwritten value one pixel
      longer, the top-right path reads x + 1, not yet overwritten;
    - 3 W, 3 W + 1: the left path's ping-pong; 3 W + 2: the top path's copy; 3 W + 3, 3 W + 4:
      the top-left delay pair; 3 W + 5: a scratch row for copies nobody reads;
    - 3 W + 6: all-zero costs, the predecessor of a path start: from a zero predecessor
      (minimum 0) the step gives min(A + min(0, ABSENT + P1, P2), cap) = min(A, cap).

    ``mins`` (3 W + 7,) uint16: the minimum over d of each row. Costs live at [1, D]; entries
    0 and D + 1 stay ABSENT so the d-loop has no branches.
    """
    buf = np.full((3 * width + 7, disparities + 2), ABSENT, np.uint16)
    buf[3 * width + 6, 1:-1] = 0
    return buf, np.zeros(3 * width + 7, np.uint16)


@njit(cache=True, inline="always")
def _path_step(c, lp, mp, p1, p2, cap, lout, acc):
    """One pixel of one path: lout[d + 1] from the predecessor's costs lp[d + 1]; acc += lout.

    ``lp``/``lout`` are padded (D + 2) with ABSENT at both ends, so the d-loop has no branches
    and LLVM vectorises it across d in uint16 lanes. Returns min_d lout (for the successor).
    ``c`` <= cap (the callers clamp it), so c + (best - mp) <= 2 * cap fits uint16.
    """
    dn = c.shape[0]
    jump = np.uint16(mp + p2)
    mpu = np.uint16(mp)
    m = np.uint16(0xFFFF)
    for d in range(dn):
        a = lp[d]
        b = lp[d + 2]
        nb = np.uint16(min(a, b) + p1)
        best = lp[d + 1]
        best = min(best, nb)
        best = min(best, jump)
        v = np.uint16(c[d] + np.uint16(best - mpu))
        v = min(v, cap)
        lout[d + 1] = v
        m = min(m, v)
        acc[d] = np.uint16(acc[d] + v)
    return m


@njit(cache=True, inline="always")
def _copy_row(buf, mins, src, dst, n):
    """Costs 1..n of row ``src`` to row ``dst`` (n = D or 0: a copy without a branch)."""
    a = buf[src]
    b = buf[dst]
    for d in range(1, n + 1):
        b[d] = a[d]
    mins[dst] = mins[src]


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
def sgm_pixel(c, x, y, img_row, img_prev, state, params, acc):
    """Every enabled path at pixel (x, y) of a raster scan; acc[d] += L_r(p, d) for each.

    ``c`` (D,) uint16: the aggregated cost, already clamped to the path cap. ``state`` is
    :func:`new_path_buffers`, ``params`` = (paths, p1, p2, adaptive, slope, path_cap) with
    p1, p2, path_cap as uint16. Pixels must come in raster order (x = 0..W-1 per row).
    """
    buf, mins = state
    paths, p1, p2, adaptive, slope, cap = params
    w = img_row.shape[0]
    dn = c.shape[0]
    left = 3 * w
    zero = 3 * w + 6
    i_p = img_row[x]
    # path 0: left to right, predecessor (x - 1, y)
    pred = zero if x == 0 else left + 1 - (x & 1)
    out = left + (x & 1)
    pen2 = _p2_at(p1, p2, adaptive, slope, i_p, img_row[max(x - 1, 0)])
    mins[out] = _path_step(c, buf[pred], mins[pred], p1, pen2, cap, buf[out], acc)
    # paths 1..3: predecessors (x, y-1), (x-1, y-1), (x+1, y-1) in the previous row
    for k in range(1, paths):
        here = (k - 1) * w + x
        n = dn
        if k == 1:
            # the predecessor is the very entry this pixel overwrites: step from a copy
            save = 3 * w + 2
            pred = save
            px = x
        elif k == 2:
            # the predecessor was overwritten by pixel x - 1, which saved it in the delay
            # pair; save this entry for pixel x + 1
            save = 3 * w + 3 + (x & 1)
            pred = 3 * w + 4 - (x & 1)
            px = x - 1
        else:
            # the predecessor x + 1 is not overwritten yet: nothing to save
            save = 3 * w + 5
            pred = here + 1
            px = x + 1
            n = 0
        if y == 0 or px < 0 or px >= w:
            pred = zero
            px = x
        _copy_row(buf, mins, here, save, n)
        pen2 = _p2_at(p1, p2, adaptive, slope, i_p, img_prev[px])
        mins[here] = _path_step(c, buf[pred], mins[pred], p1, pen2, cap, buf[here], acc)


@njit(cache=True)
def sgm_row(agg_row, img_row, img_prev, y, state, params, sum_cap, s_row):
    """One image row of every enabled path; S of the row into ``s_row`` (W, D) uint16.

    ``agg_row`` is clamped to the path cap; ``state``/``params`` as for :func:`sgm_pixel`.
    """
    dn = agg_row.shape[1]
    acc = np.empty(dn, np.uint16)
    scap = np.uint16(sum_cap)
    for x in range(agg_row.shape[0]):
        for d in range(dn):
            acc[d] = 0
        sgm_pixel(agg_row[x], x, y, img_row, img_prev, state, params, acc)
        srow = s_row[x]
        for d in range(dn):
            v = acc[d]
            srow[d] = min(v, scap)


def sgm_params(paths: int, p1: int, p2: int, adaptive: bool, slope: int, path_bits: int):
    """The ``params`` tuple of :func:`sgm_pixel` with the kernel's dtypes."""
    return (
        np.int64(paths),
        np.uint16(p1),
        np.uint16(p2),
        bool(adaptive),
        np.int64(slope),
        np.uint16((1 << path_bits) - 1),
    )


@njit(cache=True)
def _sgm_volume(agg, img, state, params, sum_cap, out):
    for y in range(agg.shape[0]):
        img_prev = img[y - 1] if y > 0 else img[0]
        sgm_row(agg[y], img[y], img_prev, y, state, params, sum_cap, out[y])


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
    params = sgm_params(paths, p1, p2, p2_adaptive, p2_slope, path_bits)
    _sgm_volume(
        agg, np.ascontiguousarray(img), new_path_buffers(w, dn), params, (1 << sum_bits) - 1, out
    )
    return out
