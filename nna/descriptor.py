"""The descriptor the configuration selects (``nna.descriptor``): census or the int8 CNN."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from stereosim.nna.census import census, census_bits
from stereosim.nna.conv import network_descriptor
from stereosim.nna.weights import SHIPPED_WEIGHTS, load_network
from stereosim.quant.intconv import IntNetwork
from stereosim.sim.config import NnaConfig, check_section
from stereosim.sim.errors import ConfigError

# stereosim's folder (the repository, in the README's editable install): where a relative
# weight path that the working directory lacks is looked up next (the presets name
# benchmarks/models/... and run from anywhere)
PROJECT_ROOT = Path(__file__).resolve().parents[1]


def weights_file(weights: str) -> str:
    """The file ``nna.cnn.weights`` names: the shipped layer for "default"; a relative path from
    the working directory, else from :data:`PROJECT_ROOT` if it is there."""
    if weights == "default":
        return SHIPPED_WEIGHTS
    path = Path(weights)
    if not path.is_absolute() and not path.exists() and (PROJECT_ROOT / path).exists():
        return str(PROJECT_ROOT / path)
    return weights


@lru_cache(maxsize=8)
def _network(weights: str) -> IntNetwork:
    return load_network(weights_file(weights))


def network(cfg: NnaConfig) -> IntNetwork:
    """The integer network of the CNN descriptor the config names (``nna.cnn.weights``: a
    weight file of one layer or a quantized artifact of 1..4 layers).

    Its last layer must have ``nna.cnn.channels`` output channels -- the SVA's register widths
    were worked out for that many bits -- else :class:`ConfigError` says which value to set."""
    net = _network(cfg.cnn.weights)
    if net.channels != cfg.cnn.channels:
        raise ConfigError(
            f"the CNN {cfg.cnn.weights!r} has {net.channels} output channels but "
            f"nna.cnn.channels is {cfg.cnn.channels}: set nna.cnn.channels = "
            f"{net.channels} (the SVA's automatic register widths follow it)"
        )
    return net


def descriptor_bits(cfg: NnaConfig) -> int:
    """Width in bits of the configured descriptor (the largest Hamming cost)."""
    if cfg.descriptor == "census":
        c = cfg.census
        return census_bits(c.window, c.kind, c.stride)
    return network(cfg).channels  # = nna.cnn.channels (network() checks it)


def compute_descriptor(img: np.ndarray, cfg: NnaConfig) -> np.ndarray:
    """Descriptor image (H, W) uint32/uint64 of a grey uint8 image."""
    cfg = check_section(cfg, "nna.")  # checked once: a checked configuration's is trusted
    if cfg.descriptor == "census":
        c = cfg.census
        return census(img, c.window, c.kind, c.stride)
    return network_descriptor(img, network(cfg))
