"""Left-right consistency check from the one aggregated volume -- no second NNA pass.

The right image's disparity is read off the left volume along its diagonals (the paper's single
NNA pass; libSGM does the same): right pixel q = (x_r, y) sees left pixel (x_r + d, y) at
disparity d, so

    dR(q) = the smallest d in [0, D) with x_r + d < W minimising S(x_r + d, y, d).

A left pixel p = (x, y) with winner d*(p) keeps its output word when x - d* >= 0 and
|d*(p) - dR(x - d*, y)| <= max_diff; otherwise its word becomes invalid (-1). With box
aggregation alone this shear is exact; through SGM's causal paths it is the usual approximation.
"""

import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit
from stereosim.sva.wta.wta import INVALID, disparity_index


def right_disparity_ref(s) -> np.ndarray:
    """Naive reference: dR (H, W) int32 by diagonal search of S (H, W, D)."""
    h, w, dn = s.shape
    dr = np.empty((h, w), np.int32)
    for y in range(h):
        for xr in range(w):
            best_d, best_c = 0, None
            for d in range(dn):
                if xr + d >= w:
                    break
                c = int(s[y, xr + d, d])
                if best_c is None or c < best_c:
                    best_d, best_c = d, c
            dr[y, xr] = best_d
    return dr


def lr_check_ref(q, dint, dr, max_diff: int) -> np.ndarray:
    """Naive reference: a copy of ``q`` with the inconsistent pixels set to -1."""
    out = q.copy()
    h, w = q.shape
    for y in range(h):
        for x in range(w):
            d = int(dint[y, x])
            if x - d < 0 or abs(d - int(dr[y, x - d])) > max_diff:
                out[y, x] = INVALID
    return out


def new_diagonal_buffers(width: int, disparities: int):
    """Scratch of :func:`diagonal_update`: (best cost, its d, the d of each lane) per right
    pixel, uint16 like S, stored reversed (x_r at index W - 1 - x_r) with room for the D - 1
    pixels x_r < 0 that the d-loop also touches; the third array is 0 .. D - 1. Reset by
    :func:`diagonal_start`."""
    n = width + disparities - 1
    return np.empty(n, np.uint16), np.empty(n, np.uint16), disparity_index(disparities)


@njit(cache=True)
def diagonal_start(diag):
    """Open every right pixel of a new row: cost 0xFFFF, d = 0. The first candidate of a
    right pixel is d = 0, so starting from (0xFFFF, 0) is the same as starting above every S
    (an S of 0xFFFF at d = 0 leaves (0xFFFF, 0))."""
    best, best_d, _ = diag
    for i in range(best.shape[0]):
        best[i] = 0xFFFF
        best_d[i] = 0


@njit(cache=True, inline="always")
def diagonal_update(sx, x, diag):
    """Feed the costs ``sx`` (D,) of left pixel x to the right pixels x_r = x - d it can match.

    With x_r stored at index W - 1 - x_r, the right pixels of d = 0, 1, ... are contiguous
    and ascending from index W - 1 - x, so the d-loop is one fixed-length vectorisable pass
    of compares, minima and selects in uint16 lanes. d > x lands on x_r < 0, which is never
    read. Pixels come in order x = 0, 1, ...: for a fixed x_r, d grows with x, so strict <
    keeps the smallest d among equal costs, as defined.
    """
    best, best_d, idx = diag
    dn = sx.shape[0]
    base = best.shape[0] - dn - x  # index of x_r = x: W - 1 - x
    b = best[base:]
    i = best_d[base:]
    for d in range(dn):
        v = sx[d]
        old = b[d]
        # 0xFFFF where this d wins, else 0: a select written as bit operations, which LLVM
        # vectorises in uint16 lanes
        take = np.uint16(0) - np.uint16(v < old)
        i[d] = (i[d] & ~take) | (idx[d] & take)
        b[d] = min(v, old)


@njit(cache=True)
def diagonal_finish(diag, dr_row):
    """After the last pixel of a row: dR of every right pixel into ``dr_row`` (W,)."""
    best_d = diag[1]
    w = dr_row.shape[0]
    for xr in range(w):
        dr_row[xr] = best_d[w - 1 - xr]


@njit(cache=True)
def right_disparity_row(s_row, diag, dr_row):
    """dR for one row of S (W, D); ``diag`` from :func:`new_diagonal_buffers`."""
    diagonal_start(diag)
    for x in range(s_row.shape[0]):
        diagonal_update(s_row[x], x, diag)
    diagonal_finish(diag, dr_row)


@njit(cache=True)
def lr_check_row(q_row, dint_row, dr_row, max_diff):
    w = q_row.shape[0]
    for x in range(w):
        d = dint_row[x]
        xr = x - d
        if xr < 0:
            q_row[x] = INVALID
            continue
        diff = d - dr_row[xr]
        if diff < 0:
            diff = -diff
        if diff > max_diff:
            q_row[x] = INVALID


@njit(cache=True)
def _lr_volume(s, q, dint, max_diff, dr, diag):
    for y in range(s.shape[0]):
        right_disparity_row(s[y], diag, dr[y])
        lr_check_row(q[y], dint[y], dr[y], max_diff)


def lr_check(s, q, dint, max_diff: int):
    """Numba version: (checked q, dR). ``q`` is not modified."""
    if not isinstance(s, np.ndarray) or s.ndim != 3 or s.dtype != np.uint16:
        raise InputError("the summed cost volume S must be a uint16 array (H, W, D)")
    h, w, _ = s.shape
    if q.shape != (h, w) or dint.shape != (h, w):
        raise InputError(f"the output words and winners must be {h}x{w} like S")
    out = np.ascontiguousarray(q, dtype=np.int32).copy()
    dr = np.empty((h, w), np.int32)
    _lr_volume(
        np.ascontiguousarray(s),
        out,
        np.ascontiguousarray(dint, dtype=np.int32),
        max_diff,
        dr,
        new_diagonal_buffers(w, s.shape[2]),
    )
    return out, dr
