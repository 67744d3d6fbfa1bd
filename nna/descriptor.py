"""The descriptor the configuration selects (``nna.descriptor``): census or the int8 CNN."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from stereosim.nna.census import census, census_bits
from stereosim.nna.conv import cnn_descriptor
from stereosim.nna.weights import default_weights, load_layer
from stereosim.sim.config import NnaConfig, check_section
from stereosim.sim.errors import ConfigError


@lru_cache(maxsize=8)
def _layer(weights: str):
    return default_weights() if weights == "default" else load_layer(weights)


def layer(cfg: NnaConfig) -> tuple[np.ndarray, np.ndarray, int]:
    """(int8 weights, int32 bias, input offset) of the CNN descriptor the config names.

    The layer must have ``nna.cnn.channels`` output channels -- the SVA's register widths were
    worked out for that many bits -- else :class:`ConfigError` says which value to set."""
    weights, bias, offset = _layer(cfg.cnn.weights)
    if weights.shape[0] != cfg.cnn.channels:
        raise ConfigError(
            f"the CNN layer {cfg.cnn.weights!r} has {weights.shape[0]} output channels but "
            f"nna.cnn.channels is {cfg.cnn.channels}: set nna.cnn.channels = "
            f"{weights.shape[0]} (the SVA's automatic register widths follow it)"
        )
    return weights, bias, offset


def descriptor_bits(cfg: NnaConfig) -> int:
    """Width in bits of the configured descriptor (the largest Hamming cost)."""
    if cfg.descriptor == "census":
        c = cfg.census
        return census_bits(c.window, c.kind, c.stride)
    return int(layer(cfg)[0].shape[0])  # = nna.cnn.channels (layer() checks it)


def compute_descriptor(img: np.ndarray, cfg: NnaConfig) -> np.ndarray:
    """Descriptor image (H, W) uint32/uint64 of a grey uint8 image."""
    cfg = check_section(cfg, "nna.")  # checked once: a checked configuration's is trusted
    if cfg.descriptor == "census":
        c = cfg.census
        return census(img, c.window, c.kind, c.stride)
    weights, bias, offset = layer(cfg)
    return cnn_descriptor(img, weights, bias, offset)
