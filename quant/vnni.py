"""The NNA's single wide layer by byte dot products (AVX512-VNNI): :func:`vnni_signs` is
:func:`quant.intconv.int_signs` for a network of one 9x9 or 11x11 layer on the grey image, on a
CPU that has the instruction (:func:`vnni_applies`), bit for bit.

``vpdpbusd`` adds to each of 16 int32 lanes the four products of the lane's uint8 bytes of one
operand with the int8 bytes of the other: 64 products an instruction, against the 8 float32
lanes of a multiply-add in :mod:`quant.intconv`'s loops (LLVM keeps those at 256 bits on this
CPU). numba does not vectorise the convolution into it, so :func:`_taps9` / :func:`_taps11`
emit it (``llvm.x86.avx512.vpdpbusd.512``), as sva/hamming/cost.py's popcount emits ``llvm.ctpop``.
A layer of one input channel (the grey image) then needs no offset in its lanes: its tap sum is
``sum w * p - offset * sum w`` with p the uint8 pixels, so bit c is ``sum w_c * p > offset *
sum w_c - bias_c``. The pixels go four to an int32 twice (:func:`_band_quads`): a pixel and the
three to its right, and a pixel and the three below it. A kernel row's first 4 G taps (G = K //
4) take the first, the K - 4 G columns left over the second, four rows at a time: K = 9 takes 21
instructions a channel where groups of four along every row took 27 (the 12 taps of three
groups hold 9). Every product and partial sum is an exact int32 (at most 255 * 128 * 121 in
magnitude). Four channels share each load of the pixels, and their sums stay in registers over
the whole kernel, two a channel (eight chains of dependent instructions, not four).
"""

from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np
from llvmlite import binding, ir
from numba import types
from numba.core import config as numba_config
from numba.extending import intrinsic

from stereosim.core.kernel_cache import njit
from stereosim.quant.vectors import VectorCode

VNNI_LANES = 16  # int32 lanes of one instruction
VNNI_GROUP = 4  # bytes a lane
VNNI_KERNELS = (9, 11)  # the kernel sizes with code of their own (_taps9, _taps11)


class TapSums(NamedTuple):
    """The int32 rows :func:`_taps9` / :func:`_taps11` store four channels' tap sums to (the
    channels c, c + 1, c + 2, c + 3 of the call)."""

    ch0: np.ndarray
    ch1: np.ndarray
    ch2: np.ndarray
    ch3: np.ndarray


class Band(NamedTuple):
    """What the tap sums of a band read: its horizontal quads ``q`` and vertical quads ``v``
    (uint32, flat, both ``qs`` words a row, :func:`_band_quads`) and every channel's weight
    words ``w`` in turn (int32)."""

    q: np.ndarray
    v: np.ndarray
    w: np.ndarray
    qs: int


def numba_targets_vnni(cpu_name, cpu_features, host: dict) -> bool:
    """Whether the code numba compiles has the instruction: the ``host`` CPU's features
    (numba's default target), or those that ``NUMBA_CPU_NAME`` / ``NUMBA_CPU_FEATURES`` name
    when set (a cache compiled for a generic CPU must not meet it)."""
    if cpu_name or cpu_features:
        return "+avx512vnni" in (cpu_features or "").split(",")
    return bool(host.get("avx512vnni", False))


#: whether the compiled code may use the instruction
HAS_VNNI = numba_targets_vnni(numba_config.CPU_NAME, numba_config.CPU_FEATURES,
                              binding.get_host_cpu_features())


def vnni_applies(weights: tuple) -> bool:
    """Whether :func:`quant.intconv.int_signs` takes the byte dot products: a CPU with
    AVX512-VNNI, a network of one layer on the grey image with K = 9 or 11 (the two with code
    of their own; the float lanes are faster for narrower kernels), and
    ``STEREOSIM_VNNI`` not ``0``."""
    if not HAS_VNNI or os.environ.get("STEREOSIM_VNNI", "1").strip() == "0":
        return False
    k = weights[0].shape[2]
    return len(weights) == 1 and weights[0].shape[1] == 1 and k in VNNI_KERNELS


def _taps_codegen(k: int):
    """The code of :func:`_taps9` / :func:`_taps11`: four channels' 16 int32 sums in
    registers over every tap of a K x K kernel, then stored to their accumulator rows.

    The taps of kernel row ky from column 0 to 4 G - 1 (G = K // 4 groups of four) come
    from ``q``, a pixel and the three to its right; the T = K - 4 G columns left over come
    from ``v``, a pixel and the three below it, in V = ceil(K / 4) groups of four rows (zero
    weights past row K - 1). K = 9: 18 + 3 = 21 instructions a channel where groups of four
    along every row would take 27 (three of their twelve taps unused)."""
    g_n, t_n, v_n = k // VNNI_GROUP, k % VNNI_GROUP, -(-k // VNNI_GROUP)

    def codegen(context, builder, signature, args):
        sums_v, band_v, y, x, c = args
        sums_t, band_t = signature.args[:2]
        code = VectorCode(context, builder, 32, VNNI_LANES)

        def field(ty, value, name):  # a field of a NamedTuple argument
            i = ty.fields.index(name)
            return ty.types[i], builder.extract_value(value, i)

        q, v, w = (code.data(*field(band_t, band_v, name)) for name in ("q", "v", "w"))
        qs = field(band_t, band_v, "qs")[1]
        fn = builder.module.declare_intrinsic("llvm.x86.avx512.vpdpbusd.512",
                                              fnty=ir.FunctionType(code.vec, [code.vec] * 3))
        accs = [code.data(*field(sums_t, sums_v, name)) for name in TapSums._fields]
        per = k * g_n + v_n * t_n  # weight words of a channel
        # two sums a channel, the taps in turn: eight chains of dependent instructions
        sums = [code.full(0) for _ in range(8)]

        def dot(half, ptr, at, word):
            b = code.load(ptr, at)
            for ch in range(4):
                base = builder.add(builder.mul(builder.add(c, ir.Constant(c.type, ch)),
                                               ir.Constant(c.type, per)),
                                   ir.Constant(c.type, word))
                # b: the unsigned bytes (pixels), the splat: the signed ones (weights)
                sums[half + ch] = builder.call(fn, [sums[half + ch], b, code.splat(
                    builder.load(builder.gep(w, [base])))])

        def cell(row, col):
            return builder.add(builder.mul(builder.add(y, ir.Constant(y.type, row)), qs),
                               builder.add(x, ir.Constant(x.type, col)))

        taps = [(q, (ky, VNNI_GROUP * g)) for ky in range(k) for g in range(g_n)]
        taps += [(v, (VNNI_GROUP * vg, VNNI_GROUP * g_n + t)) for vg in range(v_n)
                 for t in range(t_n)]
        for word, (ptr, at) in enumerate(taps):  # the weight words are in this order
            dot(4 * (word & 1), ptr, cell(*at), word)
        for ch, acc in enumerate(accs):
            code.store(builder.add(sums[ch], sums[4 + ch]), acc, x)
        return context.get_dummy_value()

    return codegen


def _taps_signature(sums, band, y, x, c):
    return types.void(sums, band, y, x, c)


@intrinsic
def _taps9(typingctx, sums, band, y, x, c):
    """sums.ch<j>[x:x+16] = the tap sums of channel c + j for the 16 pixels from x of output
    row y (:func:`_taps_codegen`, K = 9) over the :class:`Band` ``band``; ``sums`` a
    :class:`TapSums`."""
    return _taps_signature(sums, band, y, x, c), _taps_codegen(9)


@intrinsic
def _taps11(typingctx, sums, band, y, x, c):
    """:func:`_taps9` for K = 11."""
    return _taps_signature(sums, band, y, x, c), _taps_codegen(11)


@njit(cache=True, inline="always")
def _pack4(a, b, c, d, out):
    """out[x] = a[x] | b[x] << 8 | c[x] << 16 | d[x] << 24 (uint8 rows of out's length): a loop
    over whole rows of its own, which LLVM vectorises (indexed from one row at four offsets
    it ran seven times slower)."""
    for x in range(out.shape[0]):
        out[x] = (np.uint32(a[x]) | np.uint32(b[x]) << np.uint32(8)
                  | np.uint32(c[x]) << np.uint32(16) | np.uint32(d[x]) << np.uint32(24))


@njit(cache=True)
def _band_quads(img, y0, r, q, v):
    """q[i, x] = the four pixels img[clamp(y0 - r + i), clamp(x - r + t)], t = 0..3, packed
    little-endian into a uint32 (the replicate border): a pixel of the padded band and the
    three to its right; v[i, x] the same of img[clamp(y0 - r + i + t), clamp(x - r)]: a
    pixel and the three below it."""
    h, w = img.shape
    n = q.shape[1]
    # x - r .. x - r + 3 inside the row: no clamp
    lo = min(r, n)
    hi = max(lo, min(n, w - VNNI_GROUP + 1 + r))
    for i in range(q.shape[0]):
        row = img[min(max(y0 - r + i, 0), h - 1)]
        qi = q[i]
        a = lo - r
        _pack4(row[a:a + hi - lo], row[a + 1:a + 1 + hi - lo], row[a + 2:a + 2 + hi - lo],
               row[a + 3:a + 3 + hi - lo], qi[lo:hi])
        for j in range(lo + n - hi):  # the borders: x < lo, then x >= hi
            x = j if j < lo else hi + j - lo
            word = np.uint32(0)
            for t in range(VNNI_GROUP):
                word |= np.uint32(row[min(max(x - r + t, 0), w - 1)]) << np.uint32(8 * t)
            qi[x] = word
    m = v.shape[1]
    x_lo = min(r, m)
    x_hi = max(x_lo, min(m, w + r))  # x - r inside the row
    for i in range(v.shape[0]):
        r0 = img[min(max(y0 - r + i, 0), h - 1)]
        r1 = img[min(max(y0 - r + i + 1, 0), h - 1)]
        r2 = img[min(max(y0 - r + i + 2, 0), h - 1)]
        r3 = img[min(max(y0 - r + i + 3, 0), h - 1)]
        vi = v[i]
        a, b = x_lo - r, x_hi - r
        _pack4(r0[a:b], r1[a:b], r2[a:b], r3[a:b], vi[x_lo:x_hi])
        for j in range(x_lo + m - x_hi):  # the borders: x < x_lo, then x >= x_hi
            x = j if j < x_lo else x_hi + j - x_lo
            xc = min(max(x - r, 0), w - 1)
            vi[x] = (np.uint32(r0[xc]) | np.uint32(r1[xc]) << np.uint32(8)
                     | np.uint32(r2[xc]) << np.uint32(16) | np.uint32(r3[xc]) << np.uint32(24))


@njit(cache=True)
def _vnni_sign_layer(q, v, wq, k, threshold, masks, acc, out):
    """out[y, x] = OR of masks[c] over the channels whose tap sum of the pixels exceeds
    threshold[c]: the sums four channels at a time over acc's width (whole blocks of 16,
    :func:`_taps9` / :func:`_taps11`; ``wq`` the weight words of ceil(C / 4) * 4 channels,
    zero past the C-th), the signs over out's."""
    rows, width = out.shape
    blocks = acc.shape[1]
    n_c = threshold.shape[0]
    band = Band(q.reshape(q.size), v.reshape(v.size), wq, q.shape[1])
    zero = masks[0] ^ masks[0]
    sums = TapSums(acc[0], acc[1], acc[2], acc[3])
    for y in range(rows):
        bits = out[y]
        bits[:] = zero
        for c in range(0, n_c, 4):
            if k == 9:
                for x in range(0, blocks, VNNI_LANES):
                    _taps9(sums, band, y, x, c)
            else:
                for x in range(0, blocks, VNNI_LANES):
                    _taps11(sums, band, y, x, c)
            for j in range(min(4, n_c - c)):
                t, m, aj = threshold[c + j], masks[c + j], acc[j]
                for x in range(width):
                    bits[x] |= m if aj[x] > t else zero


def vnni_signs(img: np.ndarray, weights: np.ndarray, bias: np.ndarray, offset: int,
               out: np.ndarray, band_rows: int) -> None:
    """``out`` = the descriptor of the single layer ``weights`` (C, 1, K, K), K = 9 or 11, by
    byte dot products (:func:`vnni_applies` says when), ``band_rows`` output rows at a time:
    the packed pixels of a band are all it holds besides the image and ``out``."""
    c_out, _, k, _ = weights.shape
    r = k // 2
    h, w = img.shape
    wide = -(-w // VNNI_LANES) * VNNI_LANES  # whole blocks of 16 pixels (the rest dropped)
    g_n, t_n, v_n = k // VNNI_GROUP, k % VNNI_GROUP, -(-k // VNNI_GROUP)
    c_pad = -(-c_out // 4) * 4
    kern = np.zeros((c_pad, v_n * VNNI_GROUP, k), np.int8)  # rows past K: zero
    kern[:c_out, :k] = weights[:, 0]
    rows_q = kern[:, :k, :VNNI_GROUP * g_n].reshape(c_pad, k * g_n, VNNI_GROUP)
    # the leftover columns by four rows: (channel, group of rows, column, row in the group)
    tail = kern[:, :, VNNI_GROUP * g_n:].reshape(c_pad, v_n, VNNI_GROUP, t_n)
    tail = tail.transpose(0, 1, 3, 2).reshape(c_pad, v_n * t_n, VNNI_GROUP)
    wq = np.ascontiguousarray(np.concatenate([rows_q, tail], axis=1)).view(np.int32)
    wq = wq.reshape(wq.size)
    # |offset * sum w - bias| <= |bias| + sum |w| * max|x|, which check_network holds in int32
    threshold = (offset * weights.astype(np.int64).sum(axis=(1, 2, 3))
                 - bias.astype(np.int64)).astype(np.int32)
    masks = np.array([1 << c for c in range(c_out)], dtype=out.dtype)
    # both quads of a row in rows of one length (the kernel's taps read past the block's
    # 16 pixels by up to K - 1)
    q = np.empty((band_rows + 2 * r, wide + k), np.uint32)
    v = np.empty_like(q)
    acc = np.empty((4, wide), np.int32)
    for y0 in range(0, h, band_rows):
        y1 = min(h, y0 + band_rows)
        band_q, band_v = q[:y1 - y0 + 2 * r], v[:y1 - y0 + 2 * r]
        _band_quads(img, y0, r, band_q, band_v)
        _vnni_sign_layer(band_q, band_v, wq, k, threshold, masks, acc, out[y0:y1])
