"""Winner-take-all, uniqueness check and sub-pixel refinement -- SVA disparity selection.

Definitions (the chip's), on the summed SGM cost S(p, d), d in [0, D):

- **WTA**: d*(p) = the smallest d with S(p, d) = min_k S(p, k).
- **Uniqueness** (margin u percent, 0 = off): let S1 = S(p, d*) and S2 = min S(p, d) over
  |d - d*| >= 2. The pixel is invalid when S2 * 100 < S1 * (100 + u): the winner does not beat
  every clearly different disparity by u percent.
- **Sub-pixel** with F fractional bits: output word q = (d* << F) + o where, for 0 < d* < D - 1,
  a = S(d* - 1), c = S(d*), b = S(d* + 1) and

      parabola:     o = round(2^F (a - b) / (2 (a + b - 2c)))      (0 when a + b - 2c = 0)
      equiangular:  o = round(2^F (a - b) / (2 max(a - c, b - c))) (0 when the max is 0)

  round = half up, computed with floor division only (quant.fixedpoint.div_round_half_up).
  o = 0 at d* = 0, d* = D - 1, when the fit is off, or when F = 0. |o| <= 2^(F-1) always.

Invalid output words are -1; the float disparity is q / 2^F with inf for invalid.
"""

import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit
from stereosim.quant.fixedpoint import div_round_half_up

INVALID = -1
SUBPIXEL_MODES = ("off", "parabola", "equiangular")


def subpixel_offset(a: int, c: int, b: int, mode: str, frac_bits: int) -> int:
    """The offset o of the module docstring (plain Python, used by the references)."""
    if mode == "off" or frac_bits == 0:
        return 0
    num = (a - b) << frac_bits
    if mode == "parabola":
        den = 2 * (a + b - 2 * c)
    else:
        den = 2 * max(a - c, b - c)
    if den <= 0:
        return 0
    return div_round_half_up(num, den)


def wta_ref(s, *, uniqueness: int, subpixel: str, frac_bits: int):
    """Naive reference over a whole volume: (q int32 (H, W), d_int int32 (H, W)).

    ``q`` is the output word with -1 where the uniqueness check fails; ``d_int`` the integer
    winner d* for every pixel (the LR check uses it).
    """
    h, w, dn = s.shape
    q = np.empty((h, w), np.int32)
    dint = np.empty((h, w), np.int32)
    for y in range(h):
        for x in range(w):
            costs = [int(v) for v in s[y, x]]
            s1 = min(costs)
            best = costs.index(s1)
            dint[y, x] = best
            far = [costs[d] for d in range(dn) if abs(d - best) >= 2]
            if uniqueness > 0 and far and min(far) * 100 < s1 * (100 + uniqueness):
                q[y, x] = INVALID
                continue
            o = 0
            if 0 < best < dn - 1:
                o = subpixel_offset(costs[best - 1], s1, costs[best + 1], subpixel, frac_bits)
            q[y, x] = (best << frac_bits) + o
    return q, dint


@njit(cache=True, inline="always")
def _min_u16(sx):
    """min sx as uint16: a vectorised reduction."""
    m = np.uint16(0xFFFF)
    for d in range(sx.shape[0]):
        m = min(m, sx[d])
    return m


@njit(cache=True)
def disparity_index(disparities):
    """0, 1, ..., D - 1 as uint16: the d of the vectorised passes of :func:`wta_pixel`.

    Read from an array rather than converted from the loop counter, the uint16 lanes
    vectorise (a counter converted per element does not)."""
    return np.arange(disparities).astype(np.uint16)


@njit(cache=True, inline="always")
def wta_pixel(sx, s1, idx, uniqueness, mode, frac_bits):
    """One pixel of :func:`wta_ref` from its costs ``sx`` (D,) uint16 and their minimum
    ``s1`` (which the SGM step computes on the way): (q, d*).

    ``idx`` is :func:`disparity_index`. The first index holding S1 by a branch-free pass over
    d in uint16 lanes, a minimum over ``d if S(d) == S1 else 0xFFFF``; the rest is
    :func:`wta_select`. ``mode``: 0 off, 1 parabola, 2 equiangular.
    """
    first = np.uint16(0xFFFF)
    for d in range(sx.shape[0]):
        first = min(first, idx[d] if sx[d] == s1 else np.uint16(0xFFFF))
    return wta_select(sx, s1, np.int64(first), idx, uniqueness, mode, frac_bits)


@njit(cache=True, inline="always")
def wta_select(sx, s1, best, idx, uniqueness, mode, frac_bits):
    """:func:`wta_pixel` once the winner is known: ``best`` = d*, the first d holding the
    minimum ``s1`` of ``sx`` (the fused SVA loop has it from the SGM's d-loop,
    :func:`sva.sgm.sgm.sgm_pixel`). The sub-pixel offset, and with the uniqueness check on, the
    runner-up over |d - d*| >= 2: a branch-free minimum over ``S(d) if d - (d* - 1) > 2
    (modulo 2^16) else 0xFFFF`` (0xFFFF is a legal S too, so whether such a d exists is
    decided apart). Returns (q, d*).
    """
    dn = sx.shape[0]
    # the neighbours are read (clamped) before any branch: in numba an array last used inside
    # a branch costs reference counting on every call, and this runs once per pixel
    a = np.int64(sx[max(best - 1, 0)])
    b = np.int64(sx[min(best + 1, dn - 1)])
    o = np.int64(0)
    if mode != 0 and frac_bits > 0 and 0 < best < dn - 1:
        c = np.int64(s1)
        if mode == 1:
            den = 2 * (a + b - 2 * c)
        else:
            den = 2 * max(a - c, b - c)
        if den > 0:
            o = div_round_half_up((a - b) << frac_bits, den)
    q = (best << frac_bits) + o
    # the runner-up only with the check on: a loop of 0 iterations otherwise, not a branch
    # around array code (which would cost reference counting on every pixel)
    n_far = dn if uniqueness > 0 else 0
    b1 = np.uint16(best - 1)
    far = np.uint16(0xFFFF)
    for d in range(n_far):
        far = min(far, sx[d] if np.uint16(idx[d] - b1) > np.uint16(2) else np.uint16(0xFFFF))
    has_far = best >= 2 or best + 2 < dn
    if uniqueness > 0 and has_far and np.int64(far) * 100 < np.int64(s1) * (100 + uniqueness):
        q = np.int64(INVALID)
    return q, best


@njit(cache=True)
def wta_row(s_row, idx, uniqueness, mode, frac_bits, q_row, dint_row):
    """One row of :func:`wta_ref`. ``mode``: 0 off, 1 parabola, 2 equiangular."""
    for x in range(s_row.shape[0]):
        sx = s_row[x]
        q_row[x], dint_row[x] = wta_pixel(sx, _min_u16(sx), idx, uniqueness, mode, frac_bits)


def subpixel_mode_code(mode: str) -> int:
    return SUBPIXEL_MODES.index(mode)


@njit(cache=True)
def _wta_volume(s, idx, uniqueness, mode, frac_bits, q, dint):
    for y in range(s.shape[0]):
        wta_row(s[y], idx, uniqueness, mode, frac_bits, q[y], dint[y])


def wta(s, *, uniqueness: int, subpixel: str, frac_bits: int):
    """Numba version of :func:`wta_ref` (same arguments and results)."""
    if not isinstance(s, np.ndarray) or s.ndim != 3 or s.dtype != np.uint16:
        raise InputError("the summed cost volume S must be a uint16 array (H, W, D)")
    if subpixel not in SUBPIXEL_MODES:
        raise InputError(f"sub-pixel mode must be one of {SUBPIXEL_MODES}, got {subpixel!r}")
    h, w, _ = s.shape
    q = np.empty((h, w), np.int32)
    dint = np.empty((h, w), np.int32)
    _wta_volume(
        np.ascontiguousarray(s),
        disparity_index(s.shape[2]),
        uniqueness,
        subpixel_mode_code(subpixel),
        frac_bits,
        q,
        dint,
    )
    return q, dint


def to_float(q, frac_bits: int) -> np.ndarray:
    """Output words to float32 disparities in pixels, inf where invalid (q < 0):
    float32(q) / 2^F (exact: a power of two), one pass (:func:`_to_float`)."""
    q = np.asarray(q)
    out = np.empty(q.shape, np.float32)
    _to_float(np.ascontiguousarray(q, dtype=np.int32).reshape(-1), np.float32(1 << frac_bits),
              out.reshape(-1))
    return out


@njit(cache=True)
def _to_float(q, scale, out):
    for i in range(q.shape[0]):
        out[i] = np.float32(np.inf) if q[i] < 0 else np.float32(q[i]) / scale
