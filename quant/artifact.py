"""The int8 artifact of a quantised network: :class:`QuantizedModel`, its checks and its file.

``stereosim quantize`` (:mod:`quant.quantizer`) writes it; the NNA (:mod:`nna.conv.weights`) reads
the single-layer descriptor network from it. The file is an ``.npz`` archive in the format
``stereosim-quant-v1``: per layer ``weights_l`` (int8), ``bias_l`` (int32), ``weight_scales_l``
and, between layers, ``mult_l`` / ``shift_l``; plus the input offset and scale, ``z_bits``, the
activation scales, the distances used, the calibration figures and a free-text description. A
single-layer model also carries the NNA's own keys ``weights``, ``bias`` and ``input_offset``.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.npz import open_npz
from stereosim.core.outputs import atomic_write_bytes
from stereosim.quant.distances import DISTANCES
from stereosim.quant.intconv import INT32_MAX, check_network

FORMAT = "stereosim-quant-v1"


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class QuantizedModel:
    """The integer network and how it was obtained.

    weights[l] int8 (C_out, C_in, K, K); biases[l] int32; mult[l], shift[l] int32 (C_out,) for the
    non-last layers; weight_scales[l] float64 (C_out,) the chosen s_i; act_scales float64 (L,) the
    integer units per float unit at each layer's input (a_0 = 1 / input_scale); distances the
    name used per layer; sign_agreement the fraction of final sign bits equal to the float model's
    and acc_rms the RMS of ``acc - s_i * a_L * Gamma_L`` over the calibration pixels.
    """

    weights: tuple
    biases: tuple
    mult: tuple
    shift: tuple
    input_offset: int
    input_scale: float
    z_bits: int
    weight_scales: tuple
    act_scales: np.ndarray
    distances: tuple
    sign_agreement: float
    acc_rms: float
    variant: str = ""
    calibration: str = ""

    @property
    def n_layers(self) -> int:
        return len(self.weights)

    @property
    def acc_scales(self) -> tuple:
        """Integer units per float unit of each layer's accumulator: s_i * a_l."""
        return tuple(s * a for s, a in zip(self.weight_scales, self.act_scales))


def check_quantized(qm: QuantizedModel) -> None:
    """Validate a :class:`QuantizedModel`; :class:`ConfigError` with a one-line reason if bad."""
    check_network(qm.weights, qm.biases, qm.mult, qm.shift, qm.input_offset, qm.z_bits)
    n_layers = qm.n_layers
    if len(qm.weight_scales) != n_layers or len(qm.distances) != n_layers:
        raise ConfigError(f"need weight scales and a distance name for each of {n_layers} layers")
    for layer, (s, w) in enumerate(zip(qm.weight_scales, qm.weights)):
        s = np.asarray(s)
        if s.shape != (w.shape[0],) or not np.all(np.isfinite(s)) or not np.all(s > 0):
            raise ConfigError(
                f"weight_scales[{layer}] must be {w.shape[0]} positive finite numbers, "
                f"got shape {s.shape}"
            )
    act = np.asarray(qm.act_scales)
    if act.shape != (n_layers,) or not np.all(np.isfinite(act)) or not np.all(act > 0):
        raise ConfigError(f"act_scales must be {n_layers} positive finite numbers")
    for name in qm.distances:
        if name not in DISTANCES:
            raise ConfigError(f"unknown distance {name!r}; choose one of {', '.join(DISTANCES)}")
    if not (np.isfinite(qm.input_scale) and qm.input_scale > 0):
        raise ConfigError(f"input_scale must be positive and finite, got {qm.input_scale}")
    if not 0.0 <= qm.sign_agreement <= 1.0:
        raise ConfigError(f"sign_agreement must be in 0..1, got {qm.sign_agreement}")
    if not (np.isfinite(qm.acc_rms) and qm.acc_rms >= 0):
        raise ConfigError(f"acc_rms must be a non-negative number, got {qm.acc_rms}")


def to_nna_weights(qm: QuantizedModel) -> tuple[np.ndarray, np.ndarray, int]:
    """The single-layer model as the NNA's ``(weights int8 (C, K, K), bias int32 (C,), offset)``."""
    if qm.n_layers != 1 or qm.weights[0].shape[1] != 1:
        raise ConfigError(
            f"the NNA descriptor runs one layer on one input channel; this model has "
            f"{qm.n_layers} layers"
        )
    return np.ascontiguousarray(qm.weights[0][:, 0]), qm.biases[0].copy(), int(qm.input_offset)


def save_quantized(path, qm: QuantizedModel) -> None:
    """Validate ``qm`` and write it as .npz (exact name, atomically: a reader sees the old file
    or the whole new one). A single-layer model also gets the keys
    ``weights``, ``bias``, ``input_offset`` so :func:`nna.conv.weights.load_weights` reads the
    file."""
    check_quantized(qm)
    arrays = {
        "format": np.array(FORMAT),
        "n_layers": np.int32(qm.n_layers),
        "input_offset": np.int32(qm.input_offset),
        "input_scale": np.float64(qm.input_scale),
        "z_bits": np.int32(qm.z_bits),
        "act_scales": np.asarray(qm.act_scales, dtype=np.float64),
        "distances": np.array(qm.distances, dtype=str),
        "sign_agreement": np.float64(qm.sign_agreement),
        "acc_rms": np.float64(qm.acc_rms),
        "variant": np.array(qm.variant),
        "calibration": np.array(qm.calibration),
    }
    for layer in range(qm.n_layers):
        arrays[f"weights_{layer}"] = qm.weights[layer]
        arrays[f"bias_{layer}"] = qm.biases[layer]
        arrays[f"weight_scales_{layer}"] = np.asarray(qm.weight_scales[layer], dtype=np.float64)
        if layer < qm.n_layers - 1:
            arrays[f"mult_{layer}"] = qm.mult[layer]
            arrays[f"shift_{layer}"] = qm.shift[layer]
    if qm.n_layers == 1 and qm.weights[0].shape[1] == 1:
        weights, bias, _ = to_nna_weights(qm)
        arrays["weights"] = weights
        arrays["bias"] = bias
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def _get(archive, key, name):
    return archive.field(key)


def _floats(value, key, name):
    if value.dtype.kind not in "iuf":
        raise ConfigError(f"quantized model {name!r}: {key} must be numbers, got {value.dtype}")
    return value.astype(np.float64)


def _scalar(value, key, name, kind):
    if value.shape != () or value.dtype.kind not in kind:
        raise ConfigError(
            f"quantized model {name!r}: {key} must be a scalar, got {value.dtype} {value.shape}"
        )
    return value[()]


def _int8(value, key, name):
    if value.dtype.kind not in "iu":
        raise ConfigError(f"quantized model {name!r}: {key} must be integers, got {value.dtype}")
    if value.size and (value.min() < -128 or value.max() > 127):
        raise ConfigError(
            f"quantized model {name!r}: {key} values outside int8 (-128..127), got "
            f"{int(value.min())}..{int(value.max())}"
        )
    return value.astype(np.int8)


def _int32(value, key, name):
    if value.dtype.kind not in "iu":
        raise ConfigError(f"quantized model {name!r}: {key} must be integers, got {value.dtype}")
    if value.size and (value.min() < -(2**31) or value.max() > INT32_MAX):
        raise ConfigError(f"quantized model {name!r}: {key} values outside int32")
    return value.astype(np.int32)


def load_quantized(path) -> QuantizedModel:
    """Read and validate a file written by :func:`save_quantized`; problems (including those
    :func:`core.npz.open_npz` checks before anything is unpacked) raise ConfigError."""
    name = os.fspath(path)
    archive = open_npz(name, "quantized model", "write it with quant.save_quantized")
    with archive:
        fmt = str(_scalar(_get(archive, "format", name), "format", name, "U"))
        if fmt != FORMAT:
            raise ConfigError(f"quantized model {name!r} has format {fmt!r}, expected {FORMAT!r}")
        n_layers = int(_scalar(_get(archive, "n_layers", name), "n_layers", name, "iu"))
        if not 1 <= n_layers <= 4:
            raise ConfigError(f"quantized model {name!r}: n_layers must be 1..4, got {n_layers}")
        weights, biases, mult, shift, scales = [], [], [], [], []
        for layer in range(n_layers):
            weights.append(_int8(_get(archive, f"weights_{layer}", name), f"weights_{layer}", name))
            biases.append(_int32(_get(archive, f"bias_{layer}", name), f"bias_{layer}", name))
            s = _get(archive, f"weight_scales_{layer}", name)
            if s.dtype.kind != "f":
                raise ConfigError(f"quantized model {name!r}: weight_scales_{layer} must be float")
            scales.append(s.astype(np.float64))
            if layer < n_layers - 1:
                for key, dest in ((f"mult_{layer}", mult), (f"shift_{layer}", shift)):
                    dest.append(_int32(_get(archive, key, name), key, name))
        distances = _get(archive, "distances", name)
        if distances.dtype.kind != "U" or distances.ndim != 1:
            raise ConfigError(f"quantized model {name!r}: distances must be a list of names")
        fields = dict(
            input_offset=int(
                _scalar(_get(archive, "input_offset", name), "input_offset", name, "iu")
            ),
            input_scale=float(
                _scalar(_get(archive, "input_scale", name), "input_scale", name, "f")
            ),
            z_bits=int(_scalar(_get(archive, "z_bits", name), "z_bits", name, "iu")),
            act_scales=_floats(_get(archive, "act_scales", name), "act_scales", name),
            sign_agreement=float(
                _scalar(_get(archive, "sign_agreement", name), "sign_agreement", name, "f")
            ),
            acc_rms=float(_scalar(_get(archive, "acc_rms", name), "acc_rms", name, "f")),
            variant=str(_scalar(_get(archive, "variant", name), "variant", name, "U")),
            calibration=str(_scalar(_get(archive, "calibration", name), "calibration", name, "U")),
        )
        nna_keys = [k for k in ("weights", "bias") if k in archive.files]
        nna_arrays = {k: archive[k] for k in nna_keys}
    try:
        qm = QuantizedModel(
            weights=tuple(weights),
            biases=tuple(biases),
            mult=tuple(mult),
            shift=tuple(shift),
            weight_scales=tuple(scales),
            distances=tuple(str(d) for d in distances),
            **fields,
        )
        check_quantized(qm)
    except ConfigError as err:
        raise ConfigError(f"quantized model {name!r}: {err}") from None
    if nna_arrays:
        if qm.n_layers != 1 or qm.weights[0].shape[1] != 1:
            raise ConfigError(f"quantized model {name!r}: NNA keys in a multi-layer model")
        weights_nna, bias_nna, _ = to_nna_weights(qm)
        if not (
            np.array_equal(nna_arrays.get("weights"), weights_nna)
            and np.array_equal(nna_arrays.get("bias"), bias_nna)
        ):
            raise ConfigError(
                f"quantized model {name!r}: the NNA keys weights/bias disagree with "
                "weights_0/bias_0"
            )
    return qm
