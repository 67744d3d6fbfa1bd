"""The paper's int8 quantizer: channel-wise exhaustive scale search, layer by layer (Alg. 1-3).

A float model (:class:`FloatModel`) is a list of conv layers (weights float (C_out, C_in, K, K),
bias float (C_out,), stride 1, 'same' replicate padding) with ReLU between layers and none after
the last, fed with ``x = (pixel - input_offset) * input_scale``. The NNA sees the integer
``pixel - input_offset``, so the integer input carries ``a_0 = 1 / input_scale`` integer units per
float unit.

Scale mapping (paper: ``W_dot = round(W * S / tau)``, S searched in ``(0, max W]`` with a step
1000x smaller). Read as "S is the float value mapped onto tau = 127" (the only reading under which
``S = max|W|`` is the naive min/max mapping and a larger S wastes levels, as the paper says), for
output channel i of layer l with ``M_i = max|W_i|`` and ``N = n_steps`` (default 1000):

* candidates ``S_k = k * M_i / N`` for k = N, N-1, ..., 1 (step ``M_i / N``, all of (0, M_i]);
* weight scale ``s_k = tau / S_k``; ``W_dot = clip(round(W_i * s_k), -128, 127)`` (``round`` is
  numpy's ``rint``, ties to even). k = N maps the largest weight to +-127; smaller k saturates the
  largest weights to use more levels for the others, the trade-off the search arbitrates;
* the input of layer l carries ``a_l`` integer units per float unit, so the accumulator carries
  ``s_k * a_l`` and the bias is ``B_dot = round(B_i * s_k * a_l)`` (clipped so the accumulator's
  worst case stays inside int32).

For each candidate the distance (:mod:`quant.distances`) between ``s_k * a_l * Gamma_i(X)`` (the
float layer fed with the float input X) and the integer accumulator ``Gamma_dot_i(X_dot)`` (fed with
the already-quantised output X_dot of the previous integer layer, Algorithm 3) is evaluated on
sampled pixels of the calibration images, and the smallest wins; exact ties go to the smaller l1
distance, then to the larger S (fewer saturated weights).

Activations (non-last layers): the next layer's input carries ``a_{l+1} = 127 / q`` integer units
per float unit, q being the ``act_quantile`` quantile (default 0.9999) of ``ReLU(Gamma_l(X))`` over
all sampled pixels and channels; channel i's requantisation target is the accumulator rescaled,
``t = acc * a_{l+1} / (s_i * a_l)``, and (m_i, h_i) in ``[0, 2**z - 1]**2`` minimise
``mean |clamp(t, 0, 127) - clamp((acc * m) >> h, 0, 127)|`` over the samples (Algorithm 2), ties
going to the smaller h, then the smaller m.

Per-channel activation ranges (``equalize``, the default): the next layer reads all of its input
channels with one ``a_{l+1}``, so before the searches the float model is rescaled, channel by
channel, into the same function with every hidden channel's quantile at one value
(:func:`equalize_channels`); the artifact's integer network is that of the rescaled model.

Agreement figures are measured on every pixel of the calibration images.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.kernel_cache import njit
from stereosim.core.progress import progress_bar
from stereosim.quant.artifact import QuantizedModel, check_quantized
from stereosim.quant.distances import get_distance, l1
from stereosim.quant.intconv import (
    ACT_MAX,
    INT32_MAX,
    MAX_Z_BITS,
    int_layer,
    mul_shift,
    requantize,
)

TAU = 127
# Largest integer float32 represents exactly: integer matmuls below it are exact in float32.
_F32_EXACT = 2**24


@dataclass(frozen=True, slots=True, kw_only=True)
class FloatModel:
    """A float conv model: ``weights[l]`` (C_out, C_in, K, K), ``biases[l]`` (C_out,), ReLU between
    layers, none after the last; input ``(pixel - input_offset) * input_scale``."""

    weights: tuple
    biases: tuple
    input_offset: int
    input_scale: float

    def __post_init__(self):
        if not 1 <= len(self.weights) <= 4 or len(self.biases) != len(self.weights):
            raise ConfigError(
                f"a float model needs 1..4 layers with one bias each, got {len(self.weights)} "
                f"weights and {len(self.biases)} biases"
            )
        c_in = 1
        for layer, (w, b) in enumerate(zip(self.weights, self.biases)):
            w = np.asarray(w)
            b = np.asarray(b)
            if w.ndim != 4 or w.shape[1] != c_in or w.shape[2] != w.shape[3] or w.shape[2] % 2 == 0:
                raise ConfigError(
                    f"float weights[{layer}] must be (C_out, {c_in}, K, K) with K odd, "
                    f"got {w.shape}"
                )
            if b.shape != (w.shape[0],):
                raise ConfigError(f"float biases[{layer}] must be ({w.shape[0]},), got {b.shape}")
            if not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
                raise ConfigError(f"float layer {layer} has non-finite weights or bias")
            c_in = w.shape[0]
        if not 0 <= int(self.input_offset) <= 255:
            raise ConfigError(f"input_offset must be in 0..255, got {self.input_offset}")
        if not (np.isfinite(self.input_scale) and self.input_scale > 0):
            raise ConfigError(f"input_scale must be a positive number, got {self.input_scale}")


@dataclass(frozen=True, slots=True, kw_only=True)
class QuantizerConfig:
    """Search settings. ``distance`` picks the scales of the last layer, ``hidden_distance`` those
    of the other layers; ``n_steps`` candidates per channel; ``z_bits`` bounds m and h;
    ``equalize`` puts every hidden channel on one activation range first
    (:func:`equalize_channels`; False: the paper's one range for a layer's channels as they are)."""

    n_steps: int = 1000
    z_bits: int = 8
    n_samples: int = 20000
    seed: int = 0
    distance: str = "hamming"
    hidden_distance: str = "rms"
    act_quantile: float = 0.9999
    chunk: int = 128
    equalize: bool = True

    def __post_init__(self):
        get_distance(self.distance)
        get_distance(self.hidden_distance)
        if self.n_steps < 1000:
            raise ConfigError(
                f"n_steps must be >= 1000 (step <= max|W| / 1000), got {self.n_steps}"
            )
        if not 1 <= self.z_bits <= MAX_Z_BITS:
            raise ConfigError(f"z_bits must be in 1..{MAX_Z_BITS}, got {self.z_bits}")
        if self.n_samples < 1 or self.chunk < 1:
            raise ConfigError("n_samples and chunk must be positive")
        if not 0.0 < self.act_quantile <= 1.0:  # also refuses NaN
            raise ConfigError(f"act_quantile must be in (0, 1], got {self.act_quantile}")


# --- float reference --------------------------------------------------------------------------


def float_layer(x_f64, weights, bias) -> np.ndarray:
    """Float conv (C_in, H, W) -> (C_out, H, W), stride 1, replicate padding, float64."""
    w = np.asarray(weights, dtype=np.float64)
    k_size = w.shape[2]
    r = k_size // 2
    height, width = x_f64.shape[1:]
    xp = np.pad(x_f64, ((0, 0), (r, r), (r, r)), mode="edge")
    out = np.empty((w.shape[0], height, width))
    out[:] = np.asarray(bias, dtype=np.float64)[:, None, None]
    for ky in range(k_size):
        for kx in range(k_size):
            window = xp[:, ky : ky + height, kx : kx + width].reshape(x_f64.shape[0], -1)
            out += (w[:, :, ky, kx] @ window).reshape(out.shape)
    return out


def float_input(model: FloatModel, img) -> np.ndarray:
    """The float model's input (1, H, W): (pixel - input_offset) * input_scale."""
    return ((np.asarray(img, dtype=np.float64) - model.input_offset) * model.input_scale)[None]


def float_forward(model: FloatModel, img) -> np.ndarray:
    """Float model output (H, W, C_out) of the last layer (no ReLU after it)."""
    x = float_input(model, img)
    for layer, (w, b) in enumerate(zip(model.weights, model.biases)):
        x = float_layer(x, w, b)
        if layer < len(model.weights) - 1:
            x = np.maximum(x, 0.0)
    return x.transpose(1, 2, 0)


# --- the searches -------------------------------------------------------------------------------


def scale_grid(w_max: float, n_steps: int) -> np.ndarray:
    """Candidate weight scales ``tau / S_k``, S_k = k * w_max / n_steps for k = n_steps .. 1."""
    k = np.arange(n_steps, 0, -1, dtype=np.float64)
    return TAU / (k * (w_max / n_steps))


def search_channel_scale(
    w_flat, bias, patches, float_out, act_scale, x_max, distance="rms", n_steps=1000, chunk=128
):
    """Exhaustive scale search of one output channel (Algorithm 1, inner loop).

    w_flat: float (D,) the channel's weights in [ci, ky, kx] order; bias: float; patches: int
    (n, D) the quantised input X_dot around n sampled pixels; float_out: float (n,) the channel's
    float output Gamma_i(X) at those pixels; act_scale: a_l; x_max: max |X_dot|.
    Returns ``(scale, w_int int8 (D,), b_int int, dist, all_dists (n_steps,))``, candidates in
    :func:`scale_grid` order.
    """
    dist_fn = get_distance(distance)
    w_flat = np.asarray(w_flat, dtype=np.float64)
    float_out = np.ascontiguousarray(float_out, dtype=np.float64)
    w_max = float(np.abs(w_flat).max())
    if w_max == 0.0:
        w_max = 1.0  # all-zero channel: any scale gives zero weights; keep the grid finite
    scales = scale_grid(w_max, n_steps)
    w_q = np.clip(np.rint(w_flat[None, :] * scales[:, None]), -128, 127)  # (N, D)
    bias_limit = INT32_MAX - np.abs(w_q).sum(axis=1) * x_max
    b_q = np.clip(np.rint(float(bias) * scales * act_scale), -bias_limit, bias_limit)
    exact_f32 = patches.shape[1] * max(x_max, 1) * 128 < _F32_EXACT
    mat_dtype = np.float32 if exact_f32 else np.float64
    p_mat = np.ascontiguousarray(patches, dtype=mat_dtype)
    acc_scales = scales * act_scale
    primary = np.empty(n_steps)
    secondary = np.empty(n_steps)
    fused = distance in _SAMPLE_WISE
    for start in range(0, n_steps, chunk):
        sl = slice(start, min(start + chunk, n_steps))
        # (candidates, n) integer dot products, exact in mat_dtype; bias added below in float64
        dots = w_q[sl].astype(mat_dtype) @ p_mat.T
        if fused:
            out = np.empty((3, dots.shape[0]))
            _sample_wise_kernel(dots, b_q[sl], float_out, acc_scales[sl], out)
            primary[sl] = out[_SAMPLE_WISE[distance]]
            secondary[sl] = out[_SAMPLE_WISE["l1"]]
        else:
            acc = dots.T.astype(np.float64) + b_q[sl]
            target = float_out[:, None] * acc_scales[sl][None, :]
            primary[sl] = dist_fn(target, acc)
            secondary[sl] = l1(target, acc)
    order = np.lexsort((np.arange(n_steps), secondary, primary))
    best = int(order[0])
    return (
        float(scales[best]),
        w_q[best].astype(np.int8),
        int(b_q[best]),
        float(primary[best]),
        primary,
    )


# Row of the fused kernel's output holding each sample-wise distance.
_SAMPLE_WISE = {"hamming": 0, "l1": 1, "rms": 2}


@njit(cache=True)
def _sample_wise_kernel(dots, bias, float_out, acc_scales, out):
    """One pass per candidate j over the samples i, with q = dots[j, i] + bias[j] and
    t = float_out[i] * acc_scales[j]: out[0, j] = hamming, out[1, j] = l1, out[2, j] = rms
    (the definitions of :mod:`quant.distances`, summed sequentially)."""
    n_cand, n = dots.shape
    for j in range(n_cand):
        ham = 0
        abs_sum = 0.0
        sq_sum = 0.0
        b = bias[j]
        sa = acc_scales[j]
        for i in range(n):
            q = np.float64(dots[j, i]) + b
            t = float_out[i] * sa
            d = t - q
            abs_sum += abs(d)
            sq_sum += d * d
            if (t > 0) != (q > 0):
                ham += 1
        out[0, j] = ham
        out[1, j] = abs_sum / n
        out[2, j] = np.sqrt(sq_sum / n)


@njit(cache=True)
def _mul_shift_kernel(acc, target, m_max, h_max):
    """Exhaustive (m, h) search: sum |target - clamp(mul_shift(acc, m, h), 0, 127)|, early exit."""
    best = np.inf
    best_m = 0
    best_h = 0
    h_top = min(h_max, 63)  # every h >= 63 gives the same outputs as 63
    n = acc.shape[0]
    for h in range(h_top + 1):
        for m in range(m_max + 1):
            err = 0.0
            for i in range(n):
                v = mul_shift(acc[i], m, h)
                if v < 0:
                    v = 0
                elif v > 127:
                    v = 127
                err += abs(target[i] - v)
                if err >= best:
                    break
            if err < best:
                best = err
                best_m = m
                best_h = h
    return best_m, best_h, best


def search_mul_shift(acc, target, z_bits=8) -> tuple[int, int, float]:
    """Best (m, h) in [0, 2**z_bits - 1]**2 for ``clamp((acc * m) >> h, 0, 127) ~ target``.

    acc: int (n,) accumulators; target: float (n,) the wanted activations (clamped to 0..127
    before comparing). Returns ``(m, h, mean absolute error)``; ties go to the smaller h, then m.
    """
    acc_i64 = np.ascontiguousarray(acc, dtype=np.int64)
    tgt = np.clip(np.ascontiguousarray(target, dtype=np.float64), 0.0, float(ACT_MAX))
    if acc_i64.shape != tgt.shape or acc_i64.ndim != 1 or acc_i64.size == 0:
        raise ValueError("acc and target must be non-empty 1-D arrays of the same length")
    top = 2**z_bits - 1
    m, h, err = _mul_shift_kernel(acc_i64, tgt, top, top)
    return int(m), int(h), float(err) / acc_i64.size


# --- sampling -----------------------------------------------------------------------------------


def _sample_positions(shapes, n_samples, seed):
    """Per image (ys, xs): n_samples pixels drawn without replacement over all images (all pixels
    if there are fewer), reproducible from ``seed``."""
    sizes = np.array([h * w for h, w in shapes], dtype=np.int64)
    total = int(sizes.sum())
    if total <= n_samples:
        flat = np.arange(total)
    else:
        flat = np.sort(np.random.default_rng(seed).choice(total, size=n_samples, replace=False))
    starts = np.concatenate([[0], np.cumsum(sizes)])
    out = []
    for i, (_h, w) in enumerate(shapes):
        local = flat[(flat >= starts[i]) & (flat < starts[i + 1])] - starts[i]
        out.append((local // w, local % w))
    return out


def _patches(x, ys, xs, k_size) -> np.ndarray:
    """(n, C*K*K) windows of x (C, H, W) around (ys, xs), replicate border, [c, ky, kx] order."""
    r = k_size // 2
    xp = np.pad(x, ((0, 0), (r, r), (r, r)), mode="edge")
    taps = np.arange(k_size)
    rows = ys[:, None, None] + taps[None, :, None]
    cols = xs[:, None, None] + taps[None, None, :]
    win = xp[:, rows, cols]  # (C, n, K, K)
    return win.transpose(1, 0, 2, 3).reshape(len(ys), x.shape[0] * k_size * k_size)


def _as_images(calib_images):
    images = list(calib_images)
    if not images:
        raise ConfigError("quantize needs at least one calibration image")
    for i, img in enumerate(images):
        if not isinstance(img, np.ndarray) or img.dtype != np.uint8 or img.ndim != 2:
            raise ConfigError(f"calibration image {i} must be a uint8 (H, W) array")
    return images


# --- per-channel activation ranges (a float transform before the searches) ---------------------


def equalize_channels(model: FloatModel, calib_images, config: QuantizerConfig | None = None):
    """The same float function with every hidden channel's activations on one range.

    The chip's multiply-shift is per output channel, but the next layer's weights are read with
    one activation scale ``a_{l+1}`` for all of their input channels, so a hidden channel whose
    ReLU outputs span a tenth of the layer's range uses a tenth of the int8 levels. ReLU is
    positively homogeneous: multiplying channel i of layer l (weights and bias) by
    ``alpha_i > 0`` and dividing column i of layer l + 1's weights by ``alpha_i`` leaves the
    float network's output unchanged. With ``q_i`` the ``act_quantile`` quantile of channel i's
    ReLU outputs at the sampled pixels and ``q`` the largest of them, ``alpha_i = q / q_i`` (1
    for a channel that is never positive there) puts every channel's quantile at ``q``, so the
    layer's one range (127 over the quantile of all its channels' outputs) fits each of them
    alike. Layer l + 1's pre-activations do not change,
    so every layer's ``alpha`` comes from the given model's own float maps. A one-layer model is
    returned as it is.
    """
    config = config or QuantizerConfig()
    images = _as_images(calib_images)
    n_layers = len(model.weights)
    if n_layers == 1:
        return model
    weights = [np.asarray(w, dtype=np.float64).copy() for w in model.weights]
    biases = [np.asarray(b, dtype=np.float64).copy() for b in model.biases]
    positions = _sample_positions([im.shape for im in images], config.n_samples, config.seed)
    x_float = [float_input(model, im) for im in images]
    for layer in range(n_layers - 1):
        w_orig, b_orig = model.weights[layer], model.biases[layer]
        f_maps = [np.maximum(float_layer(xf, w_orig, b_orig), 0.0) for xf in x_float]
        samples = np.concatenate([f[:, ys, xs] for f, (ys, xs) in zip(f_maps, positions)], axis=1)
        q_i = np.quantile(samples, config.act_quantile, axis=1)
        alpha = np.ones_like(q_i)
        live = q_i > 0
        if live.any():
            alpha[live] = q_i[live].max() / q_i[live]
        weights[layer] *= alpha[:, None, None, None]
        biases[layer] *= alpha
        weights[layer + 1] /= alpha[None, :, None, None]
        x_float = f_maps
    return FloatModel(weights=tuple(weights), biases=tuple(biases),
                      input_offset=model.input_offset, input_scale=model.input_scale)


# --- the whole model (Algorithm 3) ---------------------------------------------------------------


def quantize(model: FloatModel, calib_images, config: QuantizerConfig | None = None,
             **options) -> QuantizedModel:
    """Quantise ``model`` layer by layer on uint8 calibration images (module docstring): the
    artifact of :func:`quantize_twin`, which takes the same arguments."""
    return quantize_twin(model, calib_images, config, **options)[1]


def quantize_twin(
    model: FloatModel,
    calib_images,
    config: QuantizerConfig | None = None,
    *,
    variant: str = "",
    calibration: str = "",
    progress: bool = True,
) -> tuple[FloatModel, QuantizedModel]:
    """The float model whose weight scales the artifact holds -- the equalised one
    (:func:`equalize_channels`) when ``config.equalize``, else ``model``; what works on the
    scales together with float weights (quantisation-aware training) needs it -- and the
    artifact.

    ``variant`` and ``calibration`` are recorded in the artifact; ``progress``: a bar on stderr
    (when it is a terminal) counting the channel searches, the scale search of every output
    channel and the (m, h) search of every hidden channel."""
    config = config or QuantizerConfig()
    images = _as_images(calib_images)
    if config.equalize:
        model = equalize_channels(model, images, config)
    n_layers = len(model.weights)
    positions = _sample_positions([im.shape for im in images], config.n_samples, config.seed)
    x_float = [float_input(model, im) for im in images]
    x_int = [(im.astype(np.int32) - np.int32(model.input_offset))[None] for im in images]
    act_scale = 1.0 / model.input_scale
    x_max = max(model.input_offset, 255 - model.input_offset)
    act_scales, weight_scales, distances = [], [], []
    q_weights, q_biases, q_mult, q_shift = [], [], [], []
    searches = sum(np.shape(w)[0] for w in model.weights) * 2 - np.shape(model.weights[-1])[0]
    bar = progress_bar(searches, "quantize", "channel", quiet=not progress)
    for layer in range(n_layers):
        bar.set_postfix(layer=layer, refresh=False)
        w = np.asarray(model.weights[layer], dtype=np.float64)
        b = np.asarray(model.biases[layer], dtype=np.float64)
        c_out, k_size = w.shape[0], w.shape[2]
        last = layer == n_layers - 1
        dist_name = config.distance if last else config.hidden_distance
        p_int = np.concatenate(
            [_patches(xi, ys, xs, k_size) for xi, (ys, xs) in zip(x_int, positions)]
        )
        p_float = np.concatenate(
            [_patches(xf, ys, xs, k_size) for xf, (ys, xs) in zip(x_float, positions)]
        )
        w_flat = w.reshape(c_out, -1)
        f_out = p_float @ w_flat.T + b  # (n, C_out): Gamma_l(X) at the samples
        scales = np.empty(c_out)
        w_int = np.empty(w.shape, dtype=np.int8)
        b_int = np.empty(c_out, dtype=np.int32)
        for c in range(c_out):
            scale, wq, bq, _, _ = search_channel_scale(
                w_flat[c], b[c], p_int, f_out[:, c], act_scale, x_max,
                dist_name, config.n_steps, config.chunk,
            )  # fmt: skip
            scales[c] = scale
            w_int[c] = wq.reshape(w.shape[1:])
            b_int[c] = bq
            bar.update(1)
        acc_maps = [int_layer(xi, w_int, b_int) for xi in x_int]
        f_maps = [float_layer(xf, w, b) for xf in x_float]
        act_scales.append(act_scale)
        weight_scales.append(scales)
        distances.append(dist_name)
        q_weights.append(w_int)
        q_biases.append(b_int)
        if last:
            break
        acc_s = np.concatenate([a[:, ys, xs].T for a, (ys, xs) in zip(acc_maps, positions)])
        q = float(np.quantile(np.maximum(f_out, 0.0), config.act_quantile))
        next_scale = ACT_MAX / q if q > 0 else 1.0
        mult = np.empty(c_out, dtype=np.int32)
        shift = np.empty(c_out, dtype=np.int32)
        for c in range(c_out):
            target = acc_s[:, c] * (next_scale / (scales[c] * act_scale))
            mult[c], shift[c], _ = search_mul_shift(acc_s[:, c], target, config.z_bits)
            bar.update(1)
        q_mult.append(mult)
        q_shift.append(shift)
        x_int = [requantize(a, mult, shift) for a in acc_maps]
        x_float = [np.maximum(f, 0.0) for f in f_maps]
        act_scale = next_scale
        x_max = ACT_MAX
    bar.close()
    acc_all = np.concatenate([a.reshape(a.shape[0], -1) for a in acc_maps], axis=1)
    f_all = np.concatenate([f.reshape(f.shape[0], -1) for f in f_maps], axis=1)
    agree = float(np.mean((acc_all > 0) == (f_all > 0)))
    acc_scale = (weight_scales[-1] * act_scales[-1])[:, None]
    acc_rms = float(np.sqrt(np.mean((acc_all - f_all * acc_scale) ** 2)))
    qm = QuantizedModel(
        weights=tuple(q_weights),
        biases=tuple(q_biases),
        mult=tuple(q_mult),
        shift=tuple(q_shift),
        input_offset=int(model.input_offset),
        input_scale=float(model.input_scale),
        z_bits=config.z_bits,
        weight_scales=tuple(weight_scales),
        act_scales=np.array(act_scales, dtype=np.float64),
        distances=tuple(distances),
        sign_agreement=agree,
        acc_rms=acc_rms,
        variant=variant,
        calibration=calibration,
    )
    check_quantized(qm)
    return model, qm
