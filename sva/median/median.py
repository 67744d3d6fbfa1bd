"""Optional k x k median filter on the output words (k = 3 or 5) -- SVA post-processing.

Definition: the median (element k*k // 2 of the sorted window) of the output words q in the k x k
window with replicate borders; invalid words (-1) take part as values below every disparity, so a
pixel whose window is mostly invalid becomes invalid. A result < 0 is invalid (-1).
"""

import functools

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit
from stereosim.quant.vectors import U16_LANES, VectorCode


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


def _batcher_pairs(m: int) -> list[tuple[int, int]]:
    """Batcher's odd-even merge sort of m values: the network for the next power of two, minus
    the pairs that touch the padding (padding would hold +inf, which a compare-exchange never
    moves)."""
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
    return pairs


@functools.cache
def selection_network(k: int) -> np.ndarray:
    """Compare-exchange pairs (n, 2) that bring the median of k*k values to index k*k // 2:
    :func:`_batcher_pairs`, minus the pairs nothing at the median index depends on (113 pairs
    for k = 5)."""
    m = k * k
    needed = {m // 2}
    kept = []
    for a, b in reversed(_batcher_pairs(m)):
        if a in needed or b in needed:
            kept.append((a, b))
            needed |= {a, b}
    return np.array(kept[::-1], np.int64).reshape(-1, 2)


def sorted_column_windows(k: int) -> tuple[list[int], int]:
    """Every 0-1 window whose k columns are sorted (index j*k + i: row j, column i; each
    column 0 .. 0 1 .. 1 from the top), (k + 1)^k of them, as bit sets: for each of the k*k
    values the int whose bit n is window n's value there, and the int whose bit n is window
    n's median."""
    zeros = np.indices((k + 1,) * k).reshape(k, -1).T  # the number of 0s of each column
    win = (np.arange(k)[None, :, None] >= zeros[:, None, :]).reshape(len(zeros), k * k)
    median = win.sum(axis=1) > k * k // 2  # at least k*k // 2 + 1 ones

    def bits(column):
        return int.from_bytes(np.packbits(column, bitorder="little").tobytes(), "little")

    return [bits(win[:, i]) for i in range(k * k)], bits(median)


def median_holds(pairs, windows: tuple[list[int], int]) -> bool:
    """Whether the compare-exchanges ``pairs`` leave every window's median (``windows``, as
    :func:`sorted_column_windows` gives them) at index k*k // 2: on bit sets, min is AND and
    max is OR."""
    wires, median = windows
    v = list(wires)
    for a, b in pairs:
        v[a], v[b] = v[a] & v[b], v[a] | v[b]
    return v[len(v) // 2] == median


# the largest window whose network is pruned against every 0-1 window with sorted columns
PRUNED_UP_TO = 5


@functools.cache
def column_networks(k: int) -> tuple[np.ndarray, np.ndarray]:
    """(pairs that sort a column of k values, pairs that bring the median of a k x k window
    whose columns are sorted to index k*k // 2): the kernel sorts the k values of each column
    once for the k windows that share them, then runs the second network per pixel.

    The second is :func:`selection_network` less every pair, tried one at a time from the
    last, without which the median of every 0-1 window with sorted columns still lands in
    the middle (:func:`median_holds`). By the 0-1 principle (a compare-exchange network
    commutes with thresholding, and thresholding keeps a column sorted) it then does so for
    every window with sorted columns. k = 5: 76 pairs against 113, and 9 for a column.
    Larger k: no column sort and the whole selection network ((k + 1)^k windows to check)."""
    if k > PRUNED_UP_TO:
        return np.zeros((0, 2), np.int64), selection_network(k)
    windows = sorted_column_windows(k)
    pairs = [tuple(p) for p in selection_network(k)]
    for i in range(len(pairs) - 1, -1, -1):
        trial = pairs[:i] + pairs[i + 1:]
        if median_holds(trial, windows):
            pairs = trial
    column = np.array(_batcher_pairs(k), np.int64).reshape(-1, 2)
    return column, np.array(pairs, np.int64).reshape(-1, 2)


# pixels per block of the network: its k*k rows of int32 stay in the L1 cache
_BLOCK = 128


@njit(cache=True, inline="always")
def _frame_row(src, height, i):
    """Row clamp(i) of a frame of ``height`` rows kept in ``src``: all of it (src has
    ``height`` rows) or the ring of its most recent rows (row i in slot i mod len(src))."""
    return src[min(max(i, 0), height - 1) % src.shape[0]]


@njit(cache=True, inline="always")
def _sorted_window_rows(src, height, y, column, plus, padded):
    """The k rows of output row y's windows into ``padded`` (k, W + 2 r), each word + ``plus``
    in ``padded``'s dtype, the borders replicated, then every column of the k rows sorted by
    the pairs ``column`` (branch-free min/max, vectorised over x)."""
    k = padded.shape[0]
    r = k // 2
    w = src.shape[1]
    for j in range(k):
        row = _frame_row(src, height, y + j - r)
        dst = padded[j]
        # the row, then its replicated borders: a plain copy LLVM vectorises (a clamped
        # index at every x did not vectorise)
        inner = dst[r:r + w]
        for x in range(w):
            inner[x] = row[x] + plus
        for x in range(r):
            dst[x] = row[0] + plus
            dst[r + w + x] = row[w - 1] + plus
    for c in range(column.shape[0]):  # sort every column of the k rows
        a = padded[column[c, 0]]
        b = padded[column[c, 1]]
        for x in range(w + 2 * r):
            u = a[x]
            v = b[x]
            a[x] = min(u, v)
            b[x] = max(u, v)


@njit(cache=True)
def median_network_rows(src, height, k, networks, y0, y1, out):
    """Median rows y0 .. y1 - 1 of a frame of ``height`` rows into ``out[y - y0]``, any odd k:
    the k rows of the window, each column sorted by ``networks[0]`` (:func:`column_networks`),
    then the window values of a block of pixels, one row per window position, and
    ``networks[1]`` as branch-free min/max over the block (vectorised over x). ``src`` holds
    the frame or a ring of its rows (:func:`_frame_row`) that includes rows y0 - k // 2 ..
    y1 - 1 + k // 2 (clamped)."""
    column, network = networks
    w = src.shape[1]
    padded = np.empty((k, w + 2 * (k // 2)), np.int32)
    win = np.empty((k * k, _BLOCK), np.int32)
    for y in range(y0, y1):
        _sorted_window_rows(src, height, y, column, 0, padded)
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


# the largest word the 16-bit median takes: words w in -1 .. NARROW_MAX become w + 1 in uint16
NARROW_MAX = 0xFFFE
# pixels of one block of the 5 x 5 median: the uint16 lanes of a vector
_LANES = U16_LANES


def _median5_codegen(context, builder, signature, args):
    rows_v, x0, out_v, n = args
    rows_t, _, out_t, _ = signature.args
    code = VectorCode(context, builder, 16, _LANES)
    words = VectorCode(context, builder, 32, _LANES)
    rows = context.make_array(rows_t)(context, builder, rows_v)
    stride = cgutils.unpack_tuple(builder, rows.shape, 2)[1]
    mask = code.lanes_below(builder.trunc(n, code.lane))
    v = [code.load_masked(builder.gep(rows.data, [builder.mul(stride, ir.Constant(
        stride.type, j))]), x0, mask, i) for j in range(5) for i in range(5)]
    for a, b in column_networks(5)[1]:
        v[a], v[b] = code.umin(v[a], v[b]), code.umax(v[a], v[b])
    m = builder.sub(builder.zext(v[12], words.vec), words.full(1))
    words.store_masked(m, words.data(out_t, out_v), x0, mask)
    return context.get_dummy_value()


@intrinsic
def _median5_lanes(typingctx, rows, x0, out, n):
    """out[x0 + t] = the median of the 5 x 5 window at rows[0:5, x0 + t .. x0 + t + 4], less
    1, for t < ``n`` <= 32: ``rows`` (5, W + 4) uint16 holds the window rows (each word + 1,
    borders replicated) with every column sorted, ``out`` int32. The 25 values of each lane
    stay in registers through the network of :func:`column_networks` (its min and max, no
    store in between), 32 pixels a step."""
    u16 = types.uint16
    if not (isinstance(rows, types.Array) and rows.ndim == 2 and rows.layout == "C"
            and rows.dtype == u16 and isinstance(out, types.Array) and out.ndim == 1
            and out.layout == "C" and out.dtype == types.int32):
        return None
    return types.void(rows, types.int64, out, types.int64), _median5_codegen


@njit(cache=True)
def median5_narrow_rows(src, height, column, y0, y1, out):
    """:func:`median_network_rows` for k = 5 and words -1 .. :data:`NARROW_MAX`, in uint16:
    each window row as word + 1 (the order kept, -1 becoming 0), every column of the five
    rows sorted by ``column`` (:func:`column_networks` (5)'s first network, vectorised over
    x), then :func:`_median5_lanes` on 32 pixels at a time, the window in registers."""
    w = src.shape[1]
    padded = np.empty((5, w + 4), np.uint16)
    for y in range(y0, y1):
        _sorted_window_rows(src, height, y, column, 1, padded)
        o = out[y - y0]
        for x0 in range(0, w, _LANES):
            _median5_lanes(padded, x0, o, min(_LANES, w - x0))


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


def median_rows(src, height: int, k: int, y0: int, y1: int, out, narrow: bool = False) -> None:
    """Median rows y0 .. y1 - 1 (k odd, >= 3) of a frame of ``height`` rows held in ``src``,
    all of it or a ring of its rows (row i in slot i mod len(src)), into ``out[y - y0]``.
    ``narrow``: every word of ``src`` is in -1 .. :data:`NARROW_MAX` (the 5 x 5 median then
    runs in uint16)."""
    if k == 3:
        median3_rows(src, height, y0, y1, out)
    elif k == 5 and narrow:
        median5_narrow_rows(src, height, column_networks(5)[0], y0, y1, out)
    else:
        median_network_rows(src, height, k, column_networks(k), y0, y1, out)


@njit(cache=True)
def _median_network(q, k, networks, out):
    """The whole frame ``q`` (H, W) through :func:`median_network_rows`."""
    median_network_rows(q, q.shape[0], k, networks, np.int64(0), q.shape[0], out)


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
    elif k == 5 and q32.size and q32.min() >= -1 and q32.max() <= NARROW_MAX:
        median5_narrow_rows(q32, q32.shape[0], column_networks(5)[0], np.int64(0), q32.shape[0],
                            out)
    else:
        _median_network(q32, k, column_networks(k), out)
    return out
