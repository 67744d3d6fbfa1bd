"""The NNA's integer descriptor: one int8 convolution layer thresholded on zero.

Definition (paper, sections "Binary descriptors" and "Quantization"; one layer of C kernels of
K x K taps, by default 32 kernels of 9x9)

* Inputs: a uint8 image ``img`` (H, W); ``weights`` int8 (C, K, K) indexed [channel, ky, kx], K odd;
  ``bias`` int32 (C,); ``input_offset`` an int in 0..255 (the zero point of the input).
* ``x = int32(img) - input_offset``, so x is in -255..255.
* ``acc[c](y, x0) = bias[c] + sum over ky, kx of weights[c, ky, kx] * x[clamp(y + ky - r),
  clamp(x0 + kx - r)]`` with ``r = K // 2``, computed in an int32 accumulator. The border policy
  is replicate (coordinates clamped into the image), the same as the census.
* Bit c of the descriptor is ``1 if acc[c] > 0 else 0`` -- the sign of the output ("if the
  original number is bigger [than zero] we set the bit to 1, 0 otherwise"); LSB = channel 0.
* Output: uint32 (H, W) for C <= 32, uint64 for 32 < C <= 64.

Overflow: every product is at most 128 * 255 = 32640 in magnitude, so the sum of the K*K products
is at most ``K*K*32640`` (2,643,840 for 9x9). :func:`check_layer` rejects biases that could push
the accumulator out of int32, so the int32 accumulator never wraps and the result equals the
exact integer value (which the reference computes with Python ints).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereosim.nna.census import as_image_u8
from stereosim.sim.errors import ConfigError

MAX_CHANNELS = 64
# The largest kernel size K: a K x K window needs K input rows in a submodule's line buffer
# (nna.geometry.check_line_buffer refuses a plan whose buffer is shorter), and nna.line_buffer_rows
# allows at most 64 rows, so the widest odd window is 63. Nothing in the paper (it tried 3x3 and
# 9x9) or the kernels bounds K more tightly: they are exact for K*K*MAX_PRODUCT < 2**31, in
# float32 up to K = 21 and in int32 beyond (tests/nna/test_conv.py runs K = 21 and 23).
MAX_KERNEL_SIZE = 63
# Largest |weight * (pixel - offset)|: -128 * -255.
MAX_PRODUCT = 128 * 255
INT32_MAX = 2**31 - 1
# Taps per pass of the innermost loop of channel_row (which hard-codes 3); kernel columns are
# zero-padded to a multiple of it.
_TAPS_PER_STEP = 3


def check_layer(weights, bias, input_offset) -> tuple[np.ndarray, np.ndarray, int]:
    """Validate one descriptor layer; return ``(weights, bias, input_offset)`` ready for use.

    weights: int8 (C, K, K) with 1 <= C <= 64 and K odd, at most :data:`MAX_KERNEL_SIZE` (63:
    the window must fit the largest line buffer, 64 rows); bias: int32 (C,) small enough that
    the int32 accumulator cannot overflow; input_offset: int in 0..255. Raises
    :class:`ConfigError` with a one-line message otherwise.
    """
    if not isinstance(weights, np.ndarray) or weights.dtype != np.int8:
        got = weights.dtype if isinstance(weights, np.ndarray) else type(weights).__name__
        raise ConfigError(
            f"weights must be an int8 numpy array (C, K, K), got {got}; "
            "quantise to -128..127 and convert with .astype(np.int8)"
        )
    if weights.ndim != 3 or weights.shape[1] != weights.shape[2]:
        raise ConfigError(
            f"weights must have shape (C, K, K) [channel, ky, kx], got {weights.shape}"
        )
    n_channels, k_size = weights.shape[0], weights.shape[1]
    if not 1 <= n_channels <= MAX_CHANNELS:
        raise ConfigError(
            f"weights must have 1..{MAX_CHANNELS} channels (one descriptor bit each), "
            f"got {n_channels}"
        )
    if k_size % 2 == 0:
        raise ConfigError(f"weights kernel size K must be odd (centred window), got {k_size}")
    if k_size > MAX_KERNEL_SIZE:
        raise ConfigError(
            f"weights kernel size {k_size}x{k_size} is larger than the {MAX_KERNEL_SIZE}x"
            f"{MAX_KERNEL_SIZE} window the largest NNA line buffer can hold "
            "(nna.line_buffer_rows <= 64): use a smaller kernel"
        )
    max_sum = k_size * k_size * MAX_PRODUCT  # < 2**31 for every K <= MAX_KERNEL_SIZE
    if not isinstance(bias, np.ndarray) or bias.dtype != np.int32:
        got = bias.dtype if isinstance(bias, np.ndarray) else type(bias).__name__
        raise ConfigError(f"bias must be an int32 numpy array (C,), got {got}")
    if bias.shape != (n_channels,):
        raise ConfigError(
            f"bias must have shape ({n_channels},) to match weights, got {bias.shape}"
        )
    bias_limit = INT32_MAX - max_sum
    if bias.size and int(np.abs(bias.astype(np.int64)).max()) > bias_limit:
        raise ConfigError(
            f"bias values must be within +-{bias_limit} so the int32 accumulator of a "
            f"{k_size}x{k_size} kernel cannot overflow, got max |bias| = "
            f"{int(np.abs(bias.astype(np.int64)).max())}"
        )
    if isinstance(input_offset, np.ndarray) and input_offset.ndim == 0:
        input_offset = input_offset[()]
    if not isinstance(input_offset, (int, np.integer)) or isinstance(input_offset, bool):
        raise ConfigError(f"input_offset must be an int in 0..255, got {input_offset!r}")
    if not 0 <= input_offset <= 255:
        raise ConfigError(f"input_offset must be in 0..255, got {int(input_offset)}")
    return np.ascontiguousarray(weights), np.ascontiguousarray(bias), int(input_offset)


def descriptor_dtype(n_channels: int) -> np.dtype:
    """Output dtype of the descriptor: uint32 for up to 32 channels, else uint64."""
    return np.dtype(np.uint32 if n_channels <= 32 else np.uint64)


def cnn_descriptor_ref(img, weights, bias, input_offset) -> np.ndarray:
    """Naive NNA descriptor, written as the definition in the module docstring reads.

    Loops over pixels and channels; coordinates are clamped explicitly and sums are Python ints.
    Slow: for tests and as the specification of :func:`cnn_descriptor`.
    """
    img = as_image_u8(img)
    weights, bias, input_offset = check_layer(weights, bias, input_offset)
    n_channels, k_size = weights.shape[0], weights.shape[1]
    r = k_size // 2
    height, width = img.shape
    x_i64 = img.astype(np.int64) - input_offset
    w_i64 = weights.astype(np.int64)
    taps = np.arange(k_size) - r
    out = np.zeros((height, width), dtype=descriptor_dtype(n_channels))
    for y in range(height):
        rows = np.clip(y + taps, 0, height - 1)
        for x in range(width):
            cols = np.clip(x + taps, 0, width - 1)
            patch = x_i64[np.ix_(rows, cols)]  # patch[ky, kx] = x[clamp(y+ky-r), clamp(x+kx-r)]
            descriptor = 0
            for c in range(n_channels):
                acc = int(bias[c]) + int(np.sum(w_i64[c] * patch))
                if acc > 0:
                    descriptor |= 1 << c
            out[y, x] = descriptor
    return out


@njit(cache=True, fastmath={"contract"})
def channel_row(xp, w_pad, bias_c, c, y, acc):
    """acc[x] = bias_c + sum over (ky, kx) of w_pad[c, ky, kx] * xp[y + ky, x + kx].

    ``w_pad`` is (C, K, Kp) with Kp a multiple of 3 and zeros beyond column K, so the innermost
    loop handles three taps per pass over the row (fewer loads and stores of ``acc``) and still
    vectorises along x. In int32 (``bias_c`` the channel's bias), or in float32 with
    ``bias_c = 0`` where :func:`f32_exact` holds -- then the sum is an exact integer-valued
    float and the caller adds the int32 bias after converting (fused multiply-adds, allowed by
    ``contract``, change nothing there and nothing in integers).
    """
    width = acc.shape[0]
    k_rows, k_cols = w_pad.shape[1], w_pad.shape[2]
    acc[:] = bias_c
    for ky in range(k_rows):
        row = xp[y + ky]
        for kx in range(0, k_cols, 3):
            w0 = w_pad[c, ky, kx]
            w1 = w_pad[c, ky, kx + 1]
            w2 = w_pad[c, ky, kx + 2]
            s0 = row[kx : kx + width]
            s1 = row[kx + 1 : kx + 1 + width]
            s2 = row[kx + 2 : kx + 2 + width]
            for x in range(width):
                acc[x] += w0 * s0[x] + w1 * s1[x] + w2 * s2[x]


# float32 holds every integer up to 2^24 exactly: while K*K*MAX_PRODUCT < 2^24 (K <= 21), every
# product and partial sum of a kernel's taps is such an integer, so float32 arithmetic -- in any
# order, fused multiply-add included -- gives the exact int32 sum. float32 lanes multiply-add
# about twice as fast as int32 ones (vpmulld is slow), so the descriptor kernels use them.
F32_EXACT = 1 << 24


def f32_exact(k_size: int) -> bool:
    """True if the K x K tap sums of :func:`channel_row` are exact in float32."""
    return k_size * k_size * MAX_PRODUCT < F32_EXACT


@njit(cache=True, fastmath={"contract"})
def _channel_rows4_f32(xp, w_pad, c, y, acc):
    """The float32 :func:`channel_row` (no bias) for channels c .. c + 3 at once into ``acc``
    (4, W): each input sample loaded feeds four channels' multiply-adds, which keeps the loop
    bound by arithmetic rather than by loads (about 1.6x faster than one channel per pass)."""
    width = acc.shape[1]
    k_rows, k_cols = w_pad.shape[1], w_pad.shape[2]
    a0, a1, a2, a3 = acc[0], acc[1], acc[2], acc[3]
    acc[:] = 0
    for ky in range(k_rows):
        row = xp[y + ky]
        for kx in range(0, k_cols, 3):
            s0 = row[kx : kx + width]
            s1 = row[kx + 1 : kx + 1 + width]
            s2 = row[kx + 2 : kx + 2 + width]
            u0, u1, u2 = w_pad[c, ky, kx], w_pad[c, ky, kx + 1], w_pad[c, ky, kx + 2]
            v0, v1, v2 = w_pad[c + 1, ky, kx], w_pad[c + 1, ky, kx + 1], w_pad[c + 1, ky, kx + 2]
            p0, p1, p2 = w_pad[c + 2, ky, kx], w_pad[c + 2, ky, kx + 1], w_pad[c + 2, ky, kx + 2]
            q0, q1, q2 = w_pad[c + 3, ky, kx], w_pad[c + 3, ky, kx + 1], w_pad[c + 3, ky, kx + 2]
            for x in range(width):
                x0, x1, x2 = s0[x], s1[x], s2[x]
                # one accumulation per tap, so that every tap is one fused multiply-add
                # (``acc + (u0 x0 + u1 x1 + u2 x2)`` would cost a multiply and an add more)
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


@njit(cache=True)
def sign_bits_rows_f32(xp, w_pad, bias, masks, y, acc4, acc, bits):
    """bits[x] |= masks[c] where bias[c] + (tap sum of channel c at row y, column x) > 0, for
    every channel: four at a time (:func:`_channel_rows4_f32`), the rest one by one. ``acc4``
    (4, W) and ``acc`` (W,) float32 scratch; ``bits`` (W,) and ``masks`` (C,) of one unsigned
    dtype, ``masks[c] = 1 << c``."""
    n_channels = w_pad.shape[0]
    c = 0
    while c + 4 <= n_channels:
        _channel_rows4_f32(xp, w_pad, c, y, acc4)
        for j in range(4):
            _sign_bits_f32(acc4[j], bias[c + j], masks[c + j], bits)
        c += 4
    while c < n_channels:
        channel_row(xp, w_pad, np.float32(0), c, y, acc)
        _sign_bits_f32(acc, bias[c], masks[c], bits)
        c += 1


@njit(cache=True)
def _sign_bits_f32(acc, bias_c, mask, bits):
    """bits[x] |= mask where bias_c + acc[x] > 0 (acc an exact integer-valued float32 row)."""
    zero = mask ^ mask
    for x in range(acc.shape[0]):
        bits[x] |= mask if np.int32(acc[x]) > -bias_c else zero


@njit(cache=True)
def _descriptor_kernel(xp, w_pad, bias, masks, out):
    """Descriptor bits of every pixel: bit c of out[y, x] = acc[c] > 0 (masks[c] = 1 << c)."""
    height, width = out.shape
    n_channels = w_pad.shape[0]
    acc = np.empty(width, dtype=np.int32)
    bits = np.zeros(width, dtype=out.dtype)
    zero = bits[0]
    for y in range(height):
        bits[:] = zero
        for c in range(n_channels):
            channel_row(xp, w_pad, bias[c], c, y, acc)
            mask = masks[c]
            for x in range(width):
                bits[x] |= mask if acc[x] > 0 else zero
        out[y, :] = bits


@njit(cache=True)
def _descriptor_kernel_f32(xp, w_pad, bias, masks, out):
    """:func:`_descriptor_kernel` on float32 lanes (``xp``, ``w_pad`` float32; exact, see
    :func:`f32_exact`)."""
    height, width = out.shape
    acc = np.empty(width, dtype=np.float32)
    acc4 = np.empty((4, width), dtype=np.float32)
    bits = np.zeros(width, dtype=out.dtype)
    zero = bits[0]
    for y in range(height):
        bits[:] = zero
        sign_bits_rows_f32(xp, w_pad, bias, masks, y, acc4, acc, bits)
        out[y, :] = bits


@njit(cache=True)
def _accumulator_kernel(xp, w_pad, bias, out):
    """Raw int32 accumulators: out[y, x, c] = acc[c] at (y, x)."""
    height, width, n_channels = out.shape
    acc = np.empty(width, dtype=np.int32)
    for y in range(height):
        for c in range(n_channels):
            channel_row(xp, w_pad, bias[c], c, y, acc)
            for x in range(width):
                out[y, x, c] = acc[x]


def _prepare(img, weights, bias, input_offset):
    """Validate, then pad the centred input once and pad the kernels' columns to a multiple of 3."""
    img = as_image_u8(img)
    weights, bias, input_offset = check_layer(weights, bias, input_offset)
    n_channels, k_size = weights.shape[0], weights.shape[1]
    r = k_size // 2
    k_cols = -(-k_size // _TAPS_PER_STEP) * _TAPS_PER_STEP
    extra = k_cols - k_size
    x_i32 = img.astype(np.int32) - np.int32(input_offset)
    # Replicate border on all sides; the `extra` columns on the right only meet zero weights.
    xp = np.pad(x_i32, ((r, r), (r, r + extra)), mode="edge")
    w_pad = np.zeros((n_channels, k_size, k_cols), dtype=np.int32)
    w_pad[:, :, :k_size] = weights
    return img, xp, w_pad, bias




def cnn_descriptor(img, weights, bias, input_offset) -> np.ndarray:
    """NNA binary descriptor of every pixel (see the module docstring).

    img: uint8 (H, W); weights: int8 (C, K, K); bias: int32 (C,); input_offset: int 0..255.
    Returns uint32 (H, W) for C <= 32, uint64 for C <= 64; bit c is the sign of channel c.
    """
    img, xp, w_pad, bias = _prepare(img, weights, bias, input_offset)
    n_channels = w_pad.shape[0]
    dtype = descriptor_dtype(n_channels)
    masks = np.array([1 << c for c in range(n_channels)], dtype=dtype)
    out = np.empty(img.shape, dtype=dtype)
    if f32_exact(w_pad.shape[1]):
        _descriptor_kernel_f32(xp.astype(np.float32), w_pad.astype(np.float32), bias, masks, out)
    else:
        _descriptor_kernel(xp, w_pad, bias, masks, out)
    return out


def cnn_accumulators(img, weights, bias, input_offset) -> np.ndarray:
    """Raw int32 accumulators (H, W, C) of the descriptor layer, before the sign threshold."""
    img, xp, w_pad, bias = _prepare(img, weights, bias, input_offset)
    out = np.empty(img.shape + (w_pad.shape[0],), dtype=np.int32)
    _accumulator_kernel(xp, w_pad, bias, out)
    return out
