"""The NNA's single wide layer by byte dot products (AVX512-VNNI): :func:`vnni_signs` is
:func:`quant.intconv.int_signs` for a network of one 9x9 or 11x11 layer on the grey image, on a
CPU that has the instruction (:func:`vnni_applies`), bit for bit.

``vpdpbusd`` adds to each of 16 int32 lanes the four products of the lane's uint8 bytes of one
operand with the int8 bytes of the other: 64 products an instruction, against the 8 float32
lanes of a multiply-add in :mod:`quant.intconv`'s loops (LLVM keeps those at 256 bits on this
CPU). numba does not vectorise the convolution into it, so :func:`_dpbusd3` emits it
(``llvm.x86.avx512.vpdpbusd.512``), as sva/cost.py's popcount emits ``llvm.ctpop``. A layer of
one input channel (the grey image) then needs no offset in its lanes: its tap sum is ``sum w * p
- offset * sum w`` with p the uint8 pixels, so bit c is ``sum w_c * p > offset * sum w_c -
bias_c``. The pixels go four to an int32 (:func:`_band_quads`: a pixel and the three to its
right), the K taps of a kernel row in three groups of four (zero weights after the K-th): K = 9
or 11 (K is odd) leaves 3 or 1 of the 12 taps unused. Every product and partial sum is an exact
int32 (at most 255 * 128 * 121 in magnitude). Four channels share each load of the pixels
(:func:`_dpbusd3c4`).
"""

from __future__ import annotations

import os

import numpy as np
from llvmlite import binding, ir
from numba import types
from numba.core import config as numba_config
from numba.extending import intrinsic

from stereosim.quant.vectors import VectorCode
from stereosim.sim.kernel_cache import njit

VNNI_LANES = 16  # int32 lanes of one instruction
VNNI_GROUP = 4  # bytes a lane
VNNI_GROUPS = 3  # groups of a kernel row: taps 0..11


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
    AVX512-VNNI, a network of one layer on the grey image with K = 9 or 11 (narrower kernels
    would waste most of the three groups: the float lanes are faster for them), and
    ``STEREOSIM_VNNI`` not ``0``."""
    if not HAS_VNNI or os.environ.get("STEREOSIM_VNNI", "1").strip() == "0":
        return False
    k = weights[0].shape[2]
    return len(weights) == 1 and weights[0].shape[1] == 1 and 9 <= k <= VNNI_GROUPS * VNNI_GROUP


def _dpbusd_codegen(channels: int):
    """The code of :func:`_dpbusd3` (one channel) and :func:`_dpbusd3c4` (four): load each
    channel's 16 int32 accumulators, add the dot products of the three groups of q (each group
    loaded once for every channel) with the channel's three weights, store them back."""

    def codegen(context, builder, signature, args):
        i_v, q_v, j_v = args[channels:channels + 3]
        weights = args[channels + 3:]
        code = VectorCode(context, builder, 32, VNNI_LANES)
        q = code.data(signature.args[channels + 1], q_v)
        fn = builder.module.declare_intrinsic("llvm.x86.avx512.vpdpbusd.512",
                                              fnty=ir.FunctionType(code.vec, [code.vec] * 3))
        accs = [code.data(signature.args[ch], args[ch]) for ch in range(channels)]
        sums = [code.load(acc, i_v) for acc in accs]
        for g in range(VNNI_GROUPS):
            b = code.load(q, j_v, VNNI_GROUP * g)
            for ch in range(channels):
                # b: the unsigned bytes (pixels), the splat: the signed ones (weights)
                sums[ch] = builder.call(fn, [sums[ch], b,
                                             code.splat(weights[ch * VNNI_GROUPS + g])])
        for acc, total in zip(accs, sums):
            code.store(total, acc, i_v)
        return context.get_dummy_value()

    return codegen


@intrinsic
def _dpbusd3(typingctx, acc, i, q, j, w0, w1, w2):
    """acc[i:i+16] += over g = 0, 1, 2: the dot products of the bytes of q[j + 4 g + lane] with
    those of w_g; the accumulator stays in a register across the three groups."""
    return types.void(acc, i, q, j, w0, w1, w2), _dpbusd_codegen(1)


@intrinsic
def _dpbusd3c4(typingctx, a0, a1, a2, a3, i, q, j, w00, w01, w02, w10, w11, w12, w20, w21, w22,
               w30, w31, w32):
    """:func:`_dpbusd3` for four channels at once (accumulators a0..a3, their three groups of
    weights in turn): each block of q loaded once for the four."""
    sig = types.void(a0, a1, a2, a3, i, q, j, w00, w01, w02, w10, w11, w12, w20, w21, w22,
                     w30, w31, w32)
    return sig, _dpbusd_codegen(4)


@njit(cache=True)
def _band_quads(img, y0, r, q):
    """q[i, x] = the four pixels img[clamp(y0 - r + i), clamp(x - r + t)], t = 0..3, packed
    little-endian into a uint32 (the replicate border): a pixel of the padded band and the
    three to its right."""
    h, w = img.shape
    n = q.shape[1]
    # x - r .. x - r + 3 inside the row: no clamp, a loop LLVM vectorises
    lo = min(r, n)
    hi = max(lo, min(n, w - VNNI_GROUP + 1 + r))
    for i in range(q.shape[0]):
        row = img[min(max(y0 - r + i, 0), h - 1)]
        qi = q[i]
        for x in range(lo, hi):
            qi[x] = (np.uint32(row[x - r]) | np.uint32(row[x - r + 1]) << np.uint32(8)
                     | np.uint32(row[x - r + 2]) << np.uint32(16)
                     | np.uint32(row[x - r + 3]) << np.uint32(24))
        for j in range(lo + n - hi):  # the borders: x < lo, then x >= hi
            x = j if j < lo else hi + j - lo
            word = np.uint32(0)
            for t in range(VNNI_GROUP):
                word |= np.uint32(row[min(max(x - r + t, 0), w - 1)]) << np.uint32(8 * t)
            qi[x] = word


@njit(cache=True)
def _vnni_sign_layer(q, wq, threshold, masks, acc, out):
    """out[y, x] = OR of masks[c] over the channels whose tap sum of the pixels exceeds
    threshold[c]; wq[c, ky] = kernel row ky's three groups of channel c, q the quads of the
    padded rows; the dot products over acc's width (whole blocks of 16), the signs over out's."""
    rows, width = out.shape
    blocks = acc.shape[1]
    k = wq.shape[1]
    zero = masks[0] ^ masks[0]
    for y in range(rows):
        bits = out[y]
        bits[:] = zero
        c = 0
        while c < wq.shape[0]:
            n = 4 if c + 4 <= wq.shape[0] else 1
            acc[:n] = 0
            a0, a1, a2, a3 = acc[0], acc[1], acc[2], acc[3]
            for ky in range(k):
                qr = q[y + ky]
                if n == 4:
                    u, v, p, s = wq[c, ky], wq[c + 1, ky], wq[c + 2, ky], wq[c + 3, ky]
                    for x in range(0, blocks, VNNI_LANES):
                        _dpbusd3c4(a0, a1, a2, a3, x, qr, x, u[0], u[1], u[2], v[0], v[1], v[2],
                                   p[0], p[1], p[2], s[0], s[1], s[2])
                else:
                    w0, w1, w2 = wq[c, ky, 0], wq[c, ky, 1], wq[c, ky, 2]
                    for x in range(0, blocks, VNNI_LANES):
                        _dpbusd3(a0, x, qr, x, w0, w1, w2)
            for j in range(n):
                t, m, aj = threshold[c + j], masks[c + j], acc[j]
                for x in range(width):
                    bits[x] |= m if aj[x] > t else zero
            c += n


def vnni_signs(img: np.ndarray, weights: np.ndarray, bias: np.ndarray, offset: int,
               out: np.ndarray, band_rows: int) -> None:
    """``out`` = the descriptor of the single layer ``weights`` (C, 1, K, K), K = 9 or 11, by
    byte dot products (:func:`vnni_applies` says when), ``band_rows`` output rows at a time:
    the packed pixels of a band are all it holds besides the image and ``out``."""
    c_out, _, k, _ = weights.shape
    r = k // 2
    h, w = img.shape
    wide = -(-w // VNNI_LANES) * VNNI_LANES  # whole blocks of 16 pixels (the rest dropped)
    taps = np.zeros((c_out, k, VNNI_GROUPS * VNNI_GROUP), np.int8)
    taps[:, :, :k] = weights[:, 0]
    wq = taps.view(np.int32).reshape(c_out, k, VNNI_GROUPS).copy()
    # |offset * sum w - bias| <= |bias| + sum |w| * max|x|, which check_network holds in int32
    threshold = (offset * weights.astype(np.int64).sum(axis=(1, 2, 3))
                 - bias.astype(np.int64)).astype(np.int32)
    masks = np.array([1 << c for c in range(c_out)], dtype=out.dtype)
    q = np.empty((band_rows + 2 * r, wide + VNNI_GROUPS * VNNI_GROUP), np.uint32)
    acc = np.empty((4, wide), np.int32)
    for y0 in range(0, h, band_rows):
        y1 = min(h, y0 + band_rows)
        band = q[:y1 - y0 + 2 * r]
        _band_quads(img, y0, r, band)
        _vnni_sign_layer(band, wq, threshold, masks, acc, out[y0:y1])
