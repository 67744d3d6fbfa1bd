"""Optional k x k median filter on the output words (k = 3 or 5) -- SVA post-processing.

Definition: the median (element k*k // 2 of the sorted window) of the output words q in the k x k
window with replicate borders; invalid words (-1) take part as values below every disparity, so a
pixel whose window is mostly invalid becomes invalid. A result < 0 is invalid (-1).
"""

import numpy as np
from numba import njit


def median_ref(q, k: int) -> np.ndarray:
    h, w = q.shape
    r = k // 2
    out = np.empty_like(q)
    for y in range(h):
        for x in range(w):
            vals = sorted(
                int(q[min(max(y + j, 0), h - 1), min(max(x + i, 0), w - 1)])
                for j in range(-r, r + 1)
                for i in range(-r, r + 1)
            )
            m = vals[len(vals) // 2]
            out[y, x] = m if m >= 0 else -1
    return out


@njit(cache=True)
def _median(q, k, out):
    h, w = q.shape
    r = k // 2
    win = np.empty(k * k, np.int32)
    for y in range(h):
        for x in range(w):
            n = 0
            for j in range(-r, r + 1):
                yy = min(max(y + j, 0), h - 1)
                for i in range(-r, r + 1):
                    xx = min(max(x + i, 0), w - 1)
                    win[n] = q[yy, xx]
                    n += 1
            # insertion sort: k*k <= 25 elements
            for a in range(1, n):
                v = win[a]
                b = a - 1
                while b >= 0 and win[b] > v:
                    win[b + 1] = win[b]
                    b -= 1
                win[b + 1] = v
            m = win[n // 2]
            out[y, x] = m if m >= 0 else -1


def median(q, k: int) -> np.ndarray:
    """Numba version of :func:`median_ref`; k = 0 or 1 returns a copy."""
    if k <= 1:
        return q.copy()
    out = np.empty_like(q)
    _median(np.ascontiguousarray(q, dtype=np.int32), k, out)
    return out
