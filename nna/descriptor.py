"""The descriptor the configuration selects (``nna.descriptor``): census, the int8 CNN, or the
hybrid of the two.

The hybrid descriptor is one word per pixel of two parts: the CNN's ``C`` sign bits in bits
``0 .. C - 1`` and the census signature's ``B`` bits in bits ``C .. C + B - 1`` (at most 64 in
all). The NNA computes both: the census unit sits beside the MAC array and reads the same
input rows (:mod:`nna.geometry`: the census rows a network of several layers adds to its
submodule). The SVA matches the word part by part with the weighted sum of the two Hamming
distances (:mod:`sva.hamming.cost`). A census window taller than the network's receptive field would
make a descriptor wait for rows the network does not, so its half height is at most the
network's reach."""

from __future__ import annotations

import os
import threading
import time
from collections import OrderedDict

import numpy as np

from stereosim.core.config import NnaConfig, check_section
from stereosim.core.errors import ConfigError
from stereosim.nna.census_unit.census import census, census_bits
from stereosim.nna.conv.conv import network_descriptor
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS, load_network
from stereosim.quant.intconv import IntNetwork


def weights_file(weights: str) -> str:
    """The file ``nna.cnn.weights`` names: the shipped layer for "default"; else the path as
    given -- a config file's already made absolute from that file's folder
    (:func:`core.config.loader.read_layer`), one given on the command line relative to the
    working directory, as every other file option is (no second place is looked in: the
    configuration's back end is read from the same file,
    :func:`core.config.loader.tuned_backend`)."""
    return SHIPPED_WEIGHTS if weights == "default" else weights


# (absolute path, device, inode, size, mtime in ns) -> the network read from that file as it
# was; the few most recent, newest last
_NETWORKS: OrderedDict[tuple, IntNetwork] = OrderedDict()
_NETWORKS_KEPT = 8
_NETWORKS_LOCK = threading.Lock()
# A file modified this shortly before it was read is not kept: a rewrite within the file
# system's timestamp tick (a few ms on Linux, up to 2 s on FAT) could keep its size and mtime,
# so its identity alone would not tell the two contents apart (git's "racily clean" entries)
_SETTLED_NS = 2_000_000_000


def file_identity(path: str) -> tuple | None:
    """What identifies the content of the file at ``path`` now: its absolute path (a relative
    path resolved against the working directory of this call), device, inode, size and
    modification time in ns; None if it cannot be stat'ed."""
    full = os.path.abspath(path)
    try:
        st = os.stat(full)
    except (OSError, ValueError):
        return None
    return (full, st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def _network(weights: str) -> IntNetwork:
    """The network of ``nna.cnn.weights``, read once per file content (:func:`file_identity`):
    a file rewritten, replaced or deleted since, or a relative path from another working
    directory, is read (and checked) again; so is a file modified less than 2 s before it was
    read."""
    path = weights_file(weights)
    key = file_identity(path)
    with _NETWORKS_LOCK:
        net = _NETWORKS.get(key) if key is not None else None
        if net is not None:
            _NETWORKS.move_to_end(key)
            return net
    net = load_network(path)  # a missing or bad file raises its one line here
    settled = key is not None and time.time_ns() - key[-1] > _SETTLED_NS
    if settled and file_identity(path) == key:  # and unchanged while it was read
        with _NETWORKS_LOCK:
            _NETWORKS[key] = net
            while len(_NETWORKS) > _NETWORKS_KEPT:
                _NETWORKS.popitem(last=False)
    return net


def network(cfg: NnaConfig) -> IntNetwork:
    """The integer network of the CNN descriptor the config names (``nna.cnn.weights``: a
    weight file of one layer or a quantized artifact of 1..4 layers), as the file holds it now
    (a relative path from the working directory of this call; :func:`_network`).

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


def descriptor_parts(cfg: NnaConfig) -> tuple[tuple[str, int], ...]:
    """The parts of the configured descriptor, in bit order, as (kind, bits): one part for the
    census or the CNN, two for the hybrid (the CNN's, then the census's). A hybrid of more than
    64 bits, or whose census is taller than the network's receptive field, is a
    :class:`ConfigError` saying what to change."""
    c = cfg.census
    if cfg.descriptor == "census":
        return (("census", census_bits(c.window, c.kind, c.stride)),)
    net = network(cfg)  # nna.cnn.channels outputs (network() checks it)
    if cfg.descriptor == "cnn":
        return (("cnn", net.channels),)
    bits = census_bits(c.window, c.kind, c.stride)
    if net.channels + bits > 64:
        raise ConfigError(
            f"the hybrid descriptor would have {net.channels} CNN bits + {bits} census bits = "
            f"{net.channels + bits}, more than the 64 a descriptor word holds: use a smaller "
            "nna.census.window (or kind symmetric, or a stride)")
    if c.window[1] // 2 > net.reach:
        raise ConfigError(
            f"the census window {c.window[0]}x{c.window[1]} reaches {c.window[1] // 2} rows "
            f"above and below, beyond the network's {net.reach} (its receptive field): the "
            "hybrid descriptor would wait for rows the network does not read; use a census "
            f"window at most {2 * net.reach + 1} rows tall")
    return (("cnn", net.channels), ("census", bits))


def descriptor_bits(cfg: NnaConfig) -> int:
    """Width in bits of the configured descriptor: the sum of its parts' bits."""
    return sum(bits for _, bits in descriptor_parts(cfg))


def census_of(img: np.ndarray, cfg: NnaConfig) -> np.ndarray:
    """The census signatures (H, W) of a grey uint8 image with the configured window."""
    c = cfg.census
    return census(img, c.window, c.kind, c.stride)


def hybrid_word(cnn_bits: np.ndarray, census_bits_: np.ndarray, channels: int,
                total: int) -> np.ndarray:
    """The hybrid descriptor words of ``total`` bits: the CNN's ``channels`` bits below, the
    census's shifted above them; uint32 when ``total`` <= 32, else uint64 (as every
    descriptor's words)."""
    word = cnn_bits.astype(np.uint64) | (census_bits_.astype(np.uint64) << np.uint64(channels))
    return word.astype(np.uint32) if total <= 32 else word


def compute_descriptor(img: np.ndarray, cfg: NnaConfig) -> np.ndarray:
    """Descriptor image (H, W) uint32/uint64 of a grey uint8 image."""
    cfg = check_section(cfg, "nna.")  # checked once: a checked configuration's is trusted
    if cfg.descriptor == "census":
        return census_of(img, cfg)
    net = network(cfg)
    if cfg.descriptor == "cnn":
        return network_descriptor(img, net)
    total = descriptor_bits(cfg)  # a hybrid that does not fit is refused before it is computed
    return hybrid_word(network_descriptor(img, net), census_of(img, cfg), net.channels, total)
