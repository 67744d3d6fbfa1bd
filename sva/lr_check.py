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
from numba import njit

from sva.wta import INVALID


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


@njit(cache=True)
def right_disparity_row(s_row, best_cost, dr_row):
    """dR for one row. ``best_cost`` (W,) int64 scratch. Scans left pixels x in order and d in
    order, keeping the first minimum, so ties resolve to the smallest d as defined."""
    w = s_row.shape[0]
    dn = s_row.shape[1]
    for xr in range(w):
        best_cost[xr] = np.int64(1) << 40
        dr_row[xr] = 0
    for x in range(w):
        sx = s_row[x]
        lim = min(dn, x + 1)
        for d in range(lim):
            xr = x - d
            c = np.int64(sx[d])
            # for a fixed xr, d grows with x: strict < keeps the smallest d among equal costs
            if c < best_cost[xr]:
                best_cost[xr] = c
                dr_row[xr] = d


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
def _lr_volume(s, q, dint, max_diff, dr):
    best = np.empty(s.shape[1], np.int64)
    for y in range(s.shape[0]):
        right_disparity_row(s[y], best, dr[y])
        lr_check_row(q[y], dint[y], dr[y], max_diff)


def lr_check(s, q, dint, max_diff: int):
    """Numba version: (checked q, dR). ``q`` is not modified."""
    h, w, _ = s.shape
    out = np.ascontiguousarray(q).copy()
    dr = np.empty((h, w), np.int32)
    _lr_volume(np.ascontiguousarray(s), out, np.ascontiguousarray(dint), max_diff, dr)
    return out, dr
