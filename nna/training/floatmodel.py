"""The file of a trained float model (``stereosim-float-v1``, ``.npz``): written by ``stereosim
train``, read by ``stereosim quantize`` and the ablation."""

from __future__ import annotations

import io
import json
import os

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.npz import open_npz
from stereosim.core.outputs import atomic_write_bytes
from stereosim.nna.training.trainconfig import VARIANTS
from stereosim.quant.quantizer import FloatModel

FORMAT = "stereosim-float-v1"


def save_float_model(path, result: dict) -> None:
    """Write a trained float model as .npz, atomically (format ``stereosim-float-v1``)."""
    cfg = result["config"]
    arrays = {
        "format": np.array(FORMAT),
        "variant": np.array(cfg["variant"]),
        "n_layers": np.int32(len(result["weights"])),
        "input_offset": np.int32(cfg["input_offset"]),
        "input_scale": np.float64(cfg["input_scale"]),
        "training": np.array(
            json.dumps(
                {k: result[k] for k in ("config", "scenes", "loss_per_epoch", "samples")},
                sort_keys=True,
            )
        ),
    }
    for i, (w, b) in enumerate(zip(result["weights"], result["biases"])):
        arrays[f"weights_{i}"] = w
        arrays[f"bias_{i}"] = b
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_float_model(path):
    """Read a file written by :func:`save_float_model`: ``(FloatModel, variant, training dict)``.

    Problems (missing, unreadable or unbounded file -- :func:`core.npz.open_npz` --, a missing
    field, a field of the wrong kind, wrong shapes for the variant) raise :class:`ConfigError`.
    """

    name = os.fspath(path)
    with open_npz(name, "float model", "write it with 'stereosim train'") as archive:
        fmt = archive.scalar("format", "U")
        if fmt != FORMAT:
            raise ConfigError(f"float model {name!r} has format {fmt!r}, expected {FORMAT!r}")
        variant = archive.scalar("variant", "U")
        if variant not in VARIANTS:
            raise ConfigError(f"float model {name!r}: unknown variant {variant!r}")
        weights, biases = [], []
        for i, (c_in, c_out, k) in enumerate(VARIANTS[variant]):
            w, b = archive.field(f"weights_{i}"), archive.field(f"bias_{i}")
            floats = w.dtype.kind == "f" and b.dtype.kind == "f"
            if not floats or w.shape != (c_out, c_in, k, k) or b.shape != (c_out,):
                raise ConfigError(
                    f"float model {name!r}: layer {i} of {variant} must be float "
                    f"({c_out}, {c_in}, {k}, {k}) + ({c_out},), got {w.dtype} {w.shape} + "
                    f"{b.dtype} {b.shape}"
                )
            weights.append(w.astype(np.float64))
            biases.append(b.astype(np.float64))
        text = archive.scalar("training", "U")
        offset, scale = archive.scalar("input_offset", "iu"), archive.scalar("input_scale", "f")
    try:
        training = json.loads(text)
    except (ValueError, RecursionError) as err:  # JSONDecodeError, or a number too long
        why = " ".join(str(err).split())[:80]
        raise ConfigError(f"float model {name!r}: its training record is not JSON ({why})"
                          ) from None
    try:
        model = FloatModel(
            weights=tuple(weights), biases=tuple(biases), input_offset=offset, input_scale=scale
        )
    except ConfigError as err:
        raise ConfigError(f"float model {name!r}: {err}") from None
    return model, variant, training
