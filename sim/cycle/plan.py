"""The chip plan: the one netlist of the cycle model, built once from (configuration, frame shape).

A :class:`ChipPlan` names every clock domain, FIFO (depth, width, producer and consumer, their
domains, the visibility and free-slot delays, the configuration key that sizes it), block (kind,
domain, ports, tile, cycles per item, windows, look-ahead, latency, buffers with their capacity
in bits), the traced signals and the run's cycle budget. The readable kernel instantiates it
(:mod:`sim.cycle.readable.chip`), the compiled engine serialises it into arrays
(:mod:`sim.cycle.compiled`), the analytic model walks it (:mod:`sim.cycle.estimate`), and reports
and traces take their names from it. A constant derived from the configuration and the frame
shape, or a topology fact, is computed here and nowhere else. The keys the configuration works
out itself when they are left unset -- the SVA's register widths, the descriptor's tuned back
end -- are filled in where it is loaded (:mod:`core.config.loader`, so that ``stereosim config
show`` prints them) and read from it here like any other key.

Topology (the order is the readable kernel's: it fixes the order of FIFOs and blocks in the
stop messages)::

    per camera side (left, right):
        source (memory_<side> in the nna domain, or camera_<side> in its own)
          -> src_<side>_to_nna[t]   one per submodule t (t only when the frame is split)
        NNA submodule nna_<side>[t] -> nna_<side>_to_sva        (one submodule per camera)
                                    -> nna_<side>t_to_merge -> merge_<side> -> nna_<side>_to_sva
    sva (joint pop of both sides) -> sva_to_sink -> sink
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

from stereosim.core.config import AUTO_BUDGET_FACTOR, ChipConfig
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.timing import BufferPlan, StagePlan
from stereosim.nna.descriptor import NnaSpec
from stereosim.nna.geometry import (
    Tile,
    census_rows,
    check_line_buffer,
    half_window,
    layer_tiles,
    split_frame,
)
from stereosim.nna.submodule.timing import (
    LayerPlan,
    cycles_per_descriptor,
    nna_layers,
    nna_stages,
    pipeline_cycles,
)
from stereosim.sim.cycle.dram import DramPlan, dram_plan
from stereosim.sim.cycle.fifo.rule import fifo_edges
from stereosim.sim.cycle.lent import LentPlan, lent_plan
from stereosim.sim.cycle.rules import (
    ClockDomain,
    period_fs,
    sva_first_slot_row,
    sva_frame_ticks,
)
from stereosim.sim.cycle.spec import ChipSpec, resolve_chip
from stereosim.sim.cycle.stages import (
    flush_ii,
    pipeline_ii,
    pipeline_latency,
    slot_ii,
    sva_stages,
)
from stereosim.sva.geometry import box_radius, check_disparity_range, median_radius
from stereosim.sva.hamming.noise import band_rows

SIDES = ("left", "right")
STATUS_CODES = {"idle": 0, "busy": 1, "starved": 2, "blocked": 3}  # as traced


@dataclass(frozen=True)
class DomainPlan:
    """A clock domain: edge k at k * period_fs (every domain starts at t = 0)."""

    name: str
    freq_hz: float
    period_fs: int

    def clock(self) -> ClockDomain:
        return ClockDomain(self.name, self.freq_hz)


@dataclass(frozen=True)
class FifoPlan:
    """A FIFO from ``producer`` (domain ``src``) to ``consumer`` (domain ``dst``)."""

    name: str
    key: str  # the configuration key of its depth
    depth: int
    width_bits: int
    producer: str
    consumer: str
    src: str
    dst: str
    latency_cycles: int
    sync_cycles: int
    beats: int  # items per frame

    @property
    def crossing(self) -> bool:
        return self.src != self.dst

    @property
    def data_edges(self) -> int:
        return fifo_edges(self.latency_cycles, self.sync_cycles, self.crossing)[0]

    @property
    def space_edges(self) -> int:
        return fifo_edges(self.latency_cycles, self.sync_cycles, self.crossing)[1]

    @property
    def sram_bits(self) -> int:
        return self.depth * self.width_bits


@dataclass(frozen=True)
class BlockPlan:
    """A block of the chip. ``kind``: memory, camera, nna, merge, sva or sink. Per kind:

    - memory: ``bytes_per_s`` (token bucket), ``items`` pixels; with ``feed`` (a camera with
      frame buffers) it reads the frames that camera writes into ``frame_buffers`` buffers
      (``line_clocks``, ``frame_clocks``: the camera's raster);
    - camera: ``line_clocks`` = W + hblank, ``frame_clocks`` = (H + vblank)(W + hblank); with
      frame buffers it writes into DRAM (no FIFO) and admits or drops each frame;
    - nna: ``tile``, ``half`` (window rows above/below), ``rows`` (line buffer), ``ii``, the
      cycles per descriptor (the MAC array's initiation interval and latency; a network of several
      layers: the slowest layer's cycles per output pixel), ``layers`` (the layer pipeline,
      :class:`~nna.submodule.timing.LayerPlan`: one stage per layer, one for a single layer or
      the census);
    - merge: ``items`` descriptors moved, one per cycle;
    - sva: ``lookahead`` rows (the box radius r: box row y needs input row y + r),
      ``passes`` (k - 1: the column sums' seeding passes before a frame's row 0), ``skew``
      (S = m W + m: the median's words behind, 0 without it), ``flush_ii`` (f: the ticks
      between its flush slots, the median's II), ``slot_ii`` (a: the
      sequencer's slot II), ``first_row`` (the input row a frame's first slot waits for: the
      automatic weights' noise band), ``stages`` (its pipeline, :mod:`sim.cycle.stages`),
      ``latency`` (a word issued -> in the output register: the stages' latencies), ``ii``, the
      cycles per word (initiation interval: the slowest stage's) -- the rules are
      :func:`~sim.cycle.rules.sva_slot` and the issue rules after it;
    - sink: one word per cycle.
    """

    name: str
    kind: str
    domain: str
    side: int | None
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    scope: str  # trace scope, e.g. "top.nna.left.sub0"
    items: int  # beats it emits per frame (the sink: words it takes)
    ii: int = 1
    latency: int = 0
    tile: Tile | None = None
    half: int = 0
    rows: int = 0
    lookahead: int = 0
    passes: int = 0  # sva: the column sums' seeding passes (k - 1)
    skew: int = 0  # sva: the median's skew in words, m W + m
    flush_ii: int = 1  # sva: ticks between the median's flush slots (its II)
    slot_ii: int = 1  # sva: the slot II
    first_row: int = 0  # sva: the input row a frame's first slot waits for (automatic weights)
    bytes_per_s: int = 0
    line_clocks: int = 0
    frame_clocks: int = 0
    buffers: tuple[BufferPlan, ...] = ()
    stages: tuple[StagePlan, ...] = ()
    feed: str = ""  # memory: the camera whose frame buffers it reads ("": frames in memory)
    frame_buffers: int = 0  # memory fed by a camera: the frame buffers in DRAM
    layers: tuple[LayerPlan, ...] = ()  # nna: its layer stages


@dataclass(frozen=True)
class SignalPlan:
    """A traced signal: VCD ``path``, ``width`` in bits, clock ``domain``; the readable kernel
    reports it as ``owner.key``."""

    path: str
    width: int
    domain: str
    owner: str
    key: str


@dataclass(frozen=True)
class ChipPlan:
    """The chip of a configuration at a frame size: clock domains, blocks, FIFOs, buffers,
    signals and the derived constants every engine, the estimate and the reports read; the
    resolved chip it was built from (``spec``, :class:`~sim.cycle.spec.ChipSpec`: the checked
    configuration, the NNA's network, the SVA's widths), which they read from here."""

    spec: ChipSpec
    shape: tuple[int, int]
    domains: dict[str, DomainPlan]
    fifos: tuple[FifoPlan, ...]
    blocks: tuple[BlockPlan, ...]
    tiles: tuple[Tile, ...]
    budget: dict[str, int]
    beat_bits: int  # NNA -> SVA beat: the descriptor (+ 8 bits of intensity: adaptive P2, auto)
    frames: int = 1  # camera frames of the stream (all of ``shape``; every pair's: ``pairs``)
    signals: tuple[SignalPlan, ...] = field(default=())
    dram: DramPlan | None = None  # the DRAM channel (dram.model = "tdm"), else None
    lent: LentPlan | None = None  # the network on the lent NNA submodules (nna.lent_network)

    @property
    def cfg(self) -> ChipConfig:
        """The checked configuration (the spec's)."""
        return self.spec.cfg

    @property
    def descriptor_parts(self) -> tuple[tuple[str, int], ...]:
        """The descriptor's parts in bit order, (kind, bits): one, or the hybrid's CNN and
        census parts (:attr:`nna.descriptor.NnaSpec.parts`)."""
        return self.spec.nna.parts

    @property
    def descriptor_bits(self) -> int:
        """Width in bits of the descriptor: the sum of its parts' bits."""
        return self.spec.nna.bits

    @property
    def part_bits(self) -> tuple[int, ...]:
        """Each descriptor part's bits, as the SVA's kernels take them (:mod:`sva.hamming.cost`)."""
        return self.spec.sva.parts

    @property
    def word_bits(self) -> int:
        """Bits of the SVA's output word."""
        return self.spec.sva.word_bits

    @property
    def cost_max(self) -> int:
        """The largest matching cost of a pixel (the hybrid: weighted)."""
        return self.spec.sva.cost_max

    @property
    def hybrid(self) -> bool:
        return len(self.descriptor_parts) > 1

    # ---- lookups ----------------------------------------------------------------------------

    def fifo(self, name: str) -> FifoPlan:
        return self._fifo_index[name]

    def block(self, name: str) -> BlockPlan:
        return self._block_index[name]

    def blocks_of(self, kind: str) -> list[BlockPlan]:
        return [b for b in self.blocks if b.kind == kind]

    @cached_property
    def _fifo_index(self) -> dict[str, FifoPlan]:
        return {f.name: f for f in self.fifos}

    @cached_property
    def _block_index(self) -> dict[str, BlockPlan]:
        return {b.name: b for b in self.blocks}

    @property
    def parts(self) -> int:
        """Submodules per camera."""
        return len(self.tiles)

    @property
    def camera(self) -> bool:
        return self.cfg.source.kind == "camera"

    @property
    def pairs(self) -> int:
        """Camera pairs sharing the chip frame by frame (``sva.pairs``): the stream's frame f is
        pair f % pairs's (:func:`~sim.cycle.rules.camera_frame_start`)."""
        return self.cfg.sva.pairs

    @property
    def frame_buffered(self) -> bool:
        """A camera that writes its frames into DRAM frame buffers, read by a memory source."""
        return self.camera and self.cfg.source.frame_buffers > 0

    @property
    def camera_direct(self) -> bool:
        """A camera streaming straight into the NNA's FIFOs."""
        return self.camera and not self.frame_buffered

    @property
    def camera_fps(self) -> float | None:
        """The camera's own frame rate (its pixel clock over its whole raster, blanking
        included): no stream from it is faster. None without a camera."""
        if not self.camera:
            return None
        camera = self.blocks_of("camera")[0]
        return self.domains["camera"].freq_hz / camera.frame_clocks

    @cached_property
    def symmetric(self) -> bool:
        """Do the two cameras' sides time alike -- the same blocks and FIFOs but for their
        names? (Then every event of the right side is the left side's: nothing in the chip's
        timing tells them apart, and the compiled engine computes one side for both.)"""

        def side(s):
            blocks = [(b.kind, b.domain, b.items, b.ii, b.tile, b.half, b.rows,
                       b.bytes_per_s, b.line_clocks, b.frame_clocks)
                      for b in self.blocks if b.side == s]
            fifos = [(f.depth, f.width_bits, f.src, f.dst, f.latency_cycles, f.sync_cycles,
                      f.beats) for f in self.fifos if self.block(f.producer).side == s]
            return blocks, fifos

        return side(0) == side(1)

    @property
    def dram_channel(self) -> bool:
        """The memory sources read, and the sink writes back, through the DRAM channel."""
        return self.dram is not None

    @property
    def source_domain(self) -> str:
        """The domain of the block that pushes the pixels into the NNA's FIFOs."""
        return "camera" if self.camera_direct else "nna"

    @property
    def p_max_fs(self) -> int:
        """The slowest clock's period (the watchdog counts in it)."""
        return max(d.period_fs for d in self.domains.values())

    @property
    def dram_wait_cycles(self) -> int:
        """Periods of the slowest clock the watchdog adds for the DRAM channel's longest wait
        (:attr:`DramPlan.longest_wait_fs`; 0 without the channel): a legal latency such as
        ``dram.latency_ns = 1e6`` is not a deadlock."""
        if self.dram is None:
            return 0
        return -(-self.dram.longest_wait_fs // self.p_max_fs)

    @property
    def watchdog_cycles(self) -> int:
        """The watchdog's window in periods of the slowest clock, as both engines count it:
        ``sim.watchdog_cycles`` plus :attr:`dram_wait_cycles`."""
        return self.cfg.sim.watchdog_cycles + self.dram_wait_cycles

    @property
    def watchdog_fs(self) -> int:
        return self.watchdog_cycles * self.p_max_fs

    @property
    def watchdog_remedy(self) -> str:
        """What a run the watchdog stopped tells the user (both engines): which limit fired
        and how to raise it."""
        limit = f"sim.watchdog_cycles = {self.cfg.sim.watchdog_cycles} periods"
        if self.dram_wait_cycles:
            limit += f" (+ {self.dram_wait_cycles} for the DRAM's longest wait)"
        return (f"the watchdog allows {limit}: deepen a FIFO or change what a block waits for, "
                "or raise sim.watchdog_cycles if the chip may legitimately wait longer")

    @property
    def budget_domain(self) -> str:
        """The clock domain whose budget ends a run that does not complete: the one whose
        last allowed edge comes first (ties: the first domain), as both engines check it."""
        order = list(self.domains)
        return min(self.budget, key=lambda d: (self.budget[d] * self.domains[d].period_fs,
                                               order.index(d)))

    @property
    def budget_reason(self) -> str:
        """Which budget ends a run that does not complete (the report's ``stopped.reason``):
        ``max_cycles``, the user's ``sim.max_cycles``; ``cycle_budget``, the automatic one;
        ``time_limit``, either capped to the longest run the engines simulate
        (:data:`MAX_RUN_FS`)."""
        d = self.budget_domain
        if self.budget[d] == MAX_RUN_FS // self.domains[d].period_fs:
            return "time_limit"
        return "max_cycles" if self.cfg.sim.max_cycles else "cycle_budget"

    @property
    def expected_run_s(self) -> float:
        """The chip time the automatic budget expects the run to take, seconds: its frames
        at :func:`expected_frame_s` each."""
        freqs = {name: d.freq_hz for name, d in self.domains.items()}
        return self.frames * expected_frame_s(self.cfg, self.shape, freqs,
                                              self.blocks_of("nna")[0].ii,
                                              self.block("sva").ii, self.frames, self.dram)

    @property
    def budget_head(self) -> str:
        """How the line of a run stopped by its budget begins (both engines): a stop the user
        asked for (``--max-cycles N``) is not called an error the chip made."""
        reason = self.budget_reason
        if reason == "max_cycles":
            return f"stopped at the cycle budget you set (--max-cycles {self.cfg.sim.max_cycles})"
        if reason == "time_limit":
            return "stopped at the longest run the cycle engines simulate"
        return "cycle budget exceeded"

    @property
    def budget_remedy(self) -> str:
        """What a run that ran out of cycles tells the user (both engines)."""
        reason, n = self.budget_reason, self.cfg.sim.max_cycles
        if reason == "max_cycles":  # --max-cycles takes N >= 1: 0 is a config file's
            return ("raise --max-cycles N (sim.max_cycles), or leave it out for the automatic "
                    f"budget ({AUTO_BUDGET_FACTOR}x the expected run)")
        if reason == "time_limit":
            asked = (f"--max-cycles {n} asks for more" if n else
                     f"the automatic budget, {AUTO_BUDGET_FACTOR}x the expected run, asks for more")
            return (f"{MAX_RUN_FS / 1e15:.3f} s of chip time is the longest run the engines "
                    f"simulate (their time counts femtoseconds in 64 bits; {asked}): a frame that "
                    "takes that long is starved -- check what the chip waits for (the DRAM "
                    "channel's slots: nna.lent_network, dram.gbps) and the clocks")
        return (f"the automatic budget ({AUTO_BUDGET_FACTOR}x the expected run) ran out: give a "
                "cycle limit with --max-cycles N (sim.max_cycles)")

    def work_cycles(self, block: BlockPlan, busy: int) -> int:
        """A block's work per frame, the cycles its critical resource is occupied: the MAC
        array's descriptors x cycles (NNA), the sequencer's ticks of a frame (SVA,
        :func:`~sim.cycle.rules.sva_frame_ticks`: words x II and its row and frame gaps), one
        beat per cycle (merge), the whole raster with blanking (camera: a camera delivers frames no
        faster), and the cycles its port transferred (memory source: ``busy``, measured over the
        stream and shared out per frame -- a bandwidth-limited source that is back-pressured
        banks tokens while blocked; through the DRAM channel: the rounds of its frame's read
        bursts)."""
        if block.kind == "memory" and self.dram is not None:  # its read slots
            d = self.dram
            h, w = self.shape
            per = self.domains[block.domain].period_fs
            bursts = -(-h * w // d.read_pixels)
            return -(-bursts * d.round_fs // per)
        if block.kind == "memory":
            return busy // self.frames  # measured over the stream: its share of a frame
        if block.kind == "camera":  # pairs sharing the chip start a frame every 1/P period
            return block.frame_clocks // self.pairs
        if block.kind == "nna":  # its busiest layer's MAC array (one layer: items x cycles)
            return pipeline_cycles(tuple(lay.items for lay in block.layers),
                                   tuple(lay.ii for lay in block.layers))
        if block.kind == "sva":  # its sequencer's ticks: words, row starts, passes, flush
            h, w = self.shape
            return sva_frame_ticks(h, w, block.ii, block.lookahead, block.slot_ii,
                                   block.skew, block.passes, block.flush_ii)
        return block.items * block.ii


def _nb(n: int) -> int:
    return max(1, int(n).bit_length())


#: The longest stretch of chip time a cycle run simulates, on both engines: the compiled engine
#: counts time in int64 femtoseconds and keeps 2**62 for "never"
#: (:data:`sim.cycle.compiled.layout.INF`), so every domain's budget is capped to the cycles
#: that end by this instant (2**61 fs, 2,305.843 s), with room to spare for the arithmetic on
#: an instant; a run stopped there says so (:attr:`ChipPlan.budget_reason` ``time_limit``).
MAX_RUN_FS = 1 << 61


def frame_budget(cfg: ChipConfig, shape: tuple[int, int], freqs: dict[str, float],
                 nna_ii: int, sva_ii: int, frames: int = 1, dram: DramPlan | None = None
                 ) -> dict[str, int]:
    """The cycles each domain may run: ``sim.max_cycles`` for every domain when set, else a
    generous budget of :data:`~core.config.AUTO_BUDGET_FACTOR` times the expected run
    (:func:`expected_frame_s` a frame); either at most the cycles of :data:`MAX_RUN_FS`."""
    cap = {name: MAX_RUN_FS // period_fs(f) for name, f in freqs.items()}
    if cfg.sim.max_cycles:
        return {name: min(cfg.sim.max_cycles, cap[name]) for name in freqs}
    frame_s = expected_frame_s(cfg, shape, freqs, nna_ii, sva_ii, frames, dram)
    return {name: min(int(min(AUTO_BUDGET_FACTOR * frames * frame_s * f, cap[name])) + 100_000,
                      cap[name]) for name, f in freqs.items()}


def expected_frame_s(cfg: ChipConfig, shape: tuple[int, int], freqs: dict[str, float],
                     nna_ii: int, sva_ii: int, frames: int = 1, dram: DramPlan | None = None
                     ) -> float:
    """The seconds of chip time the automatic budget expects a frame of a run of ``frames``
    to take (a little more: 16 rows more): the frame at the slowest block's rate. Through the
    DRAM channel a memory source reads no faster than its read slots give, nor than its
    prefetch window per round trip (``read_prefetch_bursts`` bursts per access latency), and
    every frame's first burst waits the channel's longest wait."""
    h, w = shape
    camera = cfg.source.kind == "camera"
    per_pixel_s = max(
        nna_ii / freqs["nna"],
        sva_ii / freqs["sva"],
        (w + cfg.source.camera_hblank) / w / freqs["camera"] if camera else 0.0,
        dram.round_fs / dram.read_pixels / 1e15 if dram is not None else 0.0,
        (dram.longest_wait_fs / (dram.prefetch * dram.read_pixels) / 1e15
         if dram is not None else 0.0),
    )
    frame_s = (h + 16) * w * per_pixel_s + 1e-6
    if dram is not None:
        frame_s += dram.longest_wait_fs / 1e15
    if camera and frames > 1:  # the vertical blanking between frames
        frame_s += cfg.source.camera_vblank * (w + cfg.source.camera_hblank) / freqs["camera"]
    return frame_s


# ---- buffers -----------------------------------------------------------------------------------


def nna_buffers(spec: NnaSpec, layers: tuple[LayerPlan, ...]) -> tuple[BufferPlan, ...]:
    """SRAM of one NNA submodule: its layers' line buffers (:func:`~sim.cycle.stages.
    nna_layers`), the hybrid's census rows beside a network of several layers
    (:func:`~nna.geometry.census_rows`, of layer 0's input width) and the network's weights."""
    out = [lay.buffer for lay in layers]
    rows = census_rows(spec)
    if rows:
        width = layers[0].buffer.bits // (layers[0].rows * 8)
        r_c = spec.cfg.census.window[1] // 2
        out.append(BufferPlan("nna.census_rows", rows * width * 8,
                              f"{rows} input rows x {width} pixels x 8 bits the census unit "
                              "reads beside the layers (a bank per row: per descriptor the "
                              f"census window's next column, {2 * r_c + 1} reads; per pixel 1 "
                              "write)", rows=rows, banks=rows, word_bits=8,
                              pixel_reads=2 * r_c + 1, pixel_writes=1))
    cnn = spec.cnn
    if cnn is not None:
        shapes = " + ".join(f"{w.shape[2]}x{w.shape[3]}x{w.shape[1]}x{w.shape[0]}"
                            for w in cnn.weights)
        outs = sum(w.shape[0] for w in cnn.weights)
        requant = sum(int(m.size) for m in cnn.mult)
        out.append(BufferPlan("nna.weights", 8 * sum(spec.layer_macs) + 32 * outs
                              + 2 * cnn.z_bits * requant,
                              f"{shapes} int8 weights, {outs} int32 biases and {requant} "
                              f"multiply-shift pairs of {cnn.z_bits} bits (loaded into the MAC "
                              "array's registers once: weight-stationary)"))
    return tuple(out)


# ---- building ----------------------------------------------------------------------------------


#: The frame size (H, W) a command assumes when neither the user nor the configuration gives
#: one: the paper's 720p.
DEFAULT_FRAME = (720, 1280)


def frame_size(cfg: ChipConfig) -> tuple[int, int]:
    """(H, W) of the frames ``cfg`` is built for: its camera's (``source.camera_width`` x
    ``camera_height``), else :data:`DEFAULT_FRAME`."""
    src = cfg.source
    return (src.camera_height, src.camera_width) if src.camera_width else DEFAULT_FRAME


def check_frame_size(source, shape: tuple[int, int]) -> None:
    """A chip built for a camera's frame size (``source.camera_width`` x ``camera_height``, a
    preset's resolution) takes frames of that size only: its blanking, clocks and submodule
    count were chosen for it. Raises :class:`InputError` for a pair of another size."""
    h, w = shape
    if source.camera_width and (w, h) != (source.camera_width, source.camera_height):
        raise InputError(
            f"the frames are {w}x{h} but the chip is built for the camera's "
            f"{source.camera_width}x{source.camera_height} (source.camera_width x "
            f"camera_height): give frames of that size, or --set source.camera_width=0 --set "
            "source.camera_height=0 to build it for these")


def sva_block(cfg: ChipConfig, stages, shape: tuple[int, int], n: int, to_sink,
              parts: int) -> BlockPlan:
    """The SVA's block: its ``stages`` (:func:`~sim.cycle.stages.sva_stages`) on frames of
    ``shape``, ``n`` words a frame into ``to_sink``, a descriptor of ``parts`` parts."""
    h, w = shape
    band = band_rows(cfg.sva, h) if parts > 1 and cfg.sva.weight_mode == "auto" else 0
    return BlockPlan("sva", "sva", "sva", None, ("nna_left_to_sva", "nna_right_to_sva"),
                     (to_sink,), "top.sva", n, ii=pipeline_ii(stages),
                     latency=pipeline_latency(stages), lookahead=box_radius(cfg.sva),
                     passes=cfg.sva.box_size - 1, skew=median_radius(cfg.sva) * (w + 1),
                     flush_ii=flush_ii(stages), slot_ii=slot_ii(stages),
                     first_row=sva_first_slot_row(band, h),
                     buffers=tuple(b for st in stages for b in st.buffers), stages=stages)


def build_plan(chip: ChipSpec | ChipConfig, shape: tuple[int, int], frames: int = 1
               ) -> ChipPlan:
    """The plan of ``chip`` for a stream of ``frames`` frames of ``shape`` = (H, W), back to
    back -- per camera pair: with ``sva.pairs`` = P pairs sharing the chip the stream has P x
    ``frames`` camera frames, frame f pair f % P's (f // P)-th (``ChipPlan.frames``).
    ``chip``: the run's :class:`~sim.cycle.spec.ChipSpec` (resolved where it started), or a
    bare configuration, checked and resolved here once (:func:`~sim.cycle.spec.resolve_chip`).
    Raises ConfigError for a chip that cannot be built (a line buffer smaller than the
    descriptor window, more tiles than rows or columns, D not below the width) or a stream
    without frames."""
    spec = chip if isinstance(chip, ChipSpec) else resolve_chip(chip)
    cfg, nna = spec.cfg, spec.nna
    h, w = shape
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise ConfigError(f"a stream needs at least one frame, got frames={frames!r}")
    n = h * w
    check_frame_size(cfg.source, shape)
    check_line_buffer(nna)
    check_disparity_range(cfg.sva, w)
    parts = cfg.nna.stereo_submodules // 2
    tiles = tuple(split_frame(shape, parts, cfg.nna.split, nna))
    camera = cfg.source.kind == "camera"
    buffered = camera and cfg.source.frame_buffers > 0
    src_dom = "camera" if camera and not buffered else "nna"
    freqs = {"nna": cfg.clocks.nna_mhz * 1e6, "sva": cfg.clocks.sva_mhz * 1e6}
    if camera:
        freqs["camera"] = cfg.clocks.camera_mhz * 1e6
    domains = {name: DomainPlan(name, f, period_fs(f)) for name, f in freqs.items()}
    bits, word_bits = nna.bits, spec.sva.word_bits
    # the left pixel rides with its descriptor where the SVA reads it: the adaptive P2, the
    # hybrid's noise statistic (sva.noise)
    auto = len(nna.parts) > 1 and cfg.sva.weight_mode == "auto"
    beat_bits = bits + (8 if cfg.sva.p2_adaptive or auto else 0)
    nna_ii = cycles_per_descriptor(nna)
    half = half_window(nna)
    f = cfg.fifo
    fifos: list[FifoPlan] = []
    blocks: list[BlockPlan] = []

    def fifo(name, key, depth, width, producer, consumer, src, dst, beats):
        fifos.append(FifoPlan(name, key, depth, width, producer, consumer, src, dst,
                              f.latency_cycles, f.sync_cycles, beats))
        return name

    tile_layers = [layer_tiles(t, nna, shape) for t in tiles]
    widths = tuple(max(lt[i].in_shape[1] for lt in tile_layers)
                   for i in range(len(tile_layers[0])))
    layers = [nna_layers(nna, t, shape, widths) for t in tiles]
    buffers = [nna_buffers(nna, lays) for lays in layers]
    for s, side in enumerate(SIDES):
        src = f"camera_{side}" if camera and not buffered else f"memory_{side}"
        subs = [f"nna_{side}" if parts == 1 else f"nna_{side}{t}" for t in range(parts)]
        merge = f"merge_{side}"
        to_sva = fifo(f"nna_{side}_to_sva", "fifo.nna_to_sva_depth", f.nna_to_sva_depth,
                      beat_bits, merge if parts > 1 else subs[0], "sva", "nna", "sva", n)
        src_fifos = [fifo(f"src_{side}_to_nna" + (f"{t}" if parts > 1 else ""),
                          "fifo.source_to_nna_depth", f.source_to_nna_depth, 8, src, subs[t],
                          src_dom, "nna", tiles[t].in_shape[0] * tiles[t].in_shape[1])
                     for t in range(parts)]
        if parts == 1:
            sub_outs = [to_sva]
        else:
            sub_outs = [fifo(f"nna_{side}{t}_to_merge", "fifo.nna_to_merge_depth",
                             f.nna_to_merge_depth, beat_bits, subs[t], merge, "nna", "nna",
                             tiles[t].shape[0] * tiles[t].shape[1]) for t in range(parts)]
        line = w + cfg.source.camera_hblank
        raster = {"line_clocks": line, "frame_clocks": (h + cfg.source.camera_vblank) * line}
        if camera and not buffered:
            blocks.append(BlockPlan(src, "camera", src_dom, s, (), tuple(src_fifos),
                                    f"top.{src}", n, **raster))
        else:
            if buffered:  # the camera writes its frames into DRAM, the memory source reads them
                cam = f"camera_{side}"
                blocks.append(BlockPlan(cam, "camera", "camera", s, (), (), f"top.{cam}", n,
                                        **raster))
            blocks.append(BlockPlan(src, "memory", src_dom, s, (), tuple(src_fifos),
                                    f"top.{src}", n,
                                    bytes_per_s=round(cfg.source.memory_gbps * 1e9),
                                    feed=f"camera_{side}" if buffered else "",
                                    frame_buffers=cfg.source.frame_buffers,
                                    **(raster if buffered else {})))
        for t, tile in enumerate(tiles):
            blocks.append(BlockPlan(
                subs[t], "nna", "nna", s, (src_fifos[t],), (sub_outs[t],),
                f"top.nna.{side}.sub{t}", tile.shape[0] * tile.shape[1], ii=nna_ii,
                tile=tile, half=half, rows=cfg.nna.line_buffer_rows,
                buffers=buffers[t], stages=nna_stages(nna, layers[t]),
                layers=layers[t]))
        if parts > 1:
            blocks.append(BlockPlan(merge, "merge", "nna", s, tuple(sub_outs), (to_sva,),
                                    f"top.nna.{side}.merge", n))
    to_sink = fifo("sva_to_sink", "fifo.sva_to_sink_depth", f.sva_to_sink_depth, word_bits,
                   "sva", "sink", "sva", "sva", n)
    stages = sva_stages(cfg, w, spec.sva.parts, word_bits, spec.sva.cost_max)
    sva_ii = pipeline_ii(stages)
    blocks.append(sva_block(cfg, stages, (h, w), n, to_sink, len(nna.parts)))
    blocks.append(BlockPlan("sink", "sink", "sva", None, (to_sink,), (), "top.sink", n))
    lent = lent_plan(cfg, buffers[0], cfg.nna.line_buffer_rows - 2 * nna.halves[0] - 1)
    dram = None
    if cfg.dram.model == "tdm":
        dram = dram_plan(cfg, not (camera and not buffered), buffered, beat_bits, word_bits,
                         bits, freqs.get("camera", 0.0), w / (w + cfg.source.camera_hblank),
                         lent.gbps if lent is not None else 0.0)
    plan = ChipPlan(spec=spec, shape=(h, w), domains=domains, fifos=tuple(fifos),
                    blocks=tuple(blocks), tiles=tiles,
                    budget=frame_budget(cfg, shape, freqs, nna_ii, sva_ii,
                                        frames * cfg.sva.pairs, dram),
                    beat_bits=beat_bits, frames=frames * cfg.sva.pairs, dram=dram, lent=lent)
    object.__setattr__(plan, "signals", tuple(_signals(plan)))
    return plan


def _signals(plan: ChipPlan) -> list[SignalPlan]:
    """The traced signals, blocks in plan order then FIFOs (docs/traces.md says what each
    holds). Status codes: 0 idle, 1 busy, 2 starved, 3 blocked."""
    h, w = plan.shape
    out: list[SignalPlan] = []

    def sig(block_or_fifo, scope, key, width, domain):
        out.append(SignalPlan(f"{scope}.{key}", width, domain, block_or_fifo, key))

    for b in plan.blocks:
        d = b.domain
        sig(b.name, b.scope, "status", 2, d)
        if b.kind in ("memory", "camera"):
            sig(b.name, b.scope, "sent", _nb(plan.frames * h * w), d)
        elif b.kind == "nna":
            for lay in b.layers:  # one layer: no prefix, no status of its own
                pre = "" if len(b.layers) == 1 else f"layer{lay.index}."
                if pre:
                    sig(b.name, b.scope, f"{pre}status", 2, d)
                sig(b.name, b.scope, f"{pre}line_buffer.row_in", _nb(h), d)
                sig(b.name, b.scope, f"{pre}line_buffer.fill", _nb(lay.rows), d)
                sig(b.name, b.scope, f"{pre}mac.phase", _nb(lay.ii), d)
                sig(b.name, b.scope, f"{pre}mac.row", _nb(h), d)
                sig(b.name, b.scope, f"{pre}mac.col", _nb(w), d)
            sig(b.name, b.scope, "out.valid", 1, d)
            sig(b.name, b.scope, "out.descriptor", plan.descriptor_bits, d)
        elif b.kind == "merge":
            sig(b.name, b.scope, "count", _nb(plan.frames * h * w), d)
            sig(b.name, b.scope, "out.valid", 1, d)
        elif b.kind == "sva":
            for key, width in (("input.row", _nb(h)), ("input.col", _nb(w)),
                               ("input.rows_ready", _nb(h)), ("output.row", _nb(h)),
                               ("output.col", _nb(w)), ("output.valid", 1),
                               ("output.disparity", plan.word_bits), ("lr_check.reject", 1),
                               ("pipeline.issue", 1), ("pipeline.stall", 1),
                               ("pipeline.words", _nb(b.skew + 1 - (-b.latency // b.ii)))):
                sig(b.name, b.scope, key, width, d)
            for st in b.stages:
                sig(b.name, b.scope, f"stage.{st.name}.status", 2, d)
                sig(b.name, b.scope, f"stage.{st.name}.words", _nb(st.slots), d)
        elif b.kind == "sink":
            sig(b.name, b.scope, "count", _nb(plan.frames * h * w), d)
            sig(b.name, b.scope, "valid", 1, d)
    for f in plan.fifos:
        scope = f"top.fifo.{f.name}"
        sig(f.name, scope, "occupancy", _nb(f.depth), f.dst)
        sig(f.name, scope, "push", 1, f.src)
        sig(f.name, scope, "pop", 1, f.dst)
        sig(f.name, scope, "full", 1, f.src)
        sig(f.name, scope, "empty", 1, f.dst)
    return out
