"""The descriptor the configuration selects (``nna.descriptor``): census, the int8 CNN, or the
hybrid of the two.

The hybrid descriptor is one word per pixel of two parts: the CNN's ``C`` sign bits in bits
``0 .. C - 1`` and the census signature's ``B`` bits in bits ``C .. C + B - 1`` (at most 64 in
all). The NNA computes both: the census unit sits beside the MAC array and reads the same
input rows (:mod:`nna.geometry`: the census rows a network of several layers adds to its
submodule). The SVA matches the word part by part with the weighted sum of the two Hamming
distances (:mod:`sva.hamming.cost`). A census window taller than the network's receptive field would
make a descriptor wait for rows the network does not, so its half height is at most the
network's reach (:func:`resolve_nna` checks it, with the network it loads).

The NNA of a run is resolved here once (:func:`resolve_nna`, an :class:`NnaSpec`): the checked
``nna`` section, the integer network its ``nna.cnn.weights`` names (loaded once, its channel
count checked: :func:`load_cnn`) and the descriptor's parts (the hybrid's fit checked). This is
the one place that loads the CNN and runs the rules that need it. What depends on the
configuration alone is checked where the configuration enters (:mod:`core.config.check`); what
depends on the frame shape or builds the submodule (its line buffers, its MAC shares) is a rule
of the plan (:func:`nna.geometry.check_line_buffer`, :func:`nna.geometry.mac_shares`). The rules
of :mod:`nna.geometry` and :mod:`nna.submodule.timing` read the spec; the chip's spec
(:mod:`sim.cycle.spec`) carries it from where a run starts to the plan, the engines and the
reports."""

from __future__ import annotations

import os
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from stereosim.core.config import NnaConfig, check_section
from stereosim.core.errors import ConfigError
from stereosim.nna.census_unit.census import census, census_bits
from stereosim.nna.conv.conv import network_descriptor
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS, load_network
from stereosim.quant.intconv import IntNetwork


@dataclass(frozen=True, slots=True, eq=False)
class NnaSpec:
    """The NNA of a checked configuration, resolved (:func:`resolve_nna`; its type says the
    section passed the checks, so nothing below the entry checks it again).

    ``cfg``: the checked :class:`~core.config.schema.NnaConfig`; ``cnn``: the integer network
    of ``nna.cnn.weights`` (None for the census); ``parts``: the descriptor's parts in bit
    order, (kind, bits) -- one for the census or the CNN, the hybrid's CNN part then its census
    part; ``halves``: each stage's half kernel h_l (the CNN's layers; the census unit: one
    stage of half height h // 2); ``layer_macs``: each stage's MACs per output pixel,
    K_l^2 C_in,l C_out,l (the census unit: 0)."""

    cfg: NnaConfig
    cnn: IntNetwork | None
    parts: tuple[tuple[str, int], ...]
    halves: tuple[int, ...]
    layer_macs: tuple[int, ...]

    @property
    def descriptor(self) -> str:
        """``nna.descriptor``: census, cnn or hybrid."""
        return self.cfg.descriptor

    @property
    def bits(self) -> int:
        """Width in bits of the descriptor: the sum of its parts' bits."""
        return sum(b for _, b in self.parts)

    @property
    def part_bits(self) -> tuple[int, ...]:
        """Each part's bits, as the SVA matches them (:mod:`sva.hamming.cost`)."""
        return tuple(b for _, b in self.parts)


def resolve_nna(section: NnaConfig, *, checked: bool = False) -> NnaSpec:
    """The :class:`NnaSpec` of an ``nna`` section: the section checked
    (:func:`core.config.check_section`; ``checked=True`` where the caller holds what
    :func:`core.config.load_config` or :func:`core.config.check_config` has just returned),
    the CNN loaded once (:func:`load_cnn`) and the hybrid's fit checked. Raises
    :class:`ConfigError` with one line."""
    cfg = section if checked else check_section(section, "nna.")
    c = cfg.census
    if cfg.descriptor == "census":
        return NnaSpec(cfg=cfg, cnn=None, parts=(("census", census_bits(c.window, c.kind,
                                                                        c.stride)),),
                       halves=(c.window[1] // 2,), layer_macs=(0,))
    cnn = load_cnn(cfg)
    return NnaSpec(cfg=cfg, cnn=cnn, parts=_parts(cfg, cnn), halves=cnn.halves,
                   layer_macs=cnn.layer_macs)


def as_nna_spec(spec: NnaSpec | NnaConfig) -> NnaSpec:
    """``spec`` itself, or the spec of a raw ``nna`` section (:func:`resolve_nna`: checked,
    its network loaded) -- the form the NNA's rules take from a tool that holds only a
    configuration; a run hands its spec down."""
    return spec if isinstance(spec, NnaSpec) else resolve_nna(spec)


def _parts(cfg: NnaConfig, cnn: IntNetwork) -> tuple[tuple[str, int], ...]:
    """The parts of a CNN or hybrid descriptor: the CNN's bits, then (the hybrid) the census's.
    A hybrid of more than 64 bits, or whose census is taller than the network's receptive
    field, is a :class:`ConfigError` saying what to change."""
    if cfg.descriptor == "cnn":
        return (("cnn", cnn.channels),)
    c = cfg.census
    bits = census_bits(c.window, c.kind, c.stride)
    if cnn.channels + bits > 64:
        raise ConfigError(
            f"the hybrid descriptor would have {cnn.channels} CNN bits + {bits} census bits = "
            f"{cnn.channels + bits}, more than the 64 a descriptor word holds: use a smaller "
            "nna.census.window (or kind symmetric, or a stride)")
    if c.window[1] // 2 > cnn.reach:
        raise ConfigError(
            f"the census window {c.window[0]}x{c.window[1]} reaches {c.window[1] // 2} rows "
            f"above and below, beyond the network's {cnn.reach} (its receptive field): the "
            "hybrid descriptor would wait for rows the network does not read; use a census "
            f"window at most {2 * cnn.reach + 1} rows tall")
    return (("cnn", cnn.channels), ("census", bits))


def load_cnn(cfg: NnaConfig) -> IntNetwork:
    """The integer network of the CNN descriptor the section names (``nna.cnn.weights``: a
    weight file of one layer or a quantized artifact of 1..4 layers), as the file holds it now
    (a relative path from the working directory of this call; :func:`_read_cnn`) -- the first
    step of :func:`resolve_nna`, and the command line's early check of a weight file.

    Its last layer must have ``nna.cnn.channels`` output channels -- the SVA's register widths
    were worked out for that many bits -- else :class:`ConfigError` says which value to set."""
    cnn = _read_cnn(cfg.cnn.weights)
    if cnn.channels != cfg.cnn.channels:
        raise ConfigError(
            f"the CNN {cfg.cnn.weights!r} has {cnn.channels} output channels but "
            f"nna.cnn.channels is {cfg.cnn.channels}: set nna.cnn.channels = "
            f"{cnn.channels} (the SVA's automatic register widths follow it)"
        )
    return cnn


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


def _read_cnn(weights: str) -> IntNetwork:
    """The network of ``nna.cnn.weights``, read once per file content (:func:`file_identity`)
    over the runs of a process (a sweep's): a file rewritten, replaced or deleted since, or a
    relative path from another working directory, is read (and checked) again; so is a file
    modified less than 2 s before it was read."""
    path = weights_file(weights)
    key = file_identity(path)
    with _NETWORKS_LOCK:
        cnn = _NETWORKS.get(key) if key is not None else None
        if cnn is not None:
            _NETWORKS.move_to_end(key)
            return cnn
    cnn = load_network(path)  # a missing or bad file raises its one line here
    settled = key is not None and time.time_ns() - key[-1] > _SETTLED_NS
    if settled and file_identity(path) == key:  # and unchanged while it was read
        with _NETWORKS_LOCK:
            _NETWORKS[key] = cnn
            while len(_NETWORKS) > _NETWORKS_KEPT:
                _NETWORKS.popitem(last=False)
    return cnn


def descriptor_parts(spec: NnaSpec | NnaConfig) -> tuple[tuple[str, int], ...]:
    """The parts of the configured descriptor, in bit order, as (kind, bits): one part for the
    census or the CNN, two for the hybrid (the CNN's, then the census's) -- the spec's
    (:func:`resolve_nna` refuses a hybrid that does not fit)."""
    return as_nna_spec(spec).parts


def descriptor_bits(spec: NnaSpec | NnaConfig) -> int:
    """Width in bits of the configured descriptor: the sum of its parts' bits."""
    return as_nna_spec(spec).bits


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


def compute_descriptor(img: np.ndarray, spec: NnaSpec | NnaConfig) -> np.ndarray:
    """Descriptor image (H, W) uint32/uint64 of a grey uint8 image. ``spec``: the NNA's
    :class:`~nna.descriptor.NnaSpec` (trusted: resolved where the run started), or a raw ``nna``
    section, checked and resolved here (:func:`resolve_nna`: a hybrid that does not
    fit is refused before anything is computed)."""
    spec = as_nna_spec(spec)
    if spec.cnn is None:
        return census_of(img, spec.cfg)
    if spec.descriptor == "cnn":
        return network_descriptor(img, spec.cnn)
    return hybrid_word(network_descriptor(img, spec.cnn), census_of(img, spec.cfg),
                       spec.cnn.channels, spec.bits)
