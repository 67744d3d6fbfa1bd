"""Weights of the NNA descriptor network: the shipped trained layer, a placeholder, .npz files.

A weight file is an ``.npz`` archive with three arrays:

* ``weights``: int8 (C, K, K), [channel, ky, kx], 1 <= C <= 64, K odd;
* ``bias``: int32 (C,);
* ``input_offset``: an integer scalar in 0..255.

A quantized artifact written by ``stereosim quantize`` (:func:`quant.artifact.save_quantized`) of a
single-layer model carries these three keys too, plus everything else about the model; such a
file is read and checked in full by :func:`load_layer`. :func:`load_network` reads either kind
as the network the NNA runs: a weight file as one layer, an artifact with all its layers.

:func:`default_weights` is the shipped layer, ``nna/conv/single9x9.npz``: the ``single9x9`` network
trained with ``stereosim train`` and quantised with ``stereosim quantize`` (docs/ablation.md).
:func:`placeholder_weights` is a deterministic random layer, for tests that need a layer
independent of training.
"""

from __future__ import annotations

import os

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.npz import open_npz
from stereosim.nna.conv.conv import MAX_KERNEL_SIZE, check_layer
from stereosim.quant.artifact import QuantizedModel, load_quantized, to_nna_weights
from stereosim.quant.intconv import IntNetwork, network

DEFAULT_SEED = 20261122
DEFAULT_SHAPE = (32, 9, 9)
DEFAULT_SIGMA = 24.0
DEFAULT_INPUT_OFFSET = 128
KEYS = ("weights", "bias", "input_offset")


SHIPPED_WEIGHTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "single9x9.npz")


def default_weights() -> tuple[np.ndarray, np.ndarray, int]:
    """The shipped trained layer (``nna/conv/single9x9.npz``): ``(weights int8 (32, 9, 9), bias
    int32 (32,), input_offset)``."""
    return load_layer(SHIPPED_WEIGHTS)


def _artifact(name: str, fix: str) -> QuantizedModel | None:
    """The quantized artifact at ``name`` (read and checked in full), or None where the file is
    a plain weight file (an artifact has a ``format`` member); a file that is no readable .npz
    raises :class:`ConfigError` naming it, with ``fix``."""
    with open_npz(name, "weight file", fix) as archive:
        if "format" not in archive.files:
            return None
    return load_quantized(name)


def load_layer(path) -> tuple[np.ndarray, np.ndarray, int]:
    """The NNA layer of a weight file or of a single-layer quantized artifact (checked in full:
    a damaged or inconsistent artifact raises :class:`ConfigError`)."""
    name = os.fspath(path)
    qm = _artifact(name, f"write it with nna.save_weights (keys {', '.join(KEYS)})")
    if qm is None:
        return load_weights(name)
    try:
        return check_layer(*to_nna_weights(qm))
    except ConfigError as err:
        raise ConfigError(f"weight file {name!r}: {err}") from None


def load_network(path) -> IntNetwork:
    """The network a weight file or a quantized artifact of 1..4 layers holds (checked in full;
    a damaged or inconsistent file raises :class:`ConfigError` naming it). Every layer's kernel
    fits the NNA as a one-layer file's must (:func:`nna.conv.conv.check_layer`): odd and at most
    :data:`~nna.conv.conv.MAX_KERNEL_SIZE` wide."""
    name = os.fspath(path)
    qm = _artifact(name, f"write it with nna.save_weights (keys {', '.join(KEYS)}) or "
                         "stereosim quantize")
    if qm is None:
        weights, bias, offset = load_weights(name)
        return network((weights[:, None],), (bias,), (), (), offset)
    try:
        cnn = network(qm.weights, qm.biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    except ConfigError as err:
        raise ConfigError(f"weight file {name!r}: {err}") from None
    for layer, w in enumerate(cnn.weights):
        k_size = w.shape[2]
        if k_size > MAX_KERNEL_SIZE:  # the bound check_layer puts on a one-layer file
            raise ConfigError(
                f"weight file {name!r}: layer {layer}'s kernel size {k_size}x{k_size} is larger "
                f"than the {MAX_KERNEL_SIZE}x{MAX_KERNEL_SIZE} window the largest NNA line "
                "buffer can hold (nna.line_buffer_rows <= 64): use a smaller kernel"
            )
    return cnn


def placeholder_weights() -> tuple[np.ndarray, np.ndarray, int]:
    """Deterministic placeholder layer: ``(weights int8 (32, 9, 9), bias int32 (32,), 128)``.

    Weights are round(N(0, 24)) from ``np.random.default_rng(20261122)``, each kernel shifted to
    zero mean before rounding, clipped to -127..127, and the rounding residue taken off the
    centre tap so every kernel sums to exactly zero. Bias is zero and the input offset 128.
    """
    rng = np.random.default_rng(DEFAULT_SEED)
    n_channels, k_rows, k_cols = DEFAULT_SHAPE
    w_f64 = rng.normal(0.0, DEFAULT_SIGMA, size=DEFAULT_SHAPE)
    w_f64 -= w_f64.mean(axis=(1, 2), keepdims=True)
    w_i64 = np.clip(np.rint(w_f64), -127, 127).astype(np.int64)
    w_i64[:, k_rows // 2, k_cols // 2] -= w_i64.sum(axis=(1, 2))
    if np.abs(w_i64).max() > 127:  # cannot happen for this seed; guards a changed constant
        raise RuntimeError("default_weights: the zero-sum correction left the int8 range")
    weights = w_i64.astype(np.int8)
    bias = np.zeros(n_channels, dtype=np.int32)
    return weights, bias, DEFAULT_INPUT_OFFSET


def save_weights(path, weights, bias, input_offset) -> None:
    """Validate a layer and write it to ``path`` as .npz (under that exact name, no suffix)."""
    weights, bias, input_offset = check_layer(weights, bias, input_offset)
    with open(path, "wb") as f:
        np.savez(f, weights=weights, bias=bias, input_offset=np.int32(input_offset))


def load_weights(path) -> tuple[np.ndarray, np.ndarray, int]:
    """Read and validate a layer saved by :func:`save_weights`.

    Returns ``(weights int8 (C, K, K), bias int32 (C,), input_offset int)``. Every problem (missing
    or unreadable file, not an .npz, a member that fails :func:`core.npz.open_npz`'s bounds, missing
    key, wrong dtype, shape or range) raises :class:`ConfigError` with the file name and a
    one-line reason.
    """
    name = os.fspath(path)
    how = f"write it with nna.save_weights (keys {', '.join(KEYS)})"
    archive = open_npz(name, "weight file", how)
    with archive:
        missing = [k for k in KEYS if k not in archive.files]
        if missing:
            raise ConfigError(
                f"weight file {name!r} lacks {', '.join(missing)}; it has "
                f"{', '.join(archive.files) or 'no arrays'} (needs {', '.join(KEYS)})"
            )
        weights, bias, offset = (archive[k] for k in KEYS)
    if offset.shape != () or offset.dtype.kind not in "iu":
        raise ConfigError(
            f"weight file {name!r}: input_offset must be an integer scalar, "
            f"got {offset.dtype} with shape {offset.shape}"
        )
    try:
        return check_layer(weights, bias, int(offset))
    except ConfigError as err:
        raise ConfigError(f"weight file {name!r}: {err}") from None
