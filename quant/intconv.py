"""Integer inference of a 1..4 layer int8 network, as the NNA runs it.

Definition (for an input image ``img`` uint8 (H, W) and ``L`` layers):

* ``x_0 = int32(img) - input_offset`` (one channel; values in -255..255).
* Layer ``l`` has ``weights[l]`` int8 (C_out, C_in, K, K) indexed [out, in, ky, kx] (K odd) and
  ``biases[l]`` int32 (C_out,). Its int32 accumulator is::

      acc[c](y, x) = bias[c] + sum over ci, ky, kx of
                     weights[c, ci, ky, kx] * x_l[ci, clamp(y + ky - r), clamp(x + kx - r)]

  with ``r = K // 2`` and the replicate border policy (coordinates clamped into the image) applied
  to the input of every layer, stride 1, output the same size as the input.
* Between layers (l < L - 1), per output channel c, the integer multiply-shift requantisation
  followed by the ReLU clamp to the int8 range::

      x_{l+1}[c] = clamp((int64(acc[c]) * mult[l][c]) >> shift[l][c], 0, 127)

  ``>>`` is an arithmetic shift, i.e. ``floor(v / 2**h)`` also for negative ``v``; a shift of 63 or
  more gives ``0`` or ``-1`` (the limit of the floor), which the clamp turns into 0.
* The output of the last layer is its int32 accumulator, returned as (H, W, C) like
  :func:`nna.conv.conv.cnn_accumulators`; bit c of the descriptor is ``acc[c] > 0``.

Overflow: :func:`check_network` bounds every accumulator by ``|bias| + sum |w| * max|x|`` (max|x|
is ``max(offset, 255 - offset)`` for the first layer and 127 after a requantisation) and refuses a
network whose bound exceeds int32, so the int32 accumulators never wrap. The product
``acc * mult`` is formed in int64 (at most 31 + 16 bits for the largest allowed ``z``).

Two implementations that must agree bit for bit: :func:`int_forward_ref` (numpy int64, the
definition tap by tap, checked to fit int32 after every layer) and the fast form
:func:`int_forward` / :func:`int_signs` (numba kernels over row bands through every layer, in
float lanes that are exact for the layer's worst case, :func:`lane_dtype`; a single 9x9 or
11x11 layer on a CPU with AVX512-VNNI by byte dot products instead, :mod:`quant.vnni`). The
NNA's descriptor is :func:`int_signs`; its naive form ``signs_ref(int_forward_ref(...))``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.kernel_cache import njit
from stereosim.quant.vnni import vnni_applies, vnni_signs

MAX_LAYERS = 4
MAX_OUT_CHANNELS = 64
MAX_Z_BITS = 16
INT32_MAX = 2**31 - 1
ACT_MAX = 127  # ReLU_127: the int8 activation between layers is clamped to 0..127
# floor(v / 2**h) is 0 or -1 for every h >= 62 when |v| < 2**62 (|acc * m| < 2**47 here), so the
# numpy form caps the shift at 62 (2**63 does not fit int64).
_SHIFT_LIMIT = 62


class IntNetwork(NamedTuple):
    """A checked integer network (:func:`network`): per layer int8 ``weights`` (C_out, C_in, K,
    K) and int32 ``biases``; ``mult``/``shift`` per non-last layer; the input's zero point and
    the multiply-shift's bit width."""

    weights: tuple
    biases: tuple
    mult: tuple
    shift: tuple
    input_offset: int
    z_bits: int = 8

    @property
    def n_layers(self) -> int:
        return len(self.weights)

    @property
    def halves(self) -> tuple[int, ...]:
        """Each layer's half kernel r = K // 2."""
        return tuple(int(w.shape[2]) // 2 for w in self.weights)

    @property
    def reach(self) -> int:
        """Rows (and columns) on each side of a pixel its descriptor reads: the sum of the
        layers' half kernels (the receptive field is 2 reach + 1 wide)."""
        return sum(self.halves)

    @property
    def channels(self) -> int:
        """The last layer's output channels: the descriptor's bits."""
        return int(self.weights[-1].shape[0])

    @property
    def layer_macs(self) -> tuple[int, ...]:
        """Multiply-accumulates per output pixel of each layer: K * K * C_in * C_out."""
        return tuple(int(np.prod(w.shape)) for w in self.weights)

    @property
    def args(self) -> tuple:
        """The positional arguments of :func:`int_forward`, :func:`int_signs` and the refs."""
        return (self.weights, self.biases, self.mult, self.shift, self.input_offset, self.z_bits)


def network(weights, biases, mult, shift, input_offset, z_bits=8) -> IntNetwork:
    """:func:`check_network`'s checked network as an :class:`IntNetwork`."""
    w, b, m, h, offset = check_network(weights, biases, mult, shift, input_offset, z_bits)
    return IntNetwork(w, b, m, h, offset, int(z_bits))


@njit(cache=True, inline="always")
def mul_shift(acc, m, h):
    """``floor(acc * m / 2**h)`` with int64 product and arithmetic shift (h >= 63 -> 0 or -1)."""
    v = np.int64(acc) * np.int64(m)
    if h >= 63:
        return np.int64(-1) if v < 0 else np.int64(0)
    return v >> np.int64(h)


def mul_shift_ref(acc, m, h) -> np.ndarray:
    """Numpy form of :func:`mul_shift` on arrays (broadcasting), int64: floor division by 2**h."""
    v = np.asarray(acc, dtype=np.int64) * np.asarray(m, dtype=np.int64)
    h_i64 = np.minimum(np.asarray(h, dtype=np.int64), _SHIFT_LIMIT)
    return np.floor_divide(v, np.left_shift(np.int64(1), h_i64))


def _as_image(img) -> np.ndarray:
    if not isinstance(img, np.ndarray) or img.dtype != np.uint8 or img.ndim != 2:
        got = (
            f"{img.dtype} array of shape {img.shape}"
            if isinstance(img, np.ndarray)
            else type(img).__name__
        )
        raise ConfigError(f"image must be a uint8 (H, W) numpy array, got {got}")
    if img.size == 0:
        raise ConfigError("image must not be empty")
    return np.ascontiguousarray(img)


def _int_array(value, name, dtype, lo, hi) -> np.ndarray:
    """An integer array whose values lie in [lo, hi], converted to ``dtype``; else ConfigError."""
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "iu":
        got = value.dtype if isinstance(value, np.ndarray) else type(value).__name__
        raise ConfigError(f"{name} must be an integer numpy array, got {got}")
    if value.size and (int(value.min()) < lo or int(value.max()) > hi):
        raise ConfigError(
            f"{name} values must lie in {lo}..{hi}, got {int(value.min())}..{int(value.max())}"
        )
    return np.ascontiguousarray(value.astype(dtype))


def check_network(weights, biases, mult, shift, input_offset, z_bits=8):
    """Validate a 1..4 layer integer network; return it as tuples of contiguous arrays.

    weights: sequence of int8 (C_out, C_in, K, K), K odd, C_in of layer 0 is 1 and of layer l the
    C_out of layer l - 1, at most 64 output channels in the last layer; biases: int32 (C_out,);
    mult, shift: one integer array (C_out,) per non-last layer with values in 0..2**z_bits - 1;
    input_offset: int 0..255; z_bits: 1..16. Every accumulator's worst case must fit int32.
    Raises :class:`ConfigError` with a one-line message otherwise.
    """
    if isinstance(z_bits, bool) or not isinstance(z_bits, (int, np.integer)):
        raise ConfigError(f"z_bits must be an int in 1..{MAX_Z_BITS}, got {z_bits!r}")
    if not 1 <= z_bits <= MAX_Z_BITS:
        raise ConfigError(f"z_bits must be in 1..{MAX_Z_BITS}, got {int(z_bits)}")
    if isinstance(input_offset, np.ndarray) and input_offset.ndim == 0:
        input_offset = input_offset[()]
    if isinstance(input_offset, bool) or not isinstance(input_offset, (int, np.integer)):
        raise ConfigError(f"input_offset must be an int in 0..255, got {input_offset!r}")
    if not 0 <= input_offset <= 255:
        raise ConfigError(f"input_offset must be in 0..255, got {int(input_offset)}")
    input_offset = int(input_offset)
    n_layers = len(weights)
    if not 1 <= n_layers <= MAX_LAYERS:
        raise ConfigError(f"the network must have 1..{MAX_LAYERS} layers, got {n_layers}")
    if len(biases) != n_layers:
        raise ConfigError(f"need one bias per layer ({n_layers}), got {len(biases)}")
    if len(mult) != n_layers - 1 or len(shift) != n_layers - 1:
        raise ConfigError(
            f"need mult and shift for each of the {n_layers - 1} non-last layers, "
            f"got {len(mult)} and {len(shift)}"
        )
    hmax = 2**z_bits - 1
    x_max = max(input_offset, 255 - input_offset)
    c_in = 1
    out_w, out_b, out_m, out_h = [], [], [], []
    for layer, (w, b) in enumerate(zip(weights, biases)):
        if not isinstance(w, np.ndarray) or w.dtype != np.int8:
            got = w.dtype if isinstance(w, np.ndarray) else type(w).__name__
            raise ConfigError(f"weights[{layer}] must be an int8 numpy array, got {got}")
        if w.ndim != 4 or w.shape[2] != w.shape[3] or w.shape[2] % 2 == 0 or w.shape[0] < 1:
            raise ConfigError(
                f"weights[{layer}] must have shape (C_out, C_in, K, K) with K odd, got {w.shape}"
            )
        if w.shape[1] != c_in:
            raise ConfigError(
                f"weights[{layer}] has {w.shape[1]} input channels, expected {c_in} "
                f"({'the image' if layer == 0 else f'outputs of layer {layer - 1}'})"
            )
        c_out = w.shape[0]
        if not isinstance(b, np.ndarray) or b.dtype != np.int32:
            got = b.dtype if isinstance(b, np.ndarray) else type(b).__name__
            raise ConfigError(f"biases[{layer}] must be an int32 numpy array, got {got}")
        if b.shape != (c_out,):
            raise ConfigError(f"biases[{layer}] must have shape ({c_out},), got {b.shape}")
        bound = np.abs(w.astype(np.int64)).sum(axis=(1, 2, 3)) * x_max
        bound += np.abs(b.astype(np.int64))
        if int(bound.max()) > INT32_MAX:
            raise ConfigError(
                f"layer {layer}: worst-case accumulator {int(bound.max())} exceeds int32; "
                "reduce the weights or the bias"
            )
        if layer < n_layers - 1:
            out_m.append(_int_array(mult[layer], f"mult[{layer}]", np.int32, 0, hmax))
            out_h.append(_int_array(shift[layer], f"shift[{layer}]", np.int32, 0, hmax))
            if out_m[-1].shape != (c_out,) or out_h[-1].shape != (c_out,):
                raise ConfigError(
                    f"mult[{layer}] and shift[{layer}] must have shape ({c_out},), "
                    f"got {out_m[-1].shape} and {out_h[-1].shape}"
                )
        elif c_out > MAX_OUT_CHANNELS:
            raise ConfigError(
                f"the last layer has {c_out} channels; at most {MAX_OUT_CHANNELS} descriptor bits"
            )
        out_w.append(np.ascontiguousarray(w))
        out_b.append(np.ascontiguousarray(b))
        c_in = c_out
        x_max = ACT_MAX
    return tuple(out_w), tuple(out_b), tuple(out_m), tuple(out_h), input_offset


# ---- the fast form: row bands through every layer, exact float lanes ------------------------
#
# float32 holds every integer up to 2**24 exactly, float64 up to 2**53. A layer whose worst-case
# tap sum ``max_c sum |w_c| * max|x|`` stays below that (:func:`lane_dtype`) computes every
# product and partial sum exactly in those lanes, in any order, fused multiply-adds included;
# the int32 bias is added after converting back. float32 lanes multiply-add about twice as fast
# as int32 ones (vpmulld is slow); every shipped layer fits them (single9x9 at most 2,643,840,
# a 3x3x32 layer of ReLU_127 inputs at most 4,681,728).
F32_EXACT = 1 << 24
F64_EXACT = 1 << 53
# Output rows per band: each layer computes the band plus the rows the later layers read
# around it (their half kernels), so a band of 32 rows costs a 4-layer 3x3 chain about 9 % more
# than the frame's own rows.
BAND_ROWS = 32
# Kernel columns are zero-padded to a multiple of this (the innermost loop takes three taps).
TAPS_PER_STEP = 3


def tap_bound(weights: np.ndarray, x_max: int) -> int:
    """The largest |sum over taps of w * x| of a layer whose inputs satisfy |x| <= x_max."""
    return int(np.abs(weights.astype(np.int64)).sum(axis=(1, 2, 3)).max()) * int(x_max)


def lane_dtype(weights: np.ndarray, x_max: int) -> np.dtype:
    """float32 if the layer's tap sums are exact in it, else float64 (always exact: the sums
    fit int32, :func:`check_network`)."""
    return np.dtype(np.float32 if tap_bound(weights, x_max) < F32_EXACT else np.float64)


@njit(cache=True, fastmath={"contract"})
def _rows4(xp, w_pad, c, y, acc4):
    """acc4[j, x] = tap sum of output channel c + j at row y, column x, for j = 0..3: each
    input sample loaded feeds four channels' multiply-adds (the loop stays bound by arithmetic
    rather than by loads), three taps per pass, vectorised along x; one accumulation per tap, so
    that each is one fused multiply-add."""
    c_in, k_rows, k_cols = w_pad.shape[1], w_pad.shape[2], w_pad.shape[3]
    width = acc4.shape[1]
    a0, a1, a2, a3 = acc4[0], acc4[1], acc4[2], acc4[3]
    acc4[:] = 0
    for ci in range(c_in):
        for ky in range(k_rows):
            row = xp[ci, y + ky]
            for kx in range(0, k_cols, 3):
                s0 = row[kx:kx + width]
                s1 = row[kx + 1:kx + 1 + width]
                s2 = row[kx + 2:kx + 2 + width]
                u0, u1, u2 = w_pad[c, ci, ky, kx:kx + 3]
                c1 = c + 1
                v0, v1, v2 = w_pad[c1, ci, ky, kx:kx + 3]
                c2 = c + 2
                p0, p1, p2 = w_pad[c2, ci, ky, kx:kx + 3]
                c3 = c + 3
                q0, q1, q2 = w_pad[c3, ci, ky, kx:kx + 3]
                for x in range(width):
                    x0, x1, x2 = s0[x], s1[x], s2[x]
                    a = a0[x]
                    a += u0 * x0
                    a += u1 * x1
                    a += u2 * x2
                    a0[x] = a
                    b = a1[x]
                    b += v0 * x0
                    b += v1 * x1
                    b += v2 * x2
                    a1[x] = b
                    e = a2[x]
                    e += p0 * x0
                    e += p1 * x1
                    e += p2 * x2
                    a2[x] = e
                    f = a3[x]
                    f += q0 * x0
                    f += q1 * x1
                    f += q2 * x2
                    a3[x] = f


@njit(cache=True, fastmath={"contract"})
def _rows1(xp, w_pad, c, y, acc1):
    """acc1[x] = tap sum of output channel c at row y, column x (the channels left over after
    the groups of four)."""
    c_in, k_rows, k_cols = w_pad.shape[1], w_pad.shape[2], w_pad.shape[3]
    width = acc1.shape[0]
    acc1[:] = 0
    for ci in range(c_in):
        for ky in range(k_rows):
            row = xp[ci, y + ky]
            for kx in range(0, k_cols, 3):
                s0 = row[kx:kx + width]
                s1 = row[kx + 1:kx + 1 + width]
                s2 = row[kx + 2:kx + 2 + width]
                u0, u1, u2 = w_pad[c, ci, ky, kx:kx + 3]
                for x in range(width):
                    a = acc1[x]
                    a += u0 * s0[x]
                    a += u1 * s1[x]
                    a += u2 * s2[x]
                    acc1[x] = a


@njit(cache=True)
def _tap_sums(xp, w_pad, c, y, acc4):
    """Tap sums of the output channels from c at row y into acc4[0 .. n): four channels
    (:func:`_rows4`) while four are left, else one (:func:`_rows1` into acc4[0]); returns n."""
    if c + 4 <= w_pad.shape[0]:
        _rows4(xp, w_pad, c, y, acc4)
        return 4
    _rows1(xp, w_pad, c, y, acc4[0])
    return 1


@njit(cache=True)
def _sign_row(acc, bias_c, mask, bits):
    """bits[x] |= mask where int32(acc[x]) + bias_c > 0 (acc an exact integer-valued row)."""
    zero = mask ^ mask
    limit = -bias_c
    for x in range(acc.shape[0]):
        bits[x] |= mask if np.int32(acc[x]) > limit else zero


@njit(cache=True)
def _requant_row(acc, bias_c, m, h, out):
    """out[x] = clamp(mul_shift(int32(acc[x]) + bias_c, m, h), 0, 127), in the dtype of out."""
    for x in range(acc.shape[0]):
        v = mul_shift(np.int32(acc[x]) + bias_c, m, h)
        if v < 0:
            v = 0
        elif v > ACT_MAX:
            v = ACT_MAX
        out[x] = v


@njit(cache=True)
def _acc_row(acc, bias_c, out):
    """out[x] = int32(acc[x]) + bias_c: the int32 accumulators of a row of tap sums."""
    for x in range(acc.shape[0]):
        out[x] = np.int32(acc[x]) + bias_c


@njit(cache=True)
def _layer_rows(xp, w_pad, bias, requant, masks, out):
    """A layer's output rows from its tap sums (of ``w_pad`` over ``xp``, as :func:`_rows4`),
    each row's taken while they are in cache (no accumulator leaves the row's scratch), into
    ``out`` (C, rows, W) in one of three forms, chosen by the arguments that are None (numba
    compiles one form a combination: a branch on an argument that is None is pruned):

    * ``masks`` given: the descriptor, in out[0] (``out`` (1, rows, W)): the OR of masks[c]
      over the channels c whose accumulator bias[c] + tap sum at row y, column x is > 0
      (:func:`_sign_row`);
    * ``requant`` = (mult, shift) given: the requantised activations (:func:`_requant_row`;
      ``out`` may be a view into the next layer's input);
    * neither: the int32 accumulators (:func:`_acc_row`; a transposed view of (rows, W, C)
      writes them channel last)."""
    rows, width = out.shape[1], out.shape[2]
    acc4 = np.empty((4, width), dtype=xp.dtype)
    for y in range(rows):
        if masks is not None:
            out[0, y] = masks[0] ^ masks[0]
        c = np.int64(0)  # not a literal 0: numba would compile _tap_sums once more for it
        while c < w_pad.shape[0]:
            n = _tap_sums(xp, w_pad, c, y, acc4)
            for j in range(n):
                k = c + j
                if masks is not None:
                    _sign_row(acc4[j], bias[k], masks[k], out[0, y])
                elif requant is not None:
                    _requant_row(acc4[j], bias[k], requant[0][k], requant[1][k], out[k, y])
                else:
                    _acc_row(acc4[j], bias[k], out[k, y])
            c += n


@njit(cache=True)
def _requant_rows(acc, m, h, out):
    """out[c, y, x] = clamp(mul_shift(acc[c, y, x], m[c], h[c]), 0, 127) of int32 ``acc``."""
    for c in range(acc.shape[0]):
        for y in range(acc.shape[1]):
            _requant_row(acc[c, y], np.int32(0), m[c], h[c], out[c, y])


def _pad_taps(w: np.ndarray, dtype) -> np.ndarray:
    """(C_out, C_in, K, Kp) in ``dtype``, the kernel columns zero-padded to a multiple of 3."""
    k = w.shape[3]
    k_cols = -(-k // TAPS_PER_STEP) * TAPS_PER_STEP
    out = np.zeros(w.shape[:3] + (k_cols,), dtype=dtype)
    out[..., :k] = w
    return out


def band_ranges(halves: tuple[int, ...], height: int, y0: int, y1: int) -> list[tuple[int, int]]:
    """For output rows [y0, y1) of the last layer: the rows [a, b) each layer must produce,
    the input image's first (index 0, then layer 0's outputs ... the last layer's [y0, y1)).
    A layer of half kernel r reads rows [a - r, b + r) of its input, clamped into the frame
    (the replicate border repeats the frame's edge rows, which are computed anyway)."""
    ranges = [(y0, y1)]
    a, b = y0, y1
    for r in reversed(halves):
        a, b = max(0, a - r), min(height, b + r)
        ranges.append((a, b))
    return ranges[::-1]


def _replicate_border(xp: np.ndarray, top: int, rows: int, r: int, width: int) -> None:
    """The replicate border, in place: ``xp`` (C, n, Wp) holds a layer's input in rows
    [top, top + rows) and columns [r, r + width); every other column of those rows repeats
    the nearest of them, then every row above (below) repeats the first (last) of them."""
    inner = xp[:, top : top + rows]
    inner[:, :, :r] = inner[:, :, r : r + 1]
    inner[:, :, r + width :] = inner[:, :, r + width - 1 : r + width]
    xp[:, :top] = xp[:, top : top + 1]
    xp[:, top + rows :] = xp[:, top + rows - 1 : top + rows]


def _padded(x: np.ndarray, lo: int, a: int, b: int, r: int, k_cols: int, dtype) -> np.ndarray:
    """Layer input rows [a - r, b + r) and columns [-r, W - r + k_cols - 1) with the replicate
    border, from ``x`` (C, n, W) holding rows [lo, lo + n) (the rows the border clamps into)."""
    n_ch, n, width = x.shape
    first, last = max(lo, a - r), min(lo + n, b + r)
    xp = np.empty((n_ch, b - a + 2 * r, width + k_cols - 1), dtype=dtype)
    top = first - (a - r)
    xp[:, top : top + last - first, r : r + width] = x[:, first - lo : last - lo]
    _replicate_border(xp, top, last - first, r, width)
    return xp


class _LayerPlan(NamedTuple):
    """One layer of :func:`forward_bands`: its kernel ``w_pad`` in exact float lanes, its half
    kernel ``r`` and a flat buffer that holds any band's padded input (C_in, rows, W + Kp - 1)."""

    w_pad: np.ndarray
    r: int
    buffer: np.ndarray

    def band_input(self, a: int, b: int, width: int) -> np.ndarray:
        """The padded input of output rows [a, b) of a frame ``width`` wide: a contiguous
        (C_in, b - a + 2r, width + Kp - 1) view of the buffer."""
        shape = (self.w_pad.shape[1], b - a + 2 * self.r, width + self.w_pad.shape[3] - 1)
        return self.buffer[: shape[0] * shape[1] * shape[2]].reshape(shape)


def _layer_plans(cnn, width: int, band_rows: int) -> list[_LayerPlan]:
    """Each layer's :class:`_LayerPlan` for bands of ``band_rows`` output rows: a layer's
    input spans the band plus the half kernels of it and of every layer after it, each side."""
    weights, _, _, _, input_offset = cnn
    halves = [w.shape[2] // 2 for w in weights]
    x_max = max(input_offset, 255 - input_offset)
    plans = []
    for layer, w in enumerate(weights):
        w_pad = _pad_taps(w, lane_dtype(w, x_max))
        rows = band_rows + 2 * sum(halves[layer:])
        size = w.shape[1] * rows * (width + w_pad.shape[3] - 1)
        plans.append(_LayerPlan(w_pad, halves[layer], np.empty(size, w_pad.dtype)))
        x_max = ACT_MAX
    return plans


def forward_bands(img, cnn, out, band_rows: int = BAND_ROWS) -> None:
    """Run the checked network ``cnn`` = (weights, biases, mult, shift, input_offset) over
    ``img`` band by band into ``out``: the descriptor (H, W) of unsigned ints
    (:func:`int_signs`) or the last layer's int32 accumulators (H, W, C) (:func:`int_forward`).
    Each layer's requantised outputs go straight into the next layer's padded input buffer;
    the buffers are allocated once per call."""
    weights, biases, mult, shift, input_offset = cnn
    height, width = img.shape
    plans = _layer_plans(cnn, width, band_rows)
    halves = tuple(p.r for p in plans)
    shifts = [(np.asarray(m, np.int64), np.asarray(h, np.int64)) for m, h in zip(mult, shift)]
    n_out = weights[-1].shape[0]
    masks = np.array([1 << c for c in range(n_out)], dtype=descriptor_dtype(n_out))
    for y0 in range(0, height, band_rows):
        y1 = min(height, y0 + band_rows)
        ranges = band_ranges(halves, height, y0, y1)
        lo, hi = ranges[0]
        a, b = ranges[1]
        r = plans[0].r
        xp = plans[0].band_input(a, b, width)
        top = lo - (a - r)
        xp[0, top : top + hi - lo, r : r + width] = img[lo:hi]
        xp[0, top : top + hi - lo, r : r + width] -= input_offset
        _replicate_border(xp, top, hi - lo, r, width)
        for layer, plan in enumerate(plans[:-1]):
            a_next, b_next = ranges[layer + 2]
            r_next = plans[layer + 1].r
            xp_next = plans[layer + 1].band_input(a_next, b_next, width)
            top = a - (a_next - r_next)
            inner = xp_next[:, top : top + b - a, r_next : r_next + width]
            _layer_rows(xp, plan.w_pad, biases[layer], shifts[layer], None, inner)
            _replicate_border(xp_next, top, b - a, r_next, width)
            xp, a, b = xp_next, a_next, b_next
        if out.ndim == 2:
            _layer_rows(xp, plans[-1].w_pad, biases[-1], None, masks, out[None, y0:y1])
        else:
            _layer_rows(xp, plans[-1].w_pad, biases[-1], None, None,
                        out[y0:y1].transpose(2, 0, 1))


def int_layer_rows(cnn: IntNetwork, layer: int, x, lo: int, a: int, b: int) -> np.ndarray:
    """Output rows [a, b) of layer ``layer`` of the checked network ``cnn``, computed from the
    input rows a line buffer received: ``x`` holds the layer's input rows [lo, lo + n) over the
    columns of its region -- the uint8 image rows (n, W) for layer 0, the int32 activations
    (C_in, n, W) of the layer before otherwise. The replicate border clamps into the rows and
    columns given, so a caller gives the frame's edge rows where a window leaves the frame and
    keeps only the outputs whose window lies within the columns given. Returns, for a layer
    before the last, its requantised activations int32 (C_out, b - a, W); for the last, the
    descriptors (b - a, W) (bit c: ``acc[c] > 0``, as :func:`int_signs`)."""
    weights, biases, mult, shift, offset, _ = cnn.args
    w = weights[layer]
    if layer == 0:
        x = (np.asarray(x, np.int32) - np.int32(offset))[None]
        x_max = max(offset, 255 - offset)
    else:
        x_max = ACT_MAX
    w_pad = _pad_taps(w, lane_dtype(w, x_max))
    xp = _padded(np.asarray(x), lo, a, b, w.shape[2] // 2, w_pad.shape[3], w_pad.dtype)
    if layer == len(weights) - 1:
        out_dtype = descriptor_dtype(w.shape[0])
        masks = np.array([1 << c for c in range(w.shape[0])], dtype=out_dtype)
        out = np.empty((b - a, x.shape[2]), dtype=out_dtype)
        _layer_rows(xp, w_pad, biases[layer], None, masks, out[None])
        return out
    out = np.empty((w.shape[0], b - a, x.shape[2]), dtype=np.int32)
    requant = (np.asarray(mult[layer], np.int64), np.asarray(shift[layer], np.int64))
    _layer_rows(xp, w_pad, biases[layer], requant, None, out)
    return out


def int_layer(x_i32, weights, bias) -> np.ndarray:
    """One integer conv layer: x_i32 int32 (C_in, H, W) -> int32 accumulators (C_out, H, W),
    in exact float lanes (the caller guarantees, via :func:`check_network`, that they fit
    int32)."""
    x_max = int(np.abs(x_i32).max()) if x_i32.size else 0
    w_pad = _pad_taps(weights, lane_dtype(weights, max(x_max, 1)))
    height = x_i32.shape[1]
    xp = _padded(np.asarray(x_i32), 0, 0, height, weights.shape[2] // 2, w_pad.shape[3],
                 w_pad.dtype)
    out = np.empty((weights.shape[0],) + x_i32.shape[1:], dtype=np.int32)
    _layer_rows(xp, w_pad, bias.astype(np.int32), None, None, out)
    return out


def requantize(acc_i32, mult, shift) -> np.ndarray:
    """Per-channel ``clamp((acc * m) >> h, 0, 127)`` of int32 (C, H, W); returns int32."""
    out = np.empty(acc_i32.shape, dtype=np.int32)
    _requant_rows(np.ascontiguousarray(acc_i32, dtype=np.int32), mult.astype(np.int64),
                  shift.astype(np.int64), out)
    return out


def int_forward(img, weights, biases, mult, shift, input_offset, z_bits=8, *,
                band_rows: int = BAND_ROWS) -> np.ndarray:
    """Integer inference of the network (the fast form: row bands, exact float lanes); returns
    the last layer's int32 accumulators (H, W, C_out)."""
    img = _as_image(img)
    cnn = check_network(weights, biases, mult, shift, input_offset, z_bits)
    out = np.empty(img.shape + (cnn[0][-1].shape[0],), dtype=np.int32)
    forward_bands(img, cnn, out, band_rows)
    return out


def descriptor_dtype(n_channels: int) -> np.dtype:
    """The descriptor's dtype: uint32 for up to 32 channels, else uint64."""
    return np.dtype(np.uint32 if n_channels <= 32 else np.uint64)


def int_signs(img, weights, biases, mult, shift, input_offset, z_bits=8, *,
              band_rows: int = BAND_ROWS) -> np.ndarray:
    """The descriptor: bit c of out[y, x] is ``acc[c] > 0`` of the last layer (LSB = channel
    0); uint32 (H, W) for up to 32 channels, uint64 for up to 64. The fast form, band by band,
    each row's signs taken while its tap sums are in cache: no frame of accumulators is ever
    held; a single wide layer on a CPU with AVX512-VNNI by byte dot products instead
    (:func:`vnni_signs`)."""
    img = _as_image(img)
    cnn = check_network(weights, biases, mult, shift, input_offset, z_bits)
    out = np.empty(img.shape, dtype=descriptor_dtype(cnn[0][-1].shape[0]))
    if vnni_applies(cnn[0]):
        vnni_signs(img, cnn[0][0], cnn[1][0], cnn[4], out, band_rows)
    else:
        forward_bands(img, cnn, out, band_rows)
    return out


def signs_ref(acc: np.ndarray) -> np.ndarray:
    """The descriptor of accumulators (H, W, C): bit c set where acc[..., c] > 0."""
    n_out = acc.shape[2]
    out = np.zeros(acc.shape[:2], dtype=descriptor_dtype(n_out))
    for c in range(n_out):
        out |= (acc[..., c] > 0).astype(out.dtype) << out.dtype.type(c)
    return out


def _layer_ref(x_i64, w, b) -> np.ndarray:
    """Numpy int64 layer: for each tap, a (C_out x C_in) matrix times the shifted input planes."""
    k_size = w.shape[2]
    r = k_size // 2
    height, width = x_i64.shape[1:]
    xp = np.pad(x_i64, ((0, 0), (r, r), (r, r)), mode="edge")
    acc = np.broadcast_to(b.astype(np.int64)[:, None, None], (w.shape[0], height, width)).copy()
    w_i64 = w.astype(np.int64)
    for ky in range(k_size):
        for kx in range(k_size):
            window = xp[:, ky : ky + height, kx : kx + width]
            acc += np.einsum("oi,ihw->ohw", w_i64[:, :, ky, kx], window)
    if acc.size and (acc.min() < -(2**31) or acc.max() > INT32_MAX):
        raise OverflowError("an accumulator left the int32 range")
    return acc


def int_forward_ref(img, weights, biases, mult, shift, input_offset, z_bits=8) -> np.ndarray:
    """Independent numpy emulation of :func:`int_forward` (int64, checked to fit int32)."""
    img = _as_image(img)
    weights, biases, mult, shift, input_offset = check_network(
        weights, biases, mult, shift, input_offset, z_bits
    )
    x_i64 = (img.astype(np.int64) - input_offset)[None]
    for layer in range(len(weights)):
        acc = _layer_ref(x_i64, weights[layer], biases[layer])
        if layer == len(weights) - 1:
            return acc.transpose(1, 2, 0).astype(np.int32)
        scaled = mul_shift_ref(acc, mult[layer][:, None, None], shift[layer][:, None, None])
        x_i64 = np.clip(scaled, 0, ACT_MAX)
    raise AssertionError("unreachable")
