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
    """Row buffers of the streaming SGM, padded with the absent-neighbour sentinel.

    Returns (prev, cur, prev_min, cur_min, left): the previous and current row of the three
    top paths (3, W, D + 2), their minima (3, W), and the two-entry ping-pong buffer of the
    left-to-right path (2, D + 2). Costs live at [1, D]; entries 0 and D + 1 stay ABSENT.
    """
    prev = np.full((3, width, disparities + 2), ABSENT, np.uint16)
    cur = np.full((3, width, disparities + 2), ABSENT, np.uint16)
    left = np.full((2, disparities + 2), ABSENT, np.uint16)
    return prev, cur, np.zeros((3, width), np.uint16), np.zeros((3, width), np.uint16), left


@njit(cache=True, inline="always")
def _path_step(c, lp, mp, p1, p2, cap, lout, acc):
    """One pixel of one path: lout[d + 1] from the predecessor's costs lp[d + 1]; acc += lout.

    ``lp``/``lout`` are padded (D + 2) with ABSENT at both ends, so the d-loop has no branches
    and LLVM vectorises it across d in uint16 lanes. Returns min_d lout (for the successor).
    """
    dn = c.shape[0]
    jump = np.uint16(mp + p2)
    mpu = np.uint16(mp)
    m = np.uint16(0xFFFF)
    for d in range(dn):
        a = lp[d]
        b = lp[d + 2]
        nb = np.uint16((a if a < b else b) + p1)
        best = lp[d + 1]
        best = nb if nb < best else best
        best = jump if jump < best else best
        v = np.uint16(np.uint16(c[d]) + np.uint16(best - mpu))
        v = cap if v > cap else v
        lout[d + 1] = v
        m = v if v < m else m
        acc[d] = np.uint16(acc[d] + v)
    return m


@njit(cache=True, inline="always")
def _path_start(c, cap, lout, acc):
    m = np.uint16(0xFFFF)
    for d in range(c.shape[0]):
        v = np.uint16(c[d])
        v = cap if v > cap else v
        lout[d + 1] = v
        m = v if v < m else m
        acc[d] = np.uint16(acc[d] + v)
    return m


@njit(cache=True, inline="always")
def _p2_at(p1, p2, adaptive, slope, i_p, i_prev):
    if not adaptive:
        return np.uint16(p2)
    diff = np.int64(i_p) - np.int64(i_prev)
    if diff < 0:
        diff = -diff
    pen2 = np.int64(p2) - ((np.int64(slope) * diff) >> 4)
    return np.uint16(pen2 if pen2 > p1 else p1)


@njit(cache=True)
def sgm_row(agg_row, img_row, img_prev, y, prev, prev_min, cur, cur_min, left, paths, p1, p2,
            adaptive, slope, path_cap, sum_cap, s_row):
    """One image row of every enabled path; S of the row into ``s_row`` (W, D) uint16.

    ``prev``/``prev_min`` hold the previous row of the top paths (from
    :func:`new_path_buffers`); this row's go to ``cur``/``cur_min`` and the caller swaps the two.
    The left-to-right path needs only the previous pixel: the ping-pong buffer ``left``.
    """
    w = agg_row.shape[0]
    dn = agg_row.shape[1]
    acc = np.zeros(dn, np.uint16)
    p1u = np.uint16(p1)
    cap = np.uint16(path_cap)
    scap = np.uint16(sum_cap)
    m_left = np.uint16(0)
    for x in range(w):
        acc[:] = 0
        c = agg_row[x]
        # path 0: left to right, predecessor (x - 1, y)
        lout = left[x % 2]
        if x == 0:
            m_left = _path_start(c, cap, lout, acc)
        else:
            pen2 = _p2_at(p1, p2, adaptive, slope, img_row[x], img_row[x - 1])
            m_left = _path_step(c, left[(x + 1) % 2], m_left, p1u, pen2, cap, lout, acc)
        # paths 1..3: predecessors (x, y-1), (x-1, y-1), (x+1, y-1) in the previous row
        for k in range(1, paths):
            px = x if k == 1 else (x - 1 if k == 2 else x + 1)
            if y == 0 or px < 0 or px >= w:
                cur_min[k - 1, x] = _path_start(c, cap, cur[k - 1, x], acc)
            else:
                pen2 = _p2_at(p1, p2, adaptive, slope, img_row[x], img_prev[px])
                cur_min[k - 1, x] = _path_step(
                    c, prev[k - 1, px], prev_min[k - 1, px], p1u, pen2, cap, cur[k - 1, x], acc
                )
        srow = s_row[x]
        for d in range(dn):
            v = acc[d]
            srow[d] = scap if v > scap else v


@njit(cache=True)
def _sgm_volume(agg, img, paths, p1, p2, adaptive, slope, path_cap, sum_cap, out, bufs):
    prev, cur, prev_min, cur_min, left = bufs
    for y in range(agg.shape[0]):
        img_prev = img[y - 1] if y > 0 else img[0]
        sgm_row(agg[y], img[y], img_prev, y, prev, prev_min, cur, cur_min, left, paths, p1, p2,
                adaptive, slope, path_cap, sum_cap, out[y])
        prev, cur = cur, prev
        prev_min, cur_min = cur_min, prev_min


def sgm(agg, *, p1, p2, paths, path_bits, sum_bits, img=None, p2_adaptive=False, p2_slope=16):
    """S (H, W, D) uint16 with the numba row kernel; same arguments as :func:`sgm_ref`."""
    h, w, dn = agg.shape
    if img is None:
        img = np.zeros((h, w), np.uint8)
        p2_adaptive = False
    out = np.empty((h, w, dn), np.uint16)
    _sgm_volume(
        np.ascontiguousarray(agg, dtype=np.uint16), np.ascontiguousarray(img), paths, p1, p2,
        p2_adaptive, p2_slope, (1 << path_bits) - 1, (1 << sum_bits) - 1, out,
        new_path_buffers(w, dn),
    )
    return out
