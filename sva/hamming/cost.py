"""Hamming matching cost -- the first stage of the SVA.

Definition (the chip's): for a left pixel p = (x, y) and a disparity d in [0, D), the left
descriptor at (x, y) is compared with the right descriptor at (x - d, y):

    C(x, y, d) = popcount(DL(x, y) XOR DR(x - d, y))      if x - d >= 0
    C(x, y, d) = B                                         otherwise (no right pixel to match)

where B is the descriptor width in bits -- the largest Hamming distance, so a match that would
fall outside the right image never wins against one that lies inside. Costs are uint8 (B <= 64).

A descriptor of two parts (the hybrid: the CNN's bits 0 .. b_0 - 1, the census's b_0 ..
b_0 + b_1 - 1; :mod:`nna.descriptor`) is matched part by part with a weight w_k in 0..3 each
(:class:`CostParts`):

    C(x, y, d) = sum_k w_k popcount(part_k(DL(x, y) XOR DR(x - d, y)))   if x - d >= 0
    C(x, y, d) = B = sum_k w_k b_k                                        otherwise

with ``part_k(v) = (v >> o_k) & (2^b_k - 1)``, o_k the bits below part k. A weight of 0..3 is
a 2-bit register: the weighted distance is the distance, itself shifted left by one, or their
sum (a multiplexer and an adder). B <= 3 x 64 = 192, so costs stay uint8. One part of weight 1
is the plain Hamming distance above.
"""

from typing import NamedTuple

import numpy as np
from numba import types
from numba.extending import intrinsic

from stereosim.core.config.widths import largest_cost
from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit


class CostRegisters(NamedTuple):
    """The cost stage's registers as the numba kernels read them (:meth:`CostParts.registers`),
    for descriptor words of one dtype: ``mask`` keeps part 0's bits, ``shift`` brings part 1's
    down, ``w0`` and ``w1`` are the parts' weights (uint16), ``top`` is B (uint16) and ``two``
    says whether there is a part 1 (one part: the plain popcount)."""

    mask: np.unsignedinteger
    shift: np.unsignedinteger
    w0: np.uint16
    w1: np.uint16
    top: np.uint16
    two: bool


class CostParts(NamedTuple):
    """The descriptor's parts as the cost sees them: each part's ``bits`` (in bit order) and
    ``weights`` (one per part, 0..3)."""

    bits: tuple[int, ...]
    weights: tuple[int, ...]

    @property
    def top(self) -> int:
        """B: the largest cost, sum_k w_k b_k (a match outside the right image;
        :func:`~core.config.widths.largest_cost`, the rule the register widths follow)."""
        if len(self.bits) == 1:
            return self.weights[0] * self.bits[0]
        return largest_cost(self.bits, (self.weights,))

    def registers(self, dtype) -> CostRegisters:
        """The :class:`CostRegisters` of the numba kernels for descriptor words of ``dtype``."""
        low = self.bits[0]
        mask = dtype.type((1 << low) - 1) if low < 8 * dtype.itemsize else \
            dtype.type(np.iinfo(dtype).max)
        w1 = self.weights[1] if len(self.bits) > 1 else 0
        two = len(self.bits) > 1
        return CostRegisters(mask=mask, shift=dtype.type(low if two else 0),
                             w0=np.uint16(self.weights[0]), w1=np.uint16(w1),
                             top=np.uint16(self.top), two=two)


def cost_parts(bits, weights=None) -> CostParts:
    """The :class:`CostParts` of a descriptor of ``bits`` (an int: one part of weight 1; a
    tuple: each part's bits) with ``weights`` (default: 1 each). Bad widths or weights raise
    :class:`InputError`."""
    parts = (int(bits),) if isinstance(bits, (int, np.integer)) else tuple(int(b) for b in bits)
    weights = (1,) * len(parts) if weights is None else tuple(int(w) for w in weights)
    if not 1 <= len(parts) <= 2 or any(b < 1 for b in parts) or sum(parts) > 64:
        raise InputError(f"a descriptor is one or two parts of 1..64 bits in all, got {parts}")
    if len(weights) != len(parts) or any(not 0 <= w <= 3 for w in weights) or not any(weights):
        raise InputError(f"each of the descriptor's {len(parts)} part(s) needs a weight in "
                         f"0..3, not all 0; got {weights}")
    return CostParts(parts, weights)


def hamming_cost_ref(desc_l, desc_r, disparities: int, bits) -> np.ndarray:
    """Naive reference: the whole cost volume (H, W, D) as uint8, exactly as defined above.
    ``bits``: the descriptor width, or its :class:`CostParts`."""
    spec = bits if isinstance(bits, CostParts) else cost_parts(bits)
    h, w = desc_l.shape
    cost = np.empty((h, w, disparities), np.uint8)
    for y in range(h):
        for x in range(w):
            for d in range(disparities):
                if x - d < 0:
                    cost[y, x, d] = spec.top
                    continue
                v = int(desc_l[y, x]) ^ int(desc_r[y, x - d])
                total, below = 0, 0
                for b, weight in zip(spec.bits, spec.weights, strict=True):
                    total += weight * bin((v >> below) & ((1 << b) - 1)).count("1")
                    below += b
                cost[y, x, d] = total
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


@njit(cache=True, inline="always")
def weighted(v, cost):
    """The cost of the XOR ``v`` of two descriptors, ``cost`` the :class:`CostRegisters`:
    w_0 popcount(v & mask) + w_1 popcount(v >> shift)."""
    return np.uint16(cost.w0 * np.uint16(popcount(v & cost.mask))
                     + cost.w1 * np.uint16(popcount(v >> cost.shift)))


@njit(cache=True)
def cost_row(dl_row, dr_row, disparities, cost, out):
    """One row of the cost volume into ``out`` (W, D) uint8; ``cost``: the parts'
    :class:`CostRegisters`."""
    w = dl_row.shape[0]
    top = np.uint8(cost.top)
    for x in range(w):
        a = dl_row[x]
        lim = min(disparities, x + 1)
        if cost.two:
            for d in range(lim):
                out[x, d] = np.uint8(weighted(a ^ dr_row[x - d], cost))
        else:
            for d in range(lim):
                out[x, d] = np.uint8(popcount(a ^ dr_row[x - d]))
        for d in range(lim, disparities):
            out[x, d] = top


@njit(cache=True)
def reverse_row(row, out):
    """``out[i] = row[W - 1 - i]``: with the right row reversed, the right pixels x - d of a
    fixed left pixel x are contiguous and ascending in d (out[W - 1 - x + d]), so the d-loops
    below are plain vector loads, not gathers."""
    w = row.shape[0]
    for i in range(w):
        out[i] = row[w - 1 - i]


@njit(cache=True)
def cost_row_add(dl_row, dr_rev, cost, sums):
    """``sums[x, d] += C(x, d)`` (uint16) for one row of the cost volume; ``dr_rev`` is the
    right row reversed (:func:`reverse_row`), ``cost`` the parts' :class:`CostRegisters`."""
    w, dn = sums.shape
    top = np.uint16(cost.top)
    for x in range(w):
        a = dl_row[x]
        lim = min(dn, x + 1)
        right = dr_rev[w - 1 - x :]
        sx = sums[x]
        if cost.two:
            for d in range(lim):
                sx[d] = np.uint16(sx[d] + weighted(a ^ right[d], cost))
        else:
            for d in range(lim):
                sx[d] = np.uint16(sx[d] + np.uint16(popcount(a ^ right[d])))
        for d in range(lim, dn):
            sx[d] = np.uint16(sx[d] + top)


@njit(cache=True)
def cost_row_update(dl_in, dr_rev_in, dl_out, dr_rev_out, cost, sums):
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
        if cost.two:
            for d in range(lim):
                sx[d] = np.uint16(np.uint16(sx[d] + weighted(a_in ^ r_in[d], cost))
                                  - weighted(a_out ^ r_out[d], cost))
        else:
            for d in range(lim):
                c_in = np.uint16(popcount(a_in ^ r_in[d]))
                c_out = np.uint16(popcount(a_out ^ r_out[d]))
                sx[d] = np.uint16(np.uint16(sx[d] + c_in) - c_out)


@njit(cache=True)
def _cost_volume(desc_l, desc_r, disparities, cost, out):
    for y in range(desc_l.shape[0]):
        cost_row(desc_l[y], desc_r[y], disparities, cost, out[y])


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


def hamming_cost(desc_l, desc_r, disparities: int, bits) -> np.ndarray:
    """Cost volume (H, W, D) uint8 with the numba kernel. ``bits`` = descriptor width, or its
    :class:`CostParts`."""
    check_descriptor_pair(desc_l, desc_r)
    if not isinstance(bits, CostParts) and not 1 <= bits <= 64:
        raise InputError(f"descriptor width must be 1..64 bits, got {bits}")
    spec = bits if isinstance(bits, CostParts) else cost_parts(bits)
    if disparities < 1:
        raise InputError(f"the disparity range must be at least 1, got {disparities}")
    out = np.empty(desc_l.shape + (disparities,), np.uint8)
    _cost_volume(np.ascontiguousarray(desc_l), np.ascontiguousarray(desc_r), disparities,
                 spec.registers(desc_l.dtype), out)
    return out


def cosine_cost(feat_l, feat_r, disparities: int, bits: int) -> np.ndarray:
    """The float descriptor's matching cost on the Hamming scale, uint8 (H, W, D) -- not a chip
    stage: the "float cosine" column of the ablation (``benchmarks/ablation.py``) feeds it to
    the same SGM back end (:func:`sva.pipeline.pipeline.sva_cost_volume`).

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
