"""Box-filter cost aggregation -- the second SVA stage.

Definition: for an odd window k = 2r + 1,

    A(x, y, d) = min( sum_{j=-r..r} sum_{i=-r..r} C(cx(x + i), cy(y + j), d),  2^cost_bits - 1 )

with replicate borders (cx, cy clamp a coordinate into the image), so every pixel sums exactly
k*k costs. The sum saturates at the configured aggregated-cost width ``cost_bits``. The chip
computes it as a vertical sum of k buffered cost rows followed by a horizontal sliding sum; the
row functions below do the same.
"""

import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit


def box_filter_ref(cost, k: int, cost_bits: int) -> np.ndarray:
    """Naive reference over a whole (H, W, D) volume; returns uint16."""
    h, w, dn = cost.shape
    r = k // 2
    cap = (1 << cost_bits) - 1
    out = np.empty((h, w, dn), np.uint16)
    for y in range(h):
        for x in range(w):
            for d in range(dn):
                s = 0
                for j in range(-r, r + 1):
                    for i in range(-r, r + 1):
                        yy = min(max(y + j, 0), h - 1)
                        xx = min(max(x + i, 0), w - 1)
                        s += int(cost[yy, xx, d])
                out[y, x, d] = min(s, cap)
    return out


@njit(cache=True)
def vertical_sum_row(rows, k, height, y, out):
    """Sum of the k cost rows clamp(y-r) .. clamp(y+r) into ``out`` (W, D) uint16.

    ``rows`` is the ring of k cost rows (k, W, D) of the streaming design: image row i lives in
    slot i % k, so the k rows around y are always present once row clamp(y + r) has arrived.
    """
    r = k // 2
    w = out.shape[0]
    dn = out.shape[1]
    y0 = min(max(y - r, 0), height - 1)
    s0 = rows[y0 % k]
    for x in range(w):
        for d in range(dn):
            out[x, d] = np.uint16(s0[x, d])
    for j in range(-r + 1, r + 1):
        yy = min(max(y + j, 0), height - 1)
        src = rows[yy % k]
        for x in range(w):
            for d in range(dn):
                out[x, d] = np.uint16(out[x, d] + np.uint16(src[x, d]))


@njit(cache=True, inline="always")
def box_start(colsum, k, acc):
    """The horizontal window sum at x = 0: columns clamp(-r) .. clamp(r) of ``colsum``."""
    r = k // 2
    w, dn = colsum.shape
    for d in range(dn):
        acc[d] = 0
    for i in range(-r, r + 1):
        src = colsum[min(max(i, 0), w - 1)]
        for d in range(dn):
            acc[d] = np.uint16(acc[d] + src[d])


@njit(cache=True, inline="always")
def box_step(acc, c_in, c_out, cap, out):
    """Emit the window sum of this pixel saturated at ``cap`` into ``out``, then slide the
    window one column right: ``acc += c_in - c_out``. The window sum is at most
    k*k*255 < 2^16 (k <= 15), so uint16 arithmetic (modulo 2^16 in between) is exact."""
    for d in range(acc.shape[0]):
        v = acc[d]
        out[d] = min(v, cap)
        acc[d] = np.uint16(np.uint16(v + c_in[d]) - c_out[d])


@njit(cache=True)
def horizontal_sum_row(colsum, k, cap, out):
    """Sliding horizontal sum of k columns of ``colsum`` (W, D) with replicate borders.

    The running sum adds the column entering the window and subtracts the one leaving it; with
    replicate borders the column index of both is clamped. Saturates at ``cap``.
    """
    r = k // 2
    w, dn = colsum.shape
    capu = np.uint16(cap)
    acc = np.empty(dn, np.uint16)
    box_start(colsum, k, acc)
    for x in range(w):
        box_step(acc, colsum[min(x + r + 1, w - 1)], colsum[max(x - r, 0)], capu, out[x])


@njit(cache=True)
def _box_volume(cost, k, cap, out):
    h, w, dn = cost.shape
    colsum = np.empty((w, dn), np.uint16)
    ring = np.empty((k, w, dn), np.uint8)
    r = k // 2
    for y in range(h):
        for j in range(-r, r + 1):
            yy = min(max(y + j, 0), h - 1)
            src = cost[yy]
            dst = ring[yy % k]
            for x in range(w):
                for d in range(dn):
                    dst[x, d] = src[x, d]
        vertical_sum_row(ring, k, h, y, colsum)
        horizontal_sum_row(colsum, k, cap, out[y])


def box_filter(cost, k: int, cost_bits: int) -> np.ndarray:
    """Box-filtered volume (H, W, D) uint16 with the numba row kernels."""
    if not isinstance(cost, np.ndarray) or cost.ndim != 3 or cost.dtype != np.uint8:
        raise InputError("the cost volume must be a uint8 array (H, W, D)")
    if k < 1 or k % 2 == 0:
        raise InputError(f"the box size must be odd and >= 1, got {k}")
    if k > 15:
        raise InputError(f"box size {k} is too large for 16-bit column sums (k <= 15)")
    if not 1 <= cost_bits <= 16:
        raise InputError(f"the aggregated cost width must be 1..16 bits, got {cost_bits}")
    out = np.empty(cost.shape, np.uint16)
    _box_volume(np.ascontiguousarray(cost), k, (1 << cost_bits) - 1, out)
    return out
