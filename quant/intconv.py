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
  :func:`nna.conv.cnn_accumulators`; bit c of the descriptor is ``acc[c] > 0``.

Overflow: :func:`check_network` bounds every accumulator by ``|bias| + sum |w| * max|x|`` (max|x|
is ``max(offset, 255 - offset)`` for the first layer and 127 after a requantisation) and refuses a
network whose bound exceeds int32, so the int32 accumulators never wrap. The product
``acc * mult`` is formed in int64 (at most 31 + 16 bits for the largest allowed ``z``).

Two implementations that must agree bit for bit: :func:`int_forward` (numba kernels, int32
accumulators) and :func:`int_forward_ref` (numpy int64, a different loop order, checked to fit
int32 after every layer).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stereosim.sim.errors import ConfigError

MAX_LAYERS = 4
MAX_OUT_CHANNELS = 64
MAX_Z_BITS = 16
INT32_MAX = 2**31 - 1
ACT_MAX = 127  # ReLU_127: the int8 activation between layers is clamped to 0..127
# floor(v / 2**h) is 0 or -1 for every h >= 62 when |v| < 2**62 (|acc * m| < 2**47 here), so the
# numpy form caps the shift at 62 (2**63 does not fit int64).
_SHIFT_LIMIT = 62


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


@njit(cache=True)
def _conv_kernel(xp, w, b, out):
    """out[c, y, x] = b[c] + sum w[c, ci, ky, kx] * xp[ci, y + ky, x + kx], int32 throughout."""
    c_out, c_in, k_size = w.shape[0], w.shape[1], w.shape[2]
    height, width = out.shape[1], out.shape[2]
    for c in range(c_out):
        for y in range(height):
            for x in range(width):
                out[c, y, x] = b[c]
        for ci in range(c_in):
            for ky in range(k_size):
                for kx in range(k_size):
                    wv = w[c, ci, ky, kx]
                    for y in range(height):
                        row = xp[ci, y + ky]
                        for x in range(width):
                            out[c, y, x] += wv * row[x + kx]


@njit(cache=True)
def _requant_kernel(acc, m, h, out):
    """out[c] = clamp(mul_shift(acc[c], m[c], h[c]), 0, 127)."""
    c_out, height, width = acc.shape
    for c in range(c_out):
        for y in range(height):
            for x in range(width):
                v = mul_shift(acc[c, y, x], m[c], h[c])
                if v < 0:
                    v = 0
                elif v > 127:
                    v = 127
                out[c, y, x] = v


def int_layer(x_i32, weights, bias) -> np.ndarray:
    """One integer conv layer (numba): x_i32 int32 (C_in, H, W) -> int32 accumulators (C_out, H, W).

    The caller guarantees (via :func:`check_network`) that the accumulators fit int32.
    """
    r = weights.shape[2] // 2
    xp = np.pad(np.ascontiguousarray(x_i32, dtype=np.int32), ((0, 0), (r, r), (r, r)), "edge")
    out = np.empty((weights.shape[0],) + x_i32.shape[1:], dtype=np.int32)
    _conv_kernel(xp, weights.astype(np.int32), bias.astype(np.int32), out)
    return out


def requantize(acc_i32, mult, shift) -> np.ndarray:
    """Per-channel ``clamp((acc * m) >> h, 0, 127)`` (numba) of int32 (C, H, W); returns int32."""
    out = np.empty(acc_i32.shape, dtype=np.int32)
    _requant_kernel(
        np.ascontiguousarray(acc_i32, dtype=np.int32),
        mult.astype(np.int64),
        shift.astype(np.int64),
        out,
    )
    return out


def int_forward(img, weights, biases, mult, shift, input_offset, z_bits=8) -> np.ndarray:
    """Integer inference (numba) of the network; returns the last layer's int32 (H, W, C_out)."""
    img = _as_image(img)
    weights, biases, mult, shift, input_offset = check_network(
        weights, biases, mult, shift, input_offset, z_bits
    )
    x_i32 = (img.astype(np.int32) - np.int32(input_offset))[None]
    for layer in range(len(weights)):
        acc = int_layer(x_i32, weights[layer], biases[layer])
        if layer == len(weights) - 1:
            return np.ascontiguousarray(acc.transpose(1, 2, 0))
        x_i32 = requantize(acc, mult[layer], shift[layer])
    raise AssertionError("unreachable")


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
