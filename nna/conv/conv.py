"""The NNA's CNN descriptor: the signs of an int8 network's last layer.

The network is a chain of 1..4 integer layers (:mod:`quant.intconv` defines their arithmetic:
int8 weights, int32 accumulators, the replicate border at every layer's input, per-channel
multiply-shift requantisation with ReLU between layers). The paper's descriptor is the one-layer
case (sections "Binary descriptors" and "Quantization"; 32 kernels of 9x9):

* Inputs: a uint8 image ``img`` (H, W); ``weights`` int8 (C, K, K) indexed [channel, ky, kx], K odd;
  ``bias`` int32 (C,); ``input_offset`` an int in 0..255 (the zero point of the input).
* ``x = int32(img) - input_offset``, so x is in -255..255.
* ``acc[c](y, x0) = bias[c] + sum over ky, kx of weights[c, ky, kx] * x[clamp(y + ky - r),
  clamp(x0 + kx - r)]`` with ``r = K // 2``, computed in an int32 accumulator. The border policy
  is replicate (coordinates clamped into the image), the same as the census.
* Bit c of the descriptor is ``1 if acc[c] > 0 else 0`` -- the sign of the output ("if the
  original number is bigger [than zero] we set the bit to 1, 0 otherwise"); LSB = channel 0.
  For a deeper network, acc is the last layer's accumulator.
* Output: uint32 (H, W) for C <= 32, uint64 for 32 < C <= 64.

Overflow: every product is at most 128 * 255 = 32640 in magnitude, so the sum of the K*K products
is at most ``K*K*32640`` (2,643,840 for 9x9). :func:`check_layer` rejects biases that could push
the accumulator out of int32, so the int32 accumulator never wraps and the result equals the
exact integer value (which the reference computes with Python ints).

:func:`cnn_descriptor_ref` is the one-layer definition read literally (a loop over pixels and
channels, Python ints); :func:`cnn_descriptor` and :func:`network_descriptor` run the fast form of
:mod:`quant.intconv` (:func:`~quant.intconv.int_signs`), which is tested equal to it and, for
networks, to the signs of :func:`~quant.intconv.int_forward_ref` (``signs_ref``).
"""

from __future__ import annotations

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.nna.census_unit.census import as_image_u8
from stereosim.quant.intconv import (
    IntNetwork,
    descriptor_dtype,
    int_forward,
    int_signs,
    network,
)

MAX_CHANNELS = 64
# The largest kernel size K: a K x K window needs K input rows in a submodule's line buffer
# (nna.geometry.check_line_buffer refuses a plan whose buffer is shorter), and nna.line_buffer_rows
# allows at most 64 rows, so the widest odd window is 63. Nothing in the paper (it tried 3x3 and
# 9x9) or the kernels bounds K more tightly: they are exact for K*K*MAX_PRODUCT < 2**31 (in
# float32 lanes up to K = 21, in float64 beyond: quant.intconv.lane_dtype;
# tests/nna/conv/test_conv.py runs K = 21 and 23).
MAX_KERNEL_SIZE = 63
# Largest |weight * (pixel - offset)|: -128 * -255.
MAX_PRODUCT = 128 * 255
INT32_MAX = 2**31 - 1
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


def _one_layer(img, weights, bias, input_offset) -> tuple[np.ndarray, IntNetwork]:
    """The image checked and the layer as a one-layer network (one input channel)."""
    img = as_image_u8(img)
    weights, bias, input_offset = check_layer(weights, bias, input_offset)
    return img, network((weights[:, None],), (bias,), (), (), input_offset)


def cnn_descriptor(img, weights, bias, input_offset) -> np.ndarray:
    """NNA binary descriptor of every pixel for one layer (see the module docstring).

    img: uint8 (H, W); weights: int8 (C, K, K); bias: int32 (C,); input_offset: int 0..255.
    Returns uint32 (H, W) for C <= 32, uint64 for C <= 64; bit c is the sign of channel c.
    """
    img, cnn = _one_layer(img, weights, bias, input_offset)
    return int_signs(img, *cnn.args)


def cnn_accumulators(img, weights, bias, input_offset) -> np.ndarray:
    """Raw int32 accumulators (H, W, C) of the descriptor layer, before the sign threshold."""
    img, cnn = _one_layer(img, weights, bias, input_offset)
    return int_forward(img, *cnn.args)


def network_descriptor(img, cnn: IntNetwork) -> np.ndarray:
    """The descriptor of a checked network (:func:`quant.intconv.network`): the signs of its
    last layer, uint32 (H, W) for up to 32 channels, uint64 for up to 64."""
    return int_signs(as_image_u8(img), *cnn.args)
