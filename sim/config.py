"""The one configuration object of the chip.

Frozen dataclasses, one per block, nested in :class:`ChipConfig`. Every field declares its type,
its legal range or choices and a one-line help text; :func:`load_config` builds the object from the
defaults, an optional TOML file and dotted-key overrides, and rejects unknown keys and bad values
with the key's dotted name. ``stereosim config show`` prints the result as TOML.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stereosim.sim.census_layout import comparison_offsets
from stereosim.sim.errors import ConfigError, UserError
from stereosim.sim.outputs import path_text

LEGAL_DISPARITIES = tuple(range(16, 257, 16))


#: Output channels (descriptor bits) of the shipped 9x9x32 layer: the default of
#: ``nna.cnn.channels``, which the automatic register widths follow.
CNN_BITS = 32


def sgm_widths(p2: int, box: int = 5, bits: int = CNN_BITS, paths: int = 4) -> dict:
    """The narrowest cost, path and sum registers that never saturate: a box-filtered cost stays
    below ``box^2 * bits``, a path cost below that plus P2, the sum below ``paths`` path costs."""
    top = box * box * bits
    path_bits = (top + p2).bit_length()
    return {"cost_bits": top.bit_length(), "path_bits": path_bits,
            "sum_bits": (paths * ((1 << path_bits) - 1)).bit_length()}


# The back-end settings of each descriptor, chosen on the tuning scenes only (Middlebury 2005
# without Art and 2006; clean, noisy, exposure-changed and blurred pairs;
# benchmarks/tuning_report.py writes the chain of choices into docs/tuning.md): P1, P2 and
# the adaptive P2's slope, the box, then the cost, path and sum registers just wide enough for
# that box and P2. A configuration that does not set a key gets the value of its
# nna.descriptor; a key set in a file or with --set wins. The register widths it does not set
# follow its own box, P2 and paths (_derived_widths), so that a what-if on the box or the
# penalties does not saturate the registers sized for the tuned values.
DESCRIPTOR_DEFAULTS = {
    "census": {"p1": 256, "p2": 2048, "p2_adaptive": True, "p2_slope": 512, "box_size": 7},
    "cnn": {"p1": 256, "p2": 1792, "p2_adaptive": True, "p2_slope": 512, "box_size": 7},
}
# The shipped learned descriptor beats the 32-bit census on clean and on noisy MiddEval3
# (docs/ablation.md), so it is the default; census stays selectable.
DEFAULT_DESCRIPTOR = "cnn"
_DEFAULT_WIDTHS = sgm_widths(DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p2"],
                             DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["box_size"])


def param(default, help: str, *, lo=None, hi=None, choices=None, odd=False):
    """A config field with its validation rules in the metadata."""
    meta = {"help": help, "lo": lo, "hi": hi, "choices": choices, "odd": odd}
    return field(default=default, metadata=meta)


@dataclass(frozen=True, slots=True, kw_only=True)
class CensusConfig:
    """The census descriptor. The default, plain 11x3, is exactly 32 bits -- the width of the NNA
    descriptor -- and won the sweep in docs/tuning.md among the 31/32-bit windows."""

    window: tuple[int, int] = param(
        (11, 3), "census window [width, height], both odd", lo=1, hi=15, odd=True
    )
    kind: str = param(
        "plain",
        "plain: each pixel vs the centre; symmetric: each pixel vs its mirror through the centre",
        choices=("plain", "symmetric"),
    )
    stride: int = param(1, "sampling step inside the window (2 = sparse census)", lo=1, hi=4)


@dataclass(frozen=True, slots=True, kw_only=True)
class CnnConfig:
    weights: str = param(
        "default", "int8 weight file (.npz) of the descriptor layer, or 'default' for the shipped "
        "9x9x32 one"
    )
    channels: int = param(
        CNN_BITS, "output channels of the layer = descriptor bits; the SVA's automatic register "
        "widths follow it and the weight file must have this many", lo=1, hi=64,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class NnaConfig:
    descriptor: str = param(
        DEFAULT_DESCRIPTOR,
        "per-pixel binary descriptor: census or cnn (each brings its own tuned sva.p1/p2)",
        choices=("census", "cnn"),
    )
    census: CensusConfig = field(default_factory=CensusConfig)
    cnn: CnnConfig = field(default_factory=CnnConfig)
    macs: int = param(
        288, "MAC units per NNA submodule: a 9x9x32 descriptor takes ceil(2592 / macs) cycles",
        lo=1, hi=2592,
    )
    line_buffer_rows: int = param(
        10, "input rows a submodule's line buffer holds (9 = the window; 10 lets a row arrive "
        "while the window computes; at least the descriptor window's height)", lo=3, hi=64,
    )
    submodules: int = param(10, "NNA submodules on the chip", lo=1, hi=256)
    stereo_submodules: int = param(
        2, "submodules serving the stereo pair (even: half per camera; the rest are free for "
        "other networks)", lo=2, hi=256,
    )
    split: str = param(
        "columns", "how a camera's frame is shared by its submodules: columns (tiles with a "
        "halo) or rows (bands with a halo)", choices=("columns", "rows"),
    )
    lent_submodules: int = param(
        0, "submodules lent to another network (a what-if: they run its load, not the stereo "
           "pair's, and add its energy; its DRAM traffic is dram.lent_gbps)", lo=0, hi=256,
    )
    lent_mac_load: float = param(
        0.5, "the lent network's share of its submodules' MAC capacity (0..1)", lo=0.0, hi=1.0,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class SvaConfig:
    """The stereo accelerator. Accuracy defaults (box, P1, P2, adaptive P2, checks, median) come
    from the protocol of docs/tuning.md; register widths left unset are the narrowest that never
    saturate with the configured descriptor (:func:`descriptor_width`: the census's bits, the
    CNN's ``nna.cnn.channels``) at the configured box, P2 and paths: box sums <= box^2 * bits,
    a path cost <= that + P2, the sum of the paths' costs (:func:`sgm_widths`)."""

    disparities: int = param(
        128, "disparity range D (d in [0, D)); multiple of 16 in [16, 256]", choices=LEGAL_DISPARITIES
    )
    box_size: int = param(
        DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["box_size"],
        "box-filter aggregation window k (k x k, odd; 1 = off; default: the descriptor's)",
        lo=1, hi=15, odd=True,
    )
    cost_bits: int = param(
        _DEFAULT_WIDTHS["cost_bits"],
        "width of the aggregated matching cost (saturating; default: the narrowest that never "
        "saturates at the configured box)", lo=6, hi=15,
    )
    p1: int = param(
        DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p1"],
        "SGM penalty for a disparity change of 1 (default: the descriptor's tuned value)",
        lo=0, hi=32767,
    )
    p2: int = param(
        DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p2"],
        "SGM penalty for a disparity change of more than 1 (default: the descriptor's tuned value)",
        lo=0, hi=32767,
    )
    p2_adaptive: bool = param(
        DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p2_adaptive"],
        "lower P2 at intensity steps: P2 - (slope*|dI| >> 4), >= P1 (default: the descriptor's)",
    )
    p2_slope: int = param(
        DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p2_slope"],
        "slope of the adaptive P2 (in 1/16 per grey level; default: the descriptor's)",
        lo=0, hi=16384,
    )
    path_bits: int = param(
        _DEFAULT_WIDTHS["path_bits"],
        "width of each SGM path cost register (saturating; default: the narrowest that never "
        "saturates at the configured box and P2)", lo=8, hi=14,
    )
    sum_bits: int = param(
        _DEFAULT_WIDTHS["sum_bits"],
        "width of the summed path cost S (saturating; default: the narrowest that holds the "
        "configured paths)", lo=8, hi=16,
    )
    paths: int = param(
        4, "SGM paths: 1 = left-to-right, 2 = + top, 3 = + top-left, 4 = + top-right", lo=1, hi=4
    )
    uniqueness: int = param(
        0, "uniqueness margin in percent (0 = off): best must beat the runner-up by this", lo=0, hi=99
    )
    subpixel: str = param(
        "equiangular", "sub-pixel fit: off, parabola or equiangular",
        choices=("off", "parabola", "equiangular"),
    )
    subpixel_bits: int = param(4, "fractional bits F of the output disparity", lo=0, hi=8)
    lr_check: bool = param(True, "left-right consistency check from the same aggregated volume")
    lr_max_diff: int = param(2, "largest |dL - dR| (integer disparities) accepted by the LR check", lo=0, hi=255)
    median: int = param(5, "median filter on the output: 0 (off), 3 or 5", choices=(0, 3, 5))
    lanes: int = param(
        128, "disparities each SVA stage evaluates per cycle: a pixel takes ceil(D / lanes) "
        "cycles per stage, and the left SGM path adds its minimum tree (docs/architecture.md)",
        lo=1, hi=256,
    )
    compare_levels: int = param(
        8, "levels of two-input compare/add operators that settle in one SVA cycle (the depth "
        "of a reduction tree per cycle)", lo=1, hi=64,
    )
    sram_ports: str = param(
        "1r1w", "ports of each SVA SRAM bank: 1r1w (a read and a write port per cycle) or 1rw "
        "(one shared port: a stage that reads and writes a bank in one pixel takes both)",
        choices=("1r1w", "1rw"),
    )
    pairs: int = param(
        1, "camera pairs sharing the chip frame by frame (each writes its frames into its own "
        "source.frame_buffers; pair p's frames start p/pairs of a frame period after pair 0's)",
        lo=1, hi=8,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class ClockConfig:
    camera_mhz: float = param(74.25, "camera pixel clock (CEA-861 720p: 74.25 MHz)", lo=0.001, hi=10000.0)
    nna_mhz: float = param(460.0, "NNA clock", lo=0.001, hi=10000.0)
    sva_mhz: float = param(465.0, "SVA clock", lo=0.001, hi=10000.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class SourceConfig:
    kind: str = param(
        "memory", "where frames come from: memory (at memory_gbps) or camera (pixel clock with "
        "blanking; a camera cannot stall)", choices=("memory", "camera"),
    )
    memory_gbps: float = param(
        4.0, "memory read bandwidth per camera in GB/s (at most one pixel per NNA cycle)",
        lo=0.000001, hi=1000.0,
    )
    camera_hblank: int = param(370, "camera horizontal blanking in pixel clocks", lo=0, hi=100000)
    camera_vblank: int = param(30, "camera vertical blanking in lines", lo=0, hi=100000)
    frame_buffers: int = param(
        0, "camera only: 0 streams the camera straight into the NNA; B >= 1 writes each frame "
        "into one of B frame buffers in DRAM, which the NNA reads at memory_gbps",
        lo=0, hi=64,
    )
    on_overflow: str = param(
        "error", "camera only, when a frame finds no room (a full FIFO, or with frame buffers no "
        "free buffer): error (stop with one line) or drop_frame (skip that frame and count it; "
        "needs frame_buffers >= 1)", choices=("error", "drop_frame"),
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class DramConfig:
    """The DRAM channel the memory sources read from and the sink writes the disparities back
    to (a what-if: ``model = "none"`` keeps the memory sources' own token bucket and an ideal
    sink; docs/dram.md). Defaults: one LPDDR4 x32 channel -- 4266 MT/s x 32 bits = 17 GB/s peak, bursts of
    16 beats (BL16) of 4 bytes -- with an access latency assumed for a controller and PHY
    (docs/dram.md)."""

    model: str = param(
        "none", "none (the memory sources' token bucket at source.memory_gbps, an ideal sink) "
        "or tdm (one channel shared by time slots: the stereo read, then the write-back)",
        choices=("none", "tdm"),
    )
    gbps: float = param(17.0, "the channel's peak bandwidth in GB/s (LPDDR4 x32: 17)",
                        lo=0.001, hi=10000.0)
    burst_bytes: int = param(64, "bytes a burst moves (LPDDR4 x32 BL16: 64)", lo=1, hi=4096)
    latency_ns: float = param(100.0, "from a read burst's slot to its data in the chip, ns",
                              lo=0.0, hi=1e6)
    read_prefetch_bursts: int = param(8, "read bursts a memory source may have requested "
                                         "ahead of the pixels it sent", lo=1, hi=1 << 16)
    write_buffer_bursts: int = param(8, "bursts of disparity words the sink may hold before "
                                        "they are written", lo=1, hi=1 << 16)
    spill: str = param(
        "none", "a what-if: what the NNA writes to DRAM and the SVA reads back per pixel -- "
        "none, descriptors (both views' binary descriptors) or float32 (both views' feature "
        "maps before the sign, 4 bytes per channel)",
        choices=("none", "descriptors", "float32"),
    )
    lent_gbps: float = param(0.0, "DRAM traffic of another network run on the NNA submodules "
                                  "the stereo pair does not use (nna.lent_submodules), GB/s",
                             lo=0.0, hi=10000.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class FifoConfig:
    source_to_nna_depth: int = param(16, "pixels the source-to-NNA FIFO holds", lo=1, hi=1 << 24)
    nna_to_sva_depth: int = param(64, "descriptors each NNA-to-SVA FIFO holds", lo=1, hi=1 << 24)
    nna_to_merge_depth: int = param(
        64, "descriptors each submodule-to-merge FIFO of a split frame holds (column tiles "
        "work side by side only if this holds what a tile computes while the merge serves the "
        "others: stereosim estimate gives the depth)", lo=1, hi=1 << 24
    )
    sva_to_sink_depth: int = param(16, "disparities the SVA-to-sink FIFO holds", lo=1, hi=1 << 24)
    latency_cycles: int = param(1, "FIFO latency in consumer cycles (>= 1)", lo=1, hi=1024)
    sync_cycles: int = param(2, "synchroniser stages of a clock-domain crossing", lo=1, hi=16)


@dataclass(frozen=True, slots=True, kw_only=True)
class SimConfig:
    engine: str = param(
        "auto", "cycle-model engine: fast (compiled: every configuration, traces and runs that "
        "stop), readable (the reference kernel, slow), or auto (fast, unless a run asks for "
        "what only the readable kernel does: a shuffled evaluation order or a sink stall given "
        "as a function)",
        choices=("auto", "fast", "readable"),
    )
    watchdog_cycles: int = param(
        200000, "periods of the slowest clock without progress before a run is declared "
        "deadlocked", lo=10, hi=1 << 40
    )
    max_cycles: int = param(
        0, "stop the run once any clock domain has run this many cycles (like a simulator's "
        "cycle limit; --max-cycles N); 0: an automatic budget of 20x the expected run", lo=0,
        hi=1 << 50
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class ChipConfig:
    nna: NnaConfig = field(default_factory=NnaConfig)
    sva: SvaConfig = field(default_factory=SvaConfig)
    clocks: ClockConfig = field(default_factory=ClockConfig)
    source: SourceConfig = field(default_factory=SourceConfig)
    fifo: FifoConfig = field(default_factory=FifoConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    dram: DramConfig = field(default_factory=DramConfig)


# ----------------------------------------------------------------------------------------------
# building from TOML / overrides


def _is_config_class(tp) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


@functools.lru_cache(maxsize=None)
def _field_types(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)  # slow, and the same for every configuration


def _coerce(dotted: str, value, tp, meta) -> Any:
    """Check one leaf value against its declared type and rules; return the typed value."""
    origin = typing.get_origin(tp)
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            raise ConfigError(
                f"config key '{dotted}' must be a list of {len(args)} values, e.g. "
                f"{dotted} = [9, 7]; got {value!r}"
            )
        return tuple(_coerce(dotted, v, a, meta) for v, a in zip(value, args))
    if tp is bool:
        if isinstance(value, np.bool_):
            value = bool(value)
        if not isinstance(value, bool):
            raise ConfigError(f"config key '{dotted}' must be true or false; got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise ConfigError(f"config key '{dotted}' must be an integer; got {value!r}")
        value = int(value)
    elif tp is float:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ConfigError(f"config key '{dotted}' must be a number; got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"config key '{dotted}' must be a finite number; got {value!r}")
    elif tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"config key '{dotted}' must be a string; got {value!r}")
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        shown = ", ".join(str(c) for c in choices)
        raise ConfigError(f"config key '{dotted}' must be one of {shown}; got {value!r}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and value < lo or hi is not None and value > hi:
        raise ConfigError(f"config key '{dotted}' must be in [{lo}, {hi}]; got {value!r}")
    if meta.get("odd") and value % 2 == 0:
        raise ConfigError(f"config key '{dotted}' must be odd; got {value!r}")
    return value


def _build(cls, data: dict, prefix: str):
    hints = _field_types(cls)
    names = {f.name: f for f in dataclasses.fields(cls)}
    for key in data:
        if key not in names:
            dotted = f"{prefix}{key}"
            known = ", ".join(f"{prefix}{n}" for n in names)
            raise ConfigError(f"unknown config key '{dotted}' (known here: {known})")
    kwargs = {}
    for name, f in names.items():
        tp = hints[name]
        dotted = f"{prefix}{name}"
        if _is_config_class(tp):
            sub = data.get(name, {})
            if not isinstance(sub, dict):
                raise ConfigError(f"config key '{dotted}' is a table; set its keys, e.g. {dotted}.<key>")
            kwargs[name] = _build(tp, sub, dotted + ".")
        elif name in data:
            if isinstance(data[name], dict):
                raise ConfigError(f"config key '{dotted}' is a value, not a table")
            kwargs[name] = _coerce(dotted, data[name], tp, f.metadata)
    return cls(**kwargs)


def _parse_value(text: str, key: str):
    """A --set value: TOML syntax (numbers, true/false, [a, b], "str"), else a bare string;
    one nested deeper than the TOML reader can recurse is refused by its key."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise ConfigError(f"the value of {key} nests arrays or tables too deeply to be read: "
                          "give a plain value") from None


def _insert(tree: dict, dotted: str, value) -> None:
    parts = dotted.split(".")
    node = tree
    for i, part in enumerate(parts[:-1]):
        nxt = node.setdefault(part, {})
        if not isinstance(nxt, dict):
            raise ConfigError(f"config key '{'.'.join(parts[: i + 1])}' is a value, not a table")
        node = nxt
    node[parts[-1]] = value


def read_toml(path, what: str, error: type[UserError] = ConfigError) -> dict:
    """The parsed TOML file at ``path``; a missing, unreadable, binary or malformed file (or a
    folder) raises ``error`` with one line naming ``what`` and the file."""
    p = Path(path)
    shown = path_text(p)
    try:
        if p.is_dir():
            raise error(f"{what} {shown} is a folder: give the path of a TOML file")
        if not p.is_file():
            raise error(f"{what} {shown} not found: give the path of a TOML file")
        text = p.read_text()
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise error(f"cannot read {what} {shown} ({reason}): check the file and its "
                    "permissions") from None
    except UnicodeDecodeError:
        raise error(f"{what} {shown} is not UTF-8 text: give a TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {shown} is not valid TOML: {exc}") from None
    except RecursionError:  # the reader recurses once per level of [[[...]]] or {a = {...}}
        raise error(f"{what} {shown} nests arrays or tables too deeply to be read: flatten "
                    "them") from None


def load_config(
    path: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> ChipConfig:
    """Defaults, then the TOML file at ``path``, then ``overrides`` (dotted keys).

    Override values may be typed Python values or strings in TOML syntax (as given on the
    command line with ``--set key=value``).
    """
    tree: dict = {}
    if path is not None:
        tree = read_toml(path, "config file")
    for key, value in (overrides or {}).items():
        if not isinstance(key, str) or not key:
            raise ConfigError(f"override key {key!r} must be a dotted name such as sva.p1")
        if isinstance(value, str):
            value = _parse_value(value, key)
        _insert(tree, key, value)
    _descriptor_defaults(tree)
    return _check_combinations(_build(ChipConfig, tree, ""))


def check_config(cfg) -> ChipConfig:
    """The same checks as :func:`load_config` for a configuration built any other way (by hand,
    with ``dataclasses.replace``): every section of the right class, every value of its declared
    type and in range, every combination legal. Returns the checked configuration (values
    normalised: numpy scalars become Python numbers, lists become tuples); raises
    :class:`ConfigError` naming the first bad key."""
    if not isinstance(cfg, ChipConfig):
        raise ConfigError(f"a chip configuration must be a sim.ChipConfig; got {type(cfg).__name__}")
    return _check_combinations(_build(ChipConfig, _tree_of(cfg, ChipConfig, ""), ""))


SECTIONS = {"nna.": NnaConfig, "sva.": SvaConfig, "clocks.": ClockConfig,
            "source.": SourceConfig, "fifo.": FifoConfig, "sim.": SimConfig,
            "dram.": DramConfig}


def check_section(section, prefix: str):
    """:func:`check_config` for one section (``prefix`` ``"sva."``, ``"nna."``, ...): the check a
    stage's entry point runs before any kernel sees the values. Returns the checked section."""
    cls = SECTIONS[prefix]
    return _build(cls, _tree_of(section, cls, prefix), prefix)


def _tree_of(obj, cls, prefix: str) -> dict:
    """The nested dict of a config object, checking that every section has its class."""
    if type(obj) is not cls:
        raise ConfigError(
            f"config section '{prefix.rstrip('.') or 'chip'}' must be a {cls.__name__}; got "
            f"{type(obj).__name__}"
        )
    hints = _field_types(cls)
    tree = {}
    for f in dataclasses.fields(cls):
        value = getattr(obj, f.name)
        if _is_config_class(hints[f.name]):
            tree[f.name] = _tree_of(value, hints[f.name], f"{prefix}{f.name}.")
        else:
            tree[f.name] = value
    return tree


def _descriptor_defaults(tree: dict) -> None:
    """Fill the SVA keys the configuration leaves unset with the tuned values of its
    descriptor (:data:`DESCRIPTOR_DEFAULTS`). A malformed tree is left for :func:`_build` to
    report."""
    nna = tree.get("nna", {})
    sva = tree.setdefault("sva", {})
    if not isinstance(nna, dict) or not isinstance(sva, dict):
        return
    descriptor = nna.get("descriptor", DEFAULT_DESCRIPTOR)
    if not isinstance(descriptor, str):
        return
    for key, value in DESCRIPTOR_DEFAULTS.get(descriptor, {}).items():
        sva.setdefault(key, value)
    for key, value in _derived_widths(sva, descriptor_width(nna)).items():
        sva.setdefault(key, value)


def descriptor_width(nna: dict) -> int:
    """Bits of the descriptor the NNA table ``nna`` selects (defaults where unset), as far as the
    configuration knows it: the census's comparisons (:mod:`sim.census_layout`; at most 64, more
    is refused when the census is built), else the CNN's ``nna.cnn.channels``. A malformed table
    gives :data:`CNN_BITS`; :func:`_build` reports it when the whole tree is built."""
    is_census = nna.get("descriptor", DEFAULT_DESCRIPTOR) == "census"
    cls, key = (CensusConfig, "census") if is_census else (CnnConfig, "cnn")
    sub = nna.get(key, {})
    try:  # the keys' own rules (types, ranges, odd sizes), read from their declarations
        table = _build(cls, sub, f"nna.{key}.") if isinstance(sub, dict) else None
    except ConfigError:
        table = None
    if table is None:
        return CNN_BITS
    if not is_census:
        return table.channels
    offsets = comparison_offsets(*table.window, table.kind, table.stride)
    return max(1, min(len(offsets), 64))


def _derived_widths(sva: dict, bits: int) -> dict:
    """The register widths :func:`sgm_widths` gives for a ``bits``-bit descriptor and the box,
    P2 and paths of the SVA table ``sva`` (their defaults where unset), each clamped into its
    key's legal range (a P2 too large for the widest path register saturates it); none when one
    of them is malformed (left for :func:`_build` to report)."""
    meta = {f.name: f for f in dataclasses.fields(SvaConfig)}
    values = {k: sva.get(k, meta[k].default) for k in ("box_size", "p2", "paths")}
    if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in values.values()):
        return {}
    widths = sgm_widths(values["p2"], values["box_size"], bits, paths=max(values["paths"], 1))
    return {k: min(max(v, meta[k].metadata["lo"]), meta[k].metadata["hi"])
            for k, v in widths.items()}


def _check_combinations(cfg: ChipConfig) -> ChipConfig:
    """Rules that involve more than one key."""
    nna = cfg.nna
    if nna.stereo_submodules % 2:
        raise ConfigError(
            f"nna.stereo_submodules={nna.stereo_submodules} must be even (half per camera)"
        )
    if nna.stereo_submodules > nna.submodules:
        raise ConfigError(
            f"nna.stereo_submodules={nna.stereo_submodules} exceeds nna.submodules="
            f"{nna.submodules}: raise nna.submodules or use fewer for the stereo pair"
        )
    if nna.stereo_submodules + nna.lent_submodules > nna.submodules:
        raise ConfigError(
            f"nna.lent_submodules={nna.lent_submodules} with nna.stereo_submodules="
            f"{nna.stereo_submodules} exceeds nna.submodules={nna.submodules}: lend at most "
            f"{nna.submodules - nna.stereo_submodules}"
        )
    if cfg.sva.pairs > 1 and (cfg.source.kind != "camera" or cfg.source.frame_buffers == 0):
        raise ConfigError(
            f"sva.pairs={cfg.sva.pairs} shares the chip between camera pairs frame by frame, "
            "which needs each pair's frames in DRAM frame buffers: add --set source.kind=camera "
            "--set source.frame_buffers=2 (or use sva.pairs=1)"
        )
    d = cfg.dram
    if d.model == "none" and (d.spill != "none" or d.lent_gbps > 0):
        what = "dram.spill" if d.spill != "none" else "dram.lent_gbps"
        raise ConfigError(
            f"{what} needs the DRAM channel: add --set dram.model=tdm"
        )
    if d.lent_gbps > 0 and nna.lent_submodules == 0:
        raise ConfigError(
            f"dram.lent_gbps={d.lent_gbps} is the traffic of a network on lent NNA submodules, "
            "but none is lent: add --set nna.lent_submodules=N (or drop dram.lent_gbps)"
        )
    if d.lent_gbps >= d.gbps:
        raise ConfigError(
            f"dram.lent_gbps={d.lent_gbps} is not below the channel's dram.gbps={d.gbps}: the "
            "stereo pair would get no slot; lower it or widen the channel"
        )
    return cfg


def parse_set_options(items: list[str] | None) -> dict[str, str]:
    """``["sva.p1=10", ...]`` from the CLI into an override dict (values parsed later)."""
    out: dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set expects KEY=VALUE (e.g. --set sva.p1=10); got {item!r}")
        out[key.strip()] = value.strip()
    return out


# ----------------------------------------------------------------------------------------------
# output


def config_to_dict(cfg) -> dict:
    out = {}
    for f in dataclasses.fields(cfg):
        v = getattr(cfg, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = config_to_dict(v)
        elif isinstance(v, tuple):
            out[f.name] = list(v)
        else:
            out[f.name] = v
    return out


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(v)


def keys_set(path: str | Path | None = None, overrides: dict[str, Any] | None = None
             ) -> frozenset[str]:
    """The dotted keys a configuration file at ``path`` and ``overrides`` set (the keys the
    user chose, as opposed to defaults)."""
    out = set(overrides or {})

    def walk(tree: dict, prefix: str) -> None:
        for k, v in tree.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            else:
                out.add(f"{prefix}{k}")

    if path is not None:
        walk(read_toml(path, "config file"), "")
    return frozenset(out)


def _auto_keys(cfg, set_keys) -> dict[str, str]:
    """The keys left to be worked out that hold the worked-out value and were not set by the
    user: the descriptor's tuned values (:data:`DESCRIPTOR_DEFAULTS`) and the register widths
    that follow the box, P2 and paths (:func:`_derived_widths`): dotted key -> why."""
    defaults = DESCRIPTOR_DEFAULTS.get(cfg.nna.descriptor, {})

    def choices(key: str) -> str:
        return ", ".join(f"{d} {str(v[key]).lower()}" for d, v in DESCRIPTOR_DEFAULTS.items())

    auto = {f"sva.{k}": f"auto: nna.descriptor's tuned value ({choices(k)})"
            for k, v in defaults.items()
            if f"sva.{k}" not in set_keys and getattr(cfg.sva, k) == v}
    bits = descriptor_width(dataclasses.asdict(cfg.nna))
    derived = _derived_widths(dataclasses.asdict(cfg.sva), bits)
    auto.update({f"sva.{k}": "auto: the narrowest that never saturates at this descriptor, box, P2 and paths"
                 for k, v in derived.items()
                 if f"sva.{k}" not in set_keys and getattr(cfg.sva, k) == v})
    return auto


def config_to_toml(cfg, *, comments: bool = True, set_keys=frozenset()) -> str:
    """The effective configuration as TOML (loadable again with :func:`load_config`).

    A key whose default depends on the descriptor (``sva.p1``, ``sva.p2``) that holds that
    default and is not in ``set_keys`` (the keys the user set, :func:`keys_set`) is written
    commented out, so that loading the file with another ``nna.descriptor`` gives that
    descriptor's values rather than pinning these."""
    lines: list[str] = []
    auto = _auto_keys(cfg, set_keys)

    def emit(obj, prefix: str):
        scalars = [f for f in dataclasses.fields(obj) if not dataclasses.is_dataclass(getattr(obj, f.name))]
        tables = [f for f in dataclasses.fields(obj) if dataclasses.is_dataclass(getattr(obj, f.name))]
        if scalars and prefix:
            if lines:
                lines.append("")
            lines.append(f"[{prefix}]")
        for f in scalars:
            text = f"{f.name} = {_toml_value(getattr(obj, f.name))}"
            dotted = f"{prefix}.{f.name}" if prefix else f.name
            if dotted in auto:
                text = f"# {text:<26} # {auto[dotted]}"
            elif comments and f.metadata.get("help"):
                text = f"{text:<28} # {f.metadata['help']}"
            lines.append(text)
        for f in tables:
            emit(getattr(obj, f.name), f"{prefix}.{f.name}" if prefix else f.name)

    emit(cfg, "")
    return "\n".join(lines) + "\n"


def config_diff(a: ChipConfig, b: ChipConfig) -> dict[str, tuple[Any, Any]]:
    """Dotted keys whose values differ between two configurations."""
    out: dict[str, tuple[Any, Any]] = {}

    def walk(x, y, prefix):
        for k in x:
            if isinstance(x[k], dict):
                walk(x[k], y[k], f"{prefix}{k}.")
            elif x[k] != y[k]:
                out[f"{prefix}{k}"] = (x[k], y[k])

    walk(config_to_dict(a), config_to_dict(b), "")
    return out
