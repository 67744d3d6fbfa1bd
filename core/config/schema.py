"""The declarations of the one configuration object of the chip.

Frozen dataclasses, one per block, nested in :class:`ChipConfig`. Every field declares its type,
its legal range or choices and a one-line help text (:func:`param`); the checks
(:mod:`core.config.check`) read them from here, the loader (:mod:`core.config.loader`) builds
the object from the defaults, a TOML file and dotted-key overrides, and the writer
(:mod:`core.config.writer`) prints it as TOML.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from stereosim.core.config.widths import CNN_BITS, sgm_widths

LEGAL_DISPARITIES = tuple(range(16, 257, 16))

# The back-end settings of each descriptor, chosen on the tuning scenes only (Middlebury 2005
# without Art and 2006; clean, noisy, exposure-changed and blurred pairs;
# benchmarks/tuning_report.py writes the chain of choices into docs/tuning.md): P1, P2 and
# the adaptive P2's slope, the box, then the cost, path and sum registers just wide enough for
# that box and P2. A configuration that does not set a key gets the value of its
# nna.descriptor; a key set in a file or with --set wins. The register widths it does not set
# follow its own box, P2 and paths (core.config.loader.derived_widths), so that a what-if on the
# box or the penalties does not saturate the registers sized for the tuned values.
DESCRIPTOR_DEFAULTS = {
    "census": {"p1": 256, "p2": 2048, "p2_adaptive": True, "p2_slope": 512, "box_size": 7},
    "cnn": {"p1": 256, "p2": 1792, "p2_adaptive": True, "p2_slope": 512, "box_size": 7},
    # the hybrid's: chosen with the robust network beside a plain 9x3 census, weights 3, 2 and
    # 2, 0 per frame (benchmarks/hybrid_tuning.py, docs/hybrid.md; configs/hybrid-720p.toml)
    "hybrid": {"p1": 800, "p2": 5120, "p2_adaptive": True, "p2_slope": 2048, "box_size": 7},
}
# The shipped learned descriptor beats the 32-bit census on clean and on noisy MiddEval3
# (docs/ablation.md), so it is the default; census stays selectable.
DEFAULT_DESCRIPTOR = "cnn"
#: The hybrid descriptor's weights (``sva.cost_weights``, ``noisy_weights``): each a 2-bit
#: register, so a weighted distance is the distance, itself shifted by one, or both added. The
#: defaults and the noise threshold are the hybrid preset's, chosen on the tuning scenes
#: (benchmarks/hybrid_tuning.py: the threshold is the middle of the gap between the clean and
#: the sigma-8 pairs' statistic); the gradient bound is the statistic's definition (sva.noise)
MAX_WEIGHT = 3
HYBRID_WEIGHTS = (3, 2)
NOISY_WEIGHTS = (2, 0)
NOISE_THRESHOLD = 31
NOISE_GRADIENT = 16
#: The SGM kernel's uint16 lanes bound its registers and penalties (:func:`sva.sgm.sgm.sgm`
#: checks the same numbers): a path cost of at most 14 bits (four paths and the kernel's ABSENT
#: sentinel fit), a sum of at most 16, P1 and P2 below 2^15. The largest values of
#: ``sva.path_bits``, ``sva.sum_bits``, ``sva.p1`` and ``sva.p2``.
PATH_BITS_MAX = 14
SUM_BITS_MAX = 16
PENALTY_MAX = 32767
_DEFAULT_WIDTHS = sgm_widths(DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p2"],
                             DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["box_size"])


#: The automatic cycle budget (``sim.max_cycles = 0``) allows each clock domain this many times
#: the cycles of the expected run (:func:`sim.cycle.plan.frame_budget`); its help text and the
#: message of a run that exhausts it quote this number.
AUTO_BUDGET_FACTOR = 20

def param(default, help: str, *, lo=None, hi=None, choices=None, odd=False, path=False):
    """A config field with its validation rules in the metadata. ``path``: the value names a
    file, which a config file gives relative to its own folder (:mod:`core.config.loader`);
    the default value names none."""
    meta = {"help": help, "lo": lo, "hi": hi, "choices": choices, "odd": odd, "path": path}
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
        "default", "int8 weight file (.npz) of the descriptor network (in a config file: "
        "relative to that file), or 'default' for the shipped 9x9x32 one", path=True,
    )
    channels: int = param(
        CNN_BITS, "output channels of the layer = descriptor bits; the SVA's automatic register "
        "widths follow it and the weight file must have this many", lo=1, hi=64,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class NnaConfig:
    descriptor: str = param(
        DEFAULT_DESCRIPTOR,
        "per-pixel binary descriptor: census, cnn, or hybrid (the CNN's bits beside a census "
        "signature, matched with the weighted sum of the two Hamming distances: "
        "sva.cost_weights); each brings its own tuned sva.p1/p2",
        choices=("census", "cnn", "hybrid"),
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
    layer_macs: tuple[int, ...] = param(
        (), "MAC units of each layer's stage (one per layer of the network, summing to at most "
        "nna.macs; empty: nna.macs split in proportion to the layers' MACs per pixel)",
        lo=1, hi=2592,
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
        0, "submodules lent to another network, nna.lent_network (they run its layers, not the "
           "stereo pair's; its DRAM traffic takes slots of the channel)", lo=0, hi=256,
    )
    lent_network: str = param(
        "", "TOML file of the network on the lent submodules: its input, frame rate and "
            "convolution layers (docs/lent.md; in a config file: relative to that file; "
            "\"\": none)", path=True,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class SvaConfig:
    """The stereo accelerator. Accuracy defaults (box, P1, P2, adaptive P2, checks, median) come
    from the protocol of docs/tuning.md; register widths left unset are the narrowest that never
    saturate with the configured descriptor (:func:`core.config.loader.descriptor_width`: the
    census's bits, the CNN's ``nna.cnn.channels``) at the configured box, P2 and paths: box sums
    <= box^2 * bits, a path cost <= that + P2, the sum of the paths' costs
    (:func:`core.config.widths.sgm_widths`)."""

    disparities: int = param(
        128, "disparity range D (d in [0, D)); multiple of 16 in [16, 256]",
        choices=LEGAL_DISPARITIES
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
        lo=0, hi=PENALTY_MAX,
    )
    p2: int = param(
        DESCRIPTOR_DEFAULTS[DEFAULT_DESCRIPTOR]["p2"],
        "SGM penalty for a disparity change of more than 1 (default: the descriptor's tuned value)",
        lo=0, hi=PENALTY_MAX,
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
        "saturates at the configured box and P2)", lo=8, hi=PATH_BITS_MAX,
    )
    sum_bits: int = param(
        _DEFAULT_WIDTHS["sum_bits"],
        "width of the summed path cost S (saturating; default: the narrowest that holds the "
        "configured paths)", lo=8, hi=SUM_BITS_MAX,
    )
    paths: int = param(
        4, "SGM paths: 1 = left-to-right, 2 = + top, 3 = + top-left, 4 = + top-right", lo=1, hi=4
    )
    uniqueness: int = param(
        0, "uniqueness margin in percent (0 = off): best must beat the runner-up by this",
        lo=0, hi=99
    )
    subpixel: str = param(
        "equiangular", "sub-pixel fit: off, parabola or equiangular",
        choices=("off", "parabola", "equiangular"),
    )
    subpixel_bits: int = param(4, "fractional bits F of the output disparity", lo=0, hi=8)
    lr_check: bool = param(True, "left-right consistency check from the same aggregated volume")
    lr_max_diff: int = param(
        2, "largest |dL - dR| (integer disparities) accepted by the LR check", lo=0, hi=255
    )
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
    cost_weights: tuple[int, int] = param(
        HYBRID_WEIGHTS, "hybrid descriptor only: the weights [cnn, census] of its two Hamming "
        "distances in the matching cost, 0..3 each (2-bit registers: a shift and an add)",
        lo=0, hi=MAX_WEIGHT,
    )
    weight_mode: str = param(
        "fixed", "hybrid descriptor only: fixed (sva.cost_weights on every frame) or auto "
        "(per frame, sva.noisy_weights when the left view's noise statistic exceeds "
        "sva.noise_threshold: sva.noise)", choices=("fixed", "auto"),
    )
    noisy_weights: tuple[int, int] = param(
        NOISY_WEIGHTS, "hybrid descriptor, weight_mode auto: the weights [cnn, census] of a "
        "frame found noisy", lo=0, hi=MAX_WEIGHT,
    )
    noise_threshold: int = param(
        NOISE_THRESHOLD, "weight_mode auto: a frame is noisy when its mean |Laplacian| over the "
        "statistic's pixels exceeds this (Gaussian noise of sigma s gives about 4.8 s)",
        lo=0, hi=1020,
    )
    noise_gradient: int = param(
        NOISE_GRADIENT, "weight_mode auto: the statistic leaves out pixels whose gradient "
        "|dI/dx| + |dI/dy| (central differences) exceeds this (edges are not noise)",
        lo=0, hi=1020,
    )
    pairs: int = param(
        1, "camera pairs sharing the chip frame by frame (each writes its frames into its own "
        "source.frame_buffers; pair p's frames start p/pairs of a frame period after pair 0's)",
        lo=1, hi=8,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class ClockConfig:
    camera_mhz: float = param(74.25, "camera pixel clock (CEA-861 720p: 74.25 MHz)",
                              lo=0.001, hi=10000.0)
    nna_mhz: float = param(460.0, "NNA clock", lo=0.001, hi=10000.0)
    sva_mhz: float = param(465.0, "SVA clock", lo=0.001, hi=10000.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class SourceConfig:
    kind: str = param(
        "memory", "where frames come from: memory (at memory_gbps) or camera (pixel clock with "
        "blanking; a camera cannot stall)", choices=("memory", "camera"),
    )
    camera_width: int = param(
        0, "width of the frames the chip is built for (a preset's camera resolution): a pair of "
        "another size is refused; 0 with camera_height 0: the pair's own size", lo=0, hi=1 << 16,
    )
    camera_height: int = param(
        0, "height of the frames the chip is built for (see camera_width; 0: the pair's own)",
        lo=0, hi=1 << 16,
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
    sink; docs/dram.md). Defaults: one LPDDR4 x32 channel -- 4266 MT/s x 32 bits = 17 GB/s
    peak, bursts of 16 beats (BL16) of 4 bytes -- with an access latency assumed for a
    controller and PHY (docs/dram.md)."""

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
        f"cycle limit; --max-cycles N); 0: an automatic budget of {AUTO_BUDGET_FACTOR}x the "
        "expected run", lo=0, hi=1 << 50
    )


#: The process nodes the technology model (:mod:`core.tech`) holds figures for.
NODES = ("130nm", "45nm", "7nm")


@dataclass(frozen=True, slots=True, kw_only=True)
class PowerConfig:
    node: str = param("45nm", "process node of the area and power figures (core.tech: every "
                      "figure read from a cited cell library; docs/energy.md)", choices=NODES)
    clock_gating: str = param(
        "off", "which cycles of a block clock its flip-flops (the run's power, docs/energy.md): "
        "off: every cycle of its domain; idle: all but its idle cycles; stalled: its busy "
        "cycles only (idle, blocked and starved gated)", choices=("off", "idle", "stalled"))
    gate_unused: bool = param(
        False, "power-gate the NNA submodules neither the stereo pair nor the lent network uses: "
        "no leakage, no clock; they stay off for the whole run, so no wake-up latency applies")


@dataclass(frozen=True, slots=True, kw_only=True)
class ChipConfig:
    nna: NnaConfig = field(default_factory=NnaConfig)
    sva: SvaConfig = field(default_factory=SvaConfig)
    clocks: ClockConfig = field(default_factory=ClockConfig)
    source: SourceConfig = field(default_factory=SourceConfig)
    fifo: FifoConfig = field(default_factory=FifoConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    dram: DramConfig = field(default_factory=DramConfig)
    power: PowerConfig = field(default_factory=PowerConfig)


#: Keys that no longer exist, with what replaces them (a configuration that sets one is refused
#: with this line).
RETIRED = {
    "nna.lent_mac_load": "nna.lent_mac_load is retired: describe the lent network's layers in "
                         "a TOML file and give it as nna.lent_network (docs/lent.md)",
    "dram.lent_gbps": "dram.lent_gbps is retired: the lent network's DRAM traffic follows from "
                      "its layers and frame rate; give them as nna.lent_network (docs/lent.md)",
}

#: The sections a stage's entry point may check on their own (:func:`core.config.check_section`).
SECTIONS = {"nna.": NnaConfig, "sva.": SvaConfig, "clocks.": ClockConfig,
            "source.": SourceConfig, "fifo.": FifoConfig, "sim.": SimConfig,
            "dram.": DramConfig, "power.": PowerConfig}
