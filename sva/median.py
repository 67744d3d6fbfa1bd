"""Optional k x k median filter on the output words (k = 3 or 5) -- SVA post-processing.

Definition: the median (element k*k // 2 of the sorted window) of the output words q in the k x k
window with replicate borders; invalid words (-1) take part as values below every disparity, so a
pixel whose window is mostly invalid becomes invalid. A result < 0 is invalid (-1).
"""

import functools

import numpy as np

from stereosim.sim.errors import InputError
from stereosim.sim.kernel_cache import njit


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


@functools.cache
def selection_network(k: int) -> np.ndarray:
    """Compare-exchange pairs (n, 2) that bring the median of k*k values to index k*k // 2.

    Batcher's odd-even merge sort for the next power of two, minus the pairs that touch the
    padding (padding would hold +inf, which a compare-exchange never moves) and minus the
    pairs nothing at the median index depends on: 113 pairs for k = 5.
    """
    m = k * k
    n = 1
    while n < m:
        n *= 2
    pairs = []
    p = 1
    while p < n:
        step = p
        while step >= 1:
            for j in range(step % p, n - step, 2 * step):
                for i in range(min(step, n - j - step)):
                    if (i + j) // (2 * p) == (i + j + step) // (2 * p) and i + j + step < m:
                        pairs.append((i + j, i + j + step))
            step //= 2
        p *= 2
    needed = {m // 2}
    kept = []
    for a, b in reversed(pairs):
        if a in needed or b in needed:
            kept.append((a, b))
            needed |= {a, b}
    return np.array(kept[::-1], np.int64).reshape(-1, 2)


# pixels per block of the network: its k*k rows of int32 stay in the L1 cache
_BLOCK = 128


@njit(cache=True, inline="always")
def _frame_row(src, height, i):
    """Row clamp(i) of a frame of ``height`` rows kept in ``src``: all of it (src has
    ``height`` rows) or the ring of its most recent rows (row i in slot i mod len(src))."""
    return src[min(max(i, 0), height - 1) % src.shape[0]]


@njit(cache=True)
def median_network_rows(src, height, k, network, y0, y1, out):
    """Median rows y0 .. y1 - 1 of a frame of ``height`` rows into ``out[y - y0]``, any odd k:
    the window values of a block of pixels, one row per window position, then the selection
    network as branch-free min/max over the block (vectorised over x). ``src`` holds the
    frame or a ring of its rows (:func:`_frame_row`) that includes rows y0 - k // 2 ..
    y1 - 1 + k // 2 (clamped)."""
    w = src.shape[1]
    r = k // 2
    padded = np.empty((k, w + 2 * r), np.int32)
    win = np.empty((k * k, _BLOCK), np.int32)
    for y in range(y0, y1):
        for j in range(k):
            row = _frame_row(src, height, y + j - r)
            dst = padded[j]
            for x in range(w + 2 * r):
                dst[x] = row[min(max(x - r, 0), w - 1)]
        o = out[y - y0]
        for x0 in range(0, w, _BLOCK):
            n = min(_BLOCK, w - x0)
            for j in range(k):
                for i in range(k):
                    srow = padded[j, x0 + i :]
                    dst = win[j * k + i]
                    for t in range(n):
                        dst[t] = srow[t]
            for c in range(network.shape[0]):
                a = win[network[c, 0]]
                b = win[network[c, 1]]
                for t in range(n):
                    u = a[t]
                    v = b[t]
                    a[t] = min(u, v)
                    b[t] = max(u, v)
            m = win[k * k // 2]
            for t in range(n):
                o[x0 + t] = max(m[t], -1)  # a median < 0 is invalid (-1)


@njit(cache=True)
def median3_rows(src, height, y0, y1, out):
    """:func:`median_network_rows` for k = 3 without sorting windows: sort each column of
    three once (lo <= mid <= hi), then the median of the 3 x 3 window is med3(max of the lows,
    med3 of the mids, min of the highs) -- exact for nine values (the median has at least
    five values <= and >= it, and the three candidates bracket it). Branch-free min/max over
    rows, vectorised over x."""
    w = src.shape[1]
    lo = np.empty(w + 2, np.int32)
    mid = np.empty(w + 2, np.int32)
    hi = np.empty(w + 2, np.int32)
    for y in range(y0, y1):
        r0 = _frame_row(src, height, y - 1)
        r1 = _frame_row(src, height, y)
        r2 = _frame_row(src, height, y + 1)
        for x in range(w):
            a = min(r0[x], r1[x])
            b = max(r0[x], r1[x])
            c = r2[x]
            lo[x + 1] = min(a, c)
            mid[x + 1] = max(a, min(b, c))
            hi[x + 1] = max(b, c)
        # replicate borders: columns -1 and W are columns 0 and W - 1
        lo[0], mid[0], hi[0] = lo[1], mid[1], hi[1]
        lo[w + 1], mid[w + 1], hi[w + 1] = lo[w], mid[w], hi[w]
        o = out[y - y0]
        for x in range(w):
            top = max(max(lo[x], lo[x + 1]), lo[x + 2])
            a = min(mid[x], mid[x + 1])
            b = max(mid[x], mid[x + 1])
            centre = max(a, min(b, mid[x + 2]))
            bottom = min(min(hi[x], hi[x + 1]), hi[x + 2])
            a = min(top, centre)
            b = max(top, centre)
            o[x] = max(max(a, min(b, bottom)), -1)  # a median < 0 is invalid (-1)


def median_rows(src, height: int, k: int, y0: int, y1: int, out) -> None:
    """Median rows y0 .. y1 - 1 (k odd, >= 3) of a frame of ``height`` rows held in ``src``,
    all of it or a ring of its rows (row i in slot i mod len(src)), into ``out[y - y0]``."""
    if k == 3:
        median3_rows(src, height, y0, y1, out)
    else:
        median_network_rows(src, height, k, selection_network(k), y0, y1, out)


@njit(cache=True)
def _median_network(q, k, network, out):
    """The whole frame ``q`` (H, W) through :func:`median_network_rows`."""
    median_network_rows(q, q.shape[0], k, network, np.int64(0), q.shape[0], out)


@njit(cache=True)
def _median3(q, out):
    """The whole frame ``q`` (H, W) through :func:`median3_rows`."""
    median3_rows(q, q.shape[0], np.int64(0), q.shape[0], out)


def median(q, k: int) -> np.ndarray:
    """Numba version of :func:`median_ref`; k = 0 or 1 returns a copy."""
    if k <= 1:
        return q.copy()
    if k % 2 == 0:
        raise InputError(f"the median window must be odd (3, 5, ...), got {k}")
    q32 = np.ascontiguousarray(q, dtype=np.int32)
    out = np.empty(q.shape, np.int32)
    if k == 3:
        _median3(q32, out)
    else:
        _median_network(q32, k, selection_network(k), out)
    return out
