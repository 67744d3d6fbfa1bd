"""Hamming matching cost -- the first stage of the SVA.

Definition (the chip's): for a left pixel p = (x, y) and a disparity d in [0, D), the left
descriptor at (x, y) is compared with the right descriptor at (x - d, y):

    C(x, y, d) = popcount(DL(x, y) XOR DR(x - d, y))      if x - d >= 0
    C(x, y, d) = B                                         otherwise (no right pixel to match)

where B is the descriptor width in bits -- the largest Hamming distance, so a match that would
fall outside the right image never wins against one that lies inside. Costs are uint8 (B <= 64).
"""

import numpy as np
from numba import types
from numba.extending import intrinsic

from stereosim.sim.errors import InputError
from stereosim.sim.kernel_cache import njit


def hamming_cost_ref(desc_l, desc_r, disparities: int, bits: int) -> np.ndarray:
    """Naive reference: the whole cost volume (H, W, D) as uint8, exactly as defined above."""
    h, w = desc_l.shape
    cost = np.empty((h, w, disparities), np.uint8)
    for y in range(h):
        for x in range(w):
            for d in range(disparities):
                if x - d >= 0:
                    cost[y, x, d] = bin(int(desc_l[y, x]) ^ int(desc_r[y, x - d])).count("1")
                else:
                    cost[y, x, d] = bits
    return cost


@intrinsic
def popcount(typingctx, value):
    """Number of set bits of an unsigned integer (LLVM's ctpop; a popcnt instruction, and
    vectorised when the compiler vectorises the loop around it). numba-only."""
    if not isinstance(value, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        fn = builder.module.declare_intrinsic("llvm.ctpop", [args[0].type])
        return builder.call(fn, [args[0]])

    return value(value), codegen


@njit(cache=True)
def cost_row(dl_row, dr_row, disparities, bits, out):
    """One row of the cost volume into ``out`` (W, D) uint8."""
    w = dl_row.shape[0]
    for x in range(w):
        a = dl_row[x]
        lim = min(disparities, x + 1)
        for d in range(lim):
            out[x, d] = np.uint8(popcount(a ^ dr_row[x - d]))
        for d in range(lim, disparities):
            out[x, d] = bits


@njit(cache=True)
def reverse_row(row, out):
    """``out[i] = row[W - 1 - i]``: with the right row reversed, the right pixels x - d of a
    fixed left pixel x are contiguous and ascending in d (out[W - 1 - x + d]), so the d-loops
    below are plain vector loads, not gathers."""
    w = row.shape[0]
    for i in range(w):
        out[i] = row[w - 1 - i]


@njit(cache=True)
def cost_row_add(dl_row, dr_rev, bits, sums):
    """``sums[x, d] += C(x, d)`` (uint16) for one row of the cost volume; ``dr_rev`` is the
    right row reversed (:func:`reverse_row`)."""
    w, dn = sums.shape
    bits16 = np.uint16(bits)
    for x in range(w):
        a = dl_row[x]
        lim = min(dn, x + 1)
        right = dr_rev[w - 1 - x :]
        sx = sums[x]
        for d in range(lim):
            sx[d] = np.uint16(sx[d] + np.uint16(popcount(a ^ right[d])))
        for d in range(lim, dn):
            sx[d] = np.uint16(sx[d] + bits16)


@njit(cache=True)
def cost_row_update(dl_in, dr_rev_in, dl_out, dr_rev_out, sums):
    """``sums[x, d] += C_in(x, d) - C_out(x, d)`` (uint16, modulo 2^16) for two rows of the
    cost volume: the vertical box sum slides down one row (the row entering the window in,
    the one leaving it out) without storing cost rows. Where x - d < 0 both costs are B and
    cancel, so only d <= x is visited."""
    w, dn = sums.shape
    for x in range(w):
        a_in = dl_in[x]
        a_out = dl_out[x]
        lim = min(dn, x + 1)
        r_in = dr_rev_in[w - 1 - x :]
        r_out = dr_rev_out[w - 1 - x :]
        sx = sums[x]
        for d in range(lim):
            c_in = np.uint16(popcount(a_in ^ r_in[d]))
            c_out = np.uint16(popcount(a_out ^ r_out[d]))
            sx[d] = np.uint16(np.uint16(sx[d] + c_in) - c_out)


@njit(cache=True)
def _cost_volume(desc_l, desc_r, disparities, bits, out):
    for y in range(desc_l.shape[0]):
        cost_row(desc_l[y], desc_r[y], disparities, bits, out[y])


def check_descriptor_pair(desc_l, desc_r) -> None:
    """Both descriptor images: same 2-D shape, unsigned integer words of the same dtype."""
    for name, a in (("left", desc_l), ("right", desc_r)):
        if not isinstance(a, np.ndarray) or a.ndim != 2:
            raise InputError(f"{name} descriptors must be a 2-D array (H, W)")
        if a.dtype not in (np.uint32, np.uint64):
            raise InputError(f"{name} descriptors must be uint32 or uint64, got {a.dtype}")
    if desc_l.shape != desc_r.shape or desc_l.dtype != desc_r.dtype:
        raise InputError(
            f"left and right descriptors differ: {desc_l.shape}/{desc_l.dtype} vs "
            f"{desc_r.shape}/{desc_r.dtype}"
        )


def hamming_cost(desc_l, desc_r, disparities: int, bits: int) -> np.ndarray:
    """Cost volume (H, W, D) uint8 with the numba kernel. ``bits`` = descriptor width."""
    check_descriptor_pair(desc_l, desc_r)
    if not 1 <= bits <= 64:
        raise InputError(f"descriptor width must be 1..64 bits, got {bits}")
    if disparities < 1:
        raise InputError(f"the disparity range must be at least 1, got {disparities}")
    out = np.empty(desc_l.shape + (disparities,), np.uint8)
    _cost_volume(
        np.ascontiguousarray(desc_l), np.ascontiguousarray(desc_r), disparities, np.uint8(bits), out
    )
    return out


def cosine_cost(feat_l, feat_r, disparities: int, bits: int) -> np.ndarray:
    """The float descriptor's matching cost on the Hamming scale, uint8 (H, W, D) -- not a chip
    stage: the "float cosine" column of the ablation (``benchmarks/ablation.py``) feeds it to
    the same SGM back end (:func:`sva.pipeline.sva_cost_volume`).

    ``C(x, y, d) = rint(bits / 2 * (1 - cos(FL(x, y), FR(x - d, y))))`` in 0..bits, and ``bits``
    where x - d < 0, with ``feat_*`` float (H, W, C). For +-1 vectors of C = bits channels this
    is exactly the Hamming distance of their signs (``C/2 * (1 - cos) = #differing``), so the
    float cost lives on the scale the SGM penalties were tuned for; ``rint`` rounds the float
    cost to the same bits + 1 levels. A zero feature vector has cosine 0 with everything.
    """
    feat_l = np.asarray(feat_l, dtype=np.float64)
    feat_r = np.asarray(feat_r, dtype=np.float64)
    if feat_l.ndim != 3 or feat_l.shape != feat_r.shape:
        raise InputError("float features must be two arrays (H, W, C) of the same shape")
    if not 1 <= bits <= 64 or disparities < 1:
        raise InputError("need 1..64 bits and at least one disparity")

    def unit(f):
        norm = np.sqrt((f * f).sum(axis=2, keepdims=True))
        return np.divide(f, norm, out=np.zeros_like(f), where=norm > 0)

    ul, ur = unit(feat_l), unit(feat_r)
    h, w, _ = ul.shape
    out = np.full((h, w, disparities), bits, np.uint8)
    half = bits / 2.0
    for d in range(min(disparities, w)):
        cos = np.einsum("ywc,ywc->yw", ul[:, d:], ur[:, : w - d])
        out[:, d:, d] = np.clip(np.rint(half * (1.0 - cos)), 0, bits).astype(np.uint8)
    return out
