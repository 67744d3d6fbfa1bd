"""The SVA's micro-architecture: its pipeline of stages, each with a latency, an initiation
interval (II) and buffers sized in bits, derived from the configuration.

Every stage evaluates ``L = sva.lanes`` disparities per cycle, so one pixel's D disparities take
``G = ceil(D / L)`` *lane groups* (cycles). Reductions (a popcount, the minimum over disparities,
the sum over paths, a sorting network) are trees of two-input operators, of which
``V = sva.compare_levels`` levels settle in one SVA cycle; a tree of depth ``t`` levels takes
``tree(t) = ceil(t / V)`` cycles (0 for ``t = 0``). ``lg(n) = ceil(log2 n)``.

The stages, in stream order (their docstrings give the formulas the tests check):

======================  =================================  ==================================
stage                   II (cycles per pixel)              latency (cycles)
======================  =================================  ==================================
row buffers' read       1                                  1
hamming cost            max(G, ports)                      G + tree(lg(bits)); hybrid:
                                                           G + tree(lg(max b_k) + 2)
box filter              max(G, ports)                      G + tree(2) + tree(lg(k) + 1)
SGM (per path)          max(left path's recurrence, ports) G + tree(5)
path sum                G                                  tree(lg(paths) + 1)
WTA / uniqueness / sub  G                                  G + tree(lg(L) + [G > 1]) + [uniq]
                                                           + sub
LR check (optional)     G                                  (D - 1) II + 1
median (optional)       max(1, ports)                      tree(depth of the sorting network)
output register         1                                  1
======================  =================================  ==================================

The box filter slides its column sums (an add and a subtract: tree(2)), then sums k of them
and caps the sum (tree(lg(k) + 1)). One lane's SGM step is five levels
(:data:`SGM_STEP_LEVELS`); the path sum adds the paths and caps at sum_bits (lg(paths) + 1);
WTA's minimum is a tree over a group's L lanes and, G > 1, one level folding it into the
earlier groups'. These are the levels of the RTL twin's stages (``sva/rtl/``, docs/rtl.md),
which first showed that the plan's earlier G + 2, tree(lg(paths)) and tree(lg(D)) were right
only for V >= 4 or 5.

The SVA's II is the largest stage II. The left-to-right SGM path carries a dependency from one
pixel to the next: pixel p's first lane group needs ``min_d L(p - 1, d)``, the minimum over all
D of the previous pixel's path costs. Its last group leaves the step tree(5) cycles after it
entered (G - 1 after the first), and the minimum is complete ``tree(lg(L) + [G > 1])`` cycles
later (the lanes' minimum, then one level to fold in the running minimum of the earlier
groups). So this path cannot overlap two pixels, and its II is ``G - 1 + tree(5) + tree(lg(L)
+ [G > 1])``. The other paths read the previous *row* and overlap freely.

The defaults (D = 128, L = 128, V = 8) give G = 1 and II = 0 + tree(5) + tree(7) = 2: the
paper's "one disparity every two clock ticks", 1280 x 720 x 2 / 465 MHz = 3.964 ms per frame,
252.3 fps.

SRAM ports (``sva.sram_ports``): every SRAM bank declares its reads and writes per pixel
(:class:`BufferPlan`) -- a median-row bank per row 1 and 1, the column sums and each top SGM
path's previous-row bank G and G (one lane group per access); the descriptor rows are a bank per
row and view, each either the arriving row's (written) or a row a slot reads (the rows entering
and leaving the column sums are two banks): one access a bank, whatever the ports.
With ``1r1w`` banks (a read and a write port) a stage needs max(reads, writes) cycles per pixel
for them, with ``1rw`` (one shared port) reads + writes; a stage's II is the larger of its
compute II and its banks' port cycles, so a single-port SRAM shows its cost: at the defaults
none (the left path's recurrence already leaves the second cycle), with 64 lanes at D = 128 the
SGM's II goes from 3 to 2 G = 4.

The SVA's latency L (a word issued -> it reaches the output register) is the sum of the stage
latencies. Words are the emitting *slots* of the SVA's sequencer (:func:`~sim.cycle.rules.
sva_slot`): a frame's k - 1 passes seed the box filter's column sums, and each box row is W + r
slots, the first r filling the box's row window; every slot passes the row read, the matching
cost and the box filter, one slot II apart (:func:`slot_ii`), the words one II apart. With the
median a word leaves with the word m W + m after it (:func:`~sim.cycle.rules.sva_exit_item`).
The LR check computes the right view's disparities from the same aggregated volume: the right
pixel ``x_r`` takes the best of ``S(x_r + d, d)`` over d, a diagonal through the next D left
pixels. So a left pixel's check waits until the D - 1 pixels after it have been aggregated:
(D - 1) IIs. Its buffers hold the running minimum of D right pixels and the D left words that
wait for them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from stereosim.core.config import ChipConfig
from stereosim.nna.descriptor import network
from stereosim.nna.geometry import (
    Tile,
    census_rows,
    layer_cycles,
    layer_halves,
    layer_macs_per_pixel,
    layer_rows,
    layer_tiles,
    line_buffer_bits,
    mac_shares,
)
from stereosim.sva.geometry import bits_for, disparity_bits
from stereosim.sva.noise import noise_unit_bits


@dataclass(frozen=True)
class BufferPlan:
    """A storage of a block or stage: ``bits`` of SRAM, what it holds; ``rows`` > 0: a window
    of that many image rows whose fill both engines track (:mod:`sim.cycle.buffers`).

    SRAM ports: ``reads`` and ``writes`` per pixel of each bank (one word per access: a lane
    group of D-indexed buffers), through ``ports`` = ``"1r1w"`` (a read and a write port:
    max(reads, writes) cycles per pixel) or ``"1rw"`` (one shared port: reads + writes); ``""``
    for registers, which every cycle can read and write.

    Energy (:mod:`sim.cycle.energy`): ``banks`` arrays of bits / banks each; per output pixel
    ``pixel_reads`` and ``pixel_writes`` accesses of ``word_bits`` bits over all of them (0 for
    registers, whose energy is the logic's)."""

    name: str
    bits: int
    holds: str
    rows: int = 0
    reads: int = 0
    writes: int = 0
    ports: str = ""
    banks: int = 1
    word_bits: int = 0
    pixel_reads: int = 0
    pixel_writes: int = 0

    @property
    def port_cycles(self) -> int:
        """Cycles per pixel this buffer's ports need (0: not port-limited)."""
        if self.ports == "1rw":
            return self.reads + self.writes
        if self.ports == "1r1w":
            return max(self.reads, self.writes)
        return 0


@dataclass(frozen=True)
class StagePlan:
    """A stage of the SVA pipeline: ``ii`` cycles per pixel, ``latency`` cycles from a pixel
    entering it to leaving it, ``formula`` the arithmetic behind both (shown in reports).

    Its pipeline registers (its delay line) hold ``slots`` words of ``slot_bits`` bits each:
    ceil(latency / ii) -- a stage fed at its own II holds no more words than that -- or, for
    the LR check, the D words of its window. Both engines track how many words each stage holds
    (:mod:`sim.cycle.buffers` checks the peak against ``slots``)."""

    name: str
    ii: int
    latency: int
    formula: str
    buffers: tuple[BufferPlan, ...] = ()
    slots: int = 0
    slot_bits: int = 0
    holds: str = ""

    @property
    def register_bits(self) -> int:
        return self.slots * self.slot_bits


def lg(n: int) -> int:
    """ceil(log2 n) for n >= 1: the depth of a tree of two-input operators over n inputs."""
    return max(0, math.ceil(math.log2(n))) if n > 1 else 0


def tree_cycles(levels: int, per_cycle: int) -> int:
    """Cycles of a tree of ``levels`` levels when ``per_cycle`` levels settle in one cycle."""
    return -(-levels // per_cycle) if levels > 0 else 0


def lane_groups(cfg: ChipConfig) -> int:
    """G = ceil(D / lanes): the cycles one pixel's disparities take through a stage."""
    s = cfg.sva
    return -(-s.disparities // min(s.lanes, s.disparities))


def sorting_depth(n: int) -> int:
    """Levels of Batcher's odd-even merge sort over n inputs: k (k + 1) / 2 with k = lg(n)."""
    k = lg(n)
    return k * (k + 1) // 2


# Levels of one lane's SGM step (sva.sgm): L(p-1, d) - m beside the min of its neighbours
# L(p-1, d -+ 1); + P1 beside min(P2 path); the min of the candidates; + the aggregated cost;
# the cap at path_bits. The RTL twin (sva/rtl/sva_sgm.sv) builds them so.
SGM_STEP_LEVELS = 5


def left_path_ii(cfg: ChipConfig) -> int:
    """II of the left-to-right SGM path: G - 1 + tree(5) + tree(lg(L) + [G > 1]). A pixel's
    last lane group leaves the step's five levels (:data:`SGM_STEP_LEVELS`) tree(5) cycles
    after it entered, G - 1 after the first; then the min over the pixel's D costs (its lanes'
    tree and, G > 1, one level folding in the earlier groups') must be complete before the
    next pixel's first group enters."""
    s = cfg.sva
    g = lane_groups(cfg)
    lanes = min(s.lanes, s.disparities)
    v = s.compare_levels
    return g - 1 + tree_cycles(SGM_STEP_LEVELS, v) + tree_cycles(
        lg(lanes) + (1 if g > 1 else 0), v)


def hamming_levels(parts: tuple[int, ...]) -> int:
    """Adder levels of the matching cost of a descriptor of ``parts`` (each part's bits): one
    part, its popcount tree lg(b); two (the hybrid), their popcount trees side by side, then
    each weighted (w in 0..3: the distance plus itself shifted, one level) and the two added
    (one level): lg(max b_k) + 2."""
    if len(parts) == 1:
        return lg(parts[0])
    return lg(max(parts)) + 2


def noise_buffers(cfg: ChipConfig, width: int) -> list[BufferPlan]:
    """The noise unit of the hybrid's automatic weights (:mod:`sva.noise`): the two rows of
    left pixels above the arriving one that its 3x3 window reads (written once per pixel of
    the band, each read once), and its registers -- S, N and the product T N, the two weight
    sets and the threshold and gradient registers."""
    regs = noise_unit_bits(cfg.sva, width)
    return [
        BufferPlan("sva.noise_rows", 2 * width * 8,
                   f"the two rows of left pixels above the arriving one, 2 x {width} x 8 bits "
                   "(the noise statistic's 3x3 window; only the frame's first rows)",
                   rows=0, reads=0, writes=0, banks=2, word_bits=8),
        BufferPlan("sva.noise_registers", regs + 2 * 2 * 2 + 2 * 10,
                   f"S, N and T N ({regs} bits), the two weight sets (2 x 2 x 2 bits), the "
                   "threshold and the gradient (10 bits each)"),
    ]


def hamming_stage(cfg: ChipConfig, width: int, parts: tuple[int, ...]) -> StagePlan:
    """The SVA's first stage for frames ``width`` pixels wide and descriptors of ``parts``:
    the descriptor rows it reads (both views, k + 2 rows each), the right window, the hybrid's
    noise unit with automatic weights, its II and its latency (the module docstring)."""
    s = cfg.sva
    d, v, g, ports = s.disparities, s.compare_levels, lane_groups(cfg), s.sram_ports
    lanes = min(s.lanes, d)
    bits, levels = sum(parts), hamming_levels(parts)
    # a bank per row and view: the arriving row's bank is only written (a slot reads complete
    # rows), and a slot's reads (the row entering the column sums, the row leaving them) are
    # in different banks -- each bank does one access a slot, so one port serves it
    rows_buf = BufferPlan("sva.descriptor_rows", 2 * (s.box_size + 2) * width * bits,
                          "both views' descriptor rows the box filter slides over (k + 2 "
                          "each: rows y - 1 - r .. y + r, the one leaving the column sums "
                          "included, and the row arriving; a bank per row and view, each "
                          "read or written, never both, in a slot)",
                          rows=s.box_size + 2, reads=1, writes=0, ports=ports,
                          banks=2 * (s.box_size + 2), word_bits=bits, pixel_reads=2,
                          pixel_writes=2)
    ii = max(g, rows_buf.port_cycles)
    bufs = [rows_buf, BufferPlan("sva.right_window", d * bits,
                                 "the right descriptors x - D + 1 .. x (registers)")]
    if len(parts) > 1 and s.weight_mode == "auto":
        bufs += noise_buffers(cfg, width)
    tree = (f"lg({bits})" if len(parts) == 1 else
            f"lg(max({parts[0]}, {parts[1]})) + 2: two popcounts, weighted, added")
    return StagePlan(
        "hamming", ii, g + tree_cycles(levels, v),
        f"II = max(G = ceil({d}/{lanes}) = {g}, descriptor rows' ports {ports}: "
        f"{rows_buf.port_cycles}) = {ii}; latency = G + tree({tree}) = {g} + "
        f"{tree_cycles(levels, v)}", tuple(bufs))


def sva_stages(cfg: ChipConfig, width: int, parts: tuple[int, ...], word_bits: int,
               cost_max: int) -> tuple[StagePlan, ...]:
    """The SVA's stages for frames ``width`` pixels wide, descriptors of ``parts`` (each
    part's bits), a largest matching cost of ``cost_max`` (:func:`~core.config.widths.
    largest_cost`) and ``word_bits``-bit output words, in stream order (see the module
    docstring)."""
    s = cfg.sva
    d = s.disparities
    v = s.compare_levels
    g = lane_groups(cfg)
    lanes = min(s.lanes, d)
    d_bits = disparity_bits(s)
    ports = s.sram_ports
    sums_buf = BufferPlan("sva.column_sums", width * d * bits_for(s.box_size * cost_max),
                          "the vertical box sums, W x D (a lane group read and written per "
                          "group)", reads=g, writes=g, ports=ports,
                          word_bits=lanes * bits_for(s.box_size * cost_max), pixel_reads=g,
                          pixel_writes=g)
    top = 1 if s.paths > 1 else 0
    sgm_buf = BufferPlan("sva.sgm_previous_row", (s.paths - 1) * width * d * s.path_bits
                         + d * s.path_bits,
                         "the top paths' previous row (a bank per path, a lane group read and "
                         "written per group) and the left path's previous pixel",
                         reads=g * top, writes=g * top, ports=ports if top else "",
                         banks=max(1, s.paths - 1), word_bits=lanes * s.path_bits,
                         pixel_reads=g * (s.paths - 1), pixel_writes=g * (s.paths - 1))
    box_ii = max(g, sums_buf.port_cycles)
    slide, row_sum = tree_cycles(2, v), tree_cycles(lg(s.box_size) + 1, v)
    stages = [
        StagePlan("row_read", 1, 1, "II = 1; latency = 1 (the row buffers' read register: a "
                  "slot's descriptors and the right window's new column)"),
        hamming_stage(cfg, width, parts),
        StagePlan(
            "box_filter", box_ii, g + slide + row_sum,
            f"II = max(G = {g}, column sums' ports {ports}: {sums_buf.port_cycles}) = "
            f"{box_ii}; latency = G + tree(2: the column sum's add and subtract) + "
            f"tree(lg({s.box_size}) + 1: the row sum, its cap) = {g} + {slide} + {row_sum}",
            (sums_buf,),
        ),
    ]
    left_ii = left_path_ii(cfg)
    step = tree_cycles(SGM_STEP_LEVELS, v)
    sgm_ii = max(left_ii, sgm_buf.port_cycles)
    stages.append(StagePlan(
        "sgm", sgm_ii, g + step,
        f"{s.paths} path unit(s); II = max(left path G - 1 + tree({SGM_STEP_LEVELS}) + "
        f"tree(lg({lanes}) + [G > 1]) = {left_ii} (the step, then the min over the pixel's D "
        f"costs), previous row's ports {ports}: {sgm_buf.port_cycles}) = {sgm_ii}; latency = "
        f"G + tree({SGM_STEP_LEVELS} levels of the step) = {g} + {step}",
        (sgm_buf,),
    ))
    sum_tree = tree_cycles(lg(s.paths) + 1, v)
    stages.append(StagePlan(
        "path_sum", g, sum_tree,
        f"II = G = {g}; latency = tree(lg({s.paths} paths) + 1: the adds, the cap at sum_bits) "
        f"= {sum_tree}"))
    sub = 0 if s.subpixel == "off" else s.subpixel_bits + 1
    uniq = 1 if s.uniqueness else 0
    wta_tree = tree_cycles(lg(lanes) + (1 if g > 1 else 0), v)
    stages.append(StagePlan(
        "wta", g, g + wta_tree + uniq + sub,
        f"II = G = {g}; latency = G + tree(lg({lanes}) + [G > 1]: the lanes' min, the fold "
        f"into the earlier groups') + uniqueness {uniq} + sub-pixel ({s.subpixel}: F + 1 = "
        f"{sub}) = {g + wta_tree + uniq + sub}"))
    med_buf = BufferPlan("sva.median_rows", s.median * width * word_bits,
                         "the median's output rows (a bank per row: its column read, the new "
                         "word written)", reads=1, writes=1, ports=ports,
                         banks=max(1, s.median), word_bits=word_bits,
                         pixel_reads=s.median if s.median > 1 else 0,
                         pixel_writes=1 if s.median > 1 else 0)
    med_ii = max(1, med_buf.port_cycles)
    ii = max([st.ii for st in stages] + ([med_ii] if s.median > 1 else []))  # the pipeline's
    if s.lr_check:
        stages.append(StagePlan(
            "lr_check", g, (d - 1) * ii + 1,
            f"II = G = {g}; latency = (D - 1) x II + 1 = {d - 1} x {ii} + 1 (the diagonal "
            "through the next D - 1 pixels)",
            (BufferPlan("sva.lr_window", d * (s.sum_bits + d_bits) + d * word_bits,
                        "the running best (cost, d) of D right pixels and the D left words "
                        "waiting for them (registers: shifted one pixel per II)"),),
        ))
    if s.median > 1:
        depth = sorting_depth(s.median * s.median)
        stages.append(StagePlan(
            "median", med_ii, tree_cycles(depth, v),
            f"II = max(1, median rows' ports {ports}: {med_buf.port_cycles}) = {med_ii}; "
            f"latency = tree({depth} levels of a {s.median}x{s.median} sorting network) = "
            f"{tree_cycles(depth, v)}",
            (med_buf,),
        ))
    stages.append(StagePlan("output", 1, 1, "II = 1; latency = 1 (the output register)"))
    # each stage's pipeline registers: the words in flight in it, and what one of them carries
    cost_bits = bits_for(cost_max)
    box_bits = bits_for(s.box_size * s.box_size * cost_max)
    carried = {
        "row_read": (2 * sum(parts), f"a slot's two left descriptors of {sum(parts)} bits "
                     "(the rows entering and leaving the box)"),
        "hamming": (d * cost_bits, f"D = {d} {'Hamming' if len(parts) == 1 else 'weighted'} "
                    f"costs of {cost_bits} bits"),
        "box_filter": (d * box_bits, f"D = {d} box sums of {box_bits} bits"),
        "sgm": (s.paths * d * s.path_bits,
                f"{s.paths} path(s) x D = {d} path costs of {s.path_bits} bits"),
        "path_sum": (d * s.sum_bits, f"D = {d} sums S of {s.sum_bits} bits"),
        "wta": (word_bits + s.sum_bits, f"the {word_bits}-bit word and its {s.sum_bits}-bit "
                "cost"),
        "lr_check": (s.sum_bits + d_bits + word_bits, "per pixel of its window: a right "
                     "pixel's running best (cost, d) and a left word waiting"),
        "median": (word_bits, f"the {word_bits}-bit word"),
        "output": (word_bits, f"the {word_bits}-bit word"),
    }
    return tuple(with_slots(st, *carried[st.name], slots=d if st.name == "lr_check" else -1)
                 for st in stages)


@dataclass(frozen=True)
class LayerPlan:
    """One layer's stage of an NNA submodule (:mod:`nna.geometry` gives its rules): ``tile``
    its regions (output [x0, x1) x [y0, y1), input in_*), ``half`` its half kernel h_l,
    ``rows`` its line buffer's rows, ``macs`` its MAC share of ``macs_per_pixel`` = m_l MACs
    an output pixel, ``cycles`` = cpp_l per output pixel, ``channels_in`` / ``channels_out``,
    ``buffer`` its line buffer (rows x its widest input region x C_in x 8 bits)."""

    index: int
    tile: Tile
    half: int
    rows: int
    macs: int
    macs_per_pixel: int
    cycles: int
    channels_in: int
    channels_out: int
    buffer: BufferPlan

    @property
    def items(self) -> int:
        """Output pixels of its region per frame."""
        return self.tile.shape[0] * self.tile.shape[1]


def nna_layers(cfg: ChipConfig, tile: Tile, shape: tuple[int, int], widths: tuple[int, ...]
               ) -> tuple[LayerPlan, ...]:
    """The layer stages of a submodule serving ``tile`` of a frame of ``shape``, each line
    buffer sized for ``widths[l]``, the widest input region of layer l over the camera's
    tiles. A bank per row: per output pixel the window's next column is read, one word of C_in
    activations (8 bits each; layer 0: the pixel) from each of its 2 h_l + 1 rows' banks, and
    per input pixel one word is written. One layer: the buffer ``nna.line_buffer``, else
    ``nna.layer<l>.line_buffer``."""
    n = cfg.nna
    halves = layer_halves(n)
    if n.descriptor == "census":
        channels = [(1, 1)]
    else:
        channels = [(int(w.shape[1]), int(w.shape[0])) for w in network(n).weights]
    single = len(halves) == 1
    out = []
    for i, (t, h, rows, share, m, cpp, (c_in, c_out)) in enumerate(zip(
            layer_tiles(tile, n, shape), halves, layer_rows(n), mac_shares(n),
            layer_macs_per_pixel(n), layer_cycles(n), channels, strict=True)):
        width = widths[i]
        what = ("pixels x 8 bits" if c_in == 1 else f"pixels x {c_in} channels x 8 bits")
        buf = BufferPlan("nna.line_buffer" if single else f"nna.layer{i}.line_buffer",
                         line_buffer_bits(rows, width, c_in),
                         f"{rows} input rows x {width} {what} (a bank per row: per "
                         f"{'descriptor' if single else 'output pixel'} the window's next "
                         "column read, one pixel from each of its rows' banks; per pixel one "
                         "written)",
                         rows=rows, banks=rows, word_bits=8 * c_in, pixel_reads=2 * h + 1,
                         pixel_writes=1)
        out.append(LayerPlan(i, t, h, rows, share, m, cpp, c_in, c_out, buf))
    return tuple(out)


def nna_stages(cfg: ChipConfig, layers: tuple[LayerPlan, ...]) -> tuple[StagePlan, ...]:
    """An NNA submodule's stages, per layer: its line buffer (a bank per row: each output pixel
    takes the next column of the layer's window, one word from each of its 2 h + 1 banks,
    while the arriving one is written), its MAC array (m_l multiply-accumulates an output
    pixel on its share of the MACs, cpp_l = ceil(m_l / share) cycles; the census unit: 1
    cycle) and its requantise stage (per channel a multiply-shift and the ReLU clamp; the last
    layer: the sign bit), in the MAC array's last cycle. One layer: ``line_buffer``,
    ``mac_array`` (or ``census_unit``), ``requantise_sign``; more: the same names prefixed
    ``layer<l>.``, the last layer's requantise stage named ``layer<l>.sign``."""
    n = cfg.nna
    single = len(layers) == 1
    out = []
    for lay in layers:
        pre = "" if single else f"layer{lay.index}."
        last = lay.index == len(layers) - 1
        window = 2 * lay.half + 1
        if n.descriptor == "census":
            mac = StagePlan("census_unit", 1, 1, "II = latency = 1 (one comparison per window "
                            "sample, all in one cycle)")
        else:
            m, cpp, share = lay.macs_per_pixel, lay.cycles, lay.macs
            mac = StagePlan(
                f"{pre}mac_array", cpp, cpp,
                f"II = latency = ceil({m} MACs / {share}) = {cpp}; {m / cpp:g} MACs per cycle, "
                f"{100 * m / (cpp * share):.1f} % of {'the array' if single else 'its MACs'} "
                "busy")
        out.append(StagePlan(f"{pre}line_buffer", 1, 0,
                             f"a bank per row: per {'descriptor' if single else 'output pixel'}"
                             f" {window} reads (one per bank: the window's next column) and per "
                             "pixel 1 write"))
        out.append(mac)
        if single:
            out.append(StagePlan("requantise_sign", 1, 0, "per channel a multiply-shift and the "
                                 "sign bit, in the MAC array's last cycle"))
        elif last:
            out.append(StagePlan(f"{pre}sign", 1, 0, "per channel the sign bit of the "
                                 "accumulator, in the MAC array's last cycle"))
        else:
            out.append(StagePlan(f"{pre}requantise", 1, 0, "per channel a multiply-shift and "
                                 "the clamp to 0..127, in the MAC array's last cycle"))
    if n.descriptor == "hybrid":
        c = n.census
        source = ("layer 0's line buffer" if single else
                  f"its own {census_rows(n)} input rows (nna.census_rows)")
        out.append(StagePlan("census_unit", 1, 0,
                             f"the {c.window[0]}x{c.window[1]} {c.kind} census of the output "
                             f"pixel from {source}, in the MAC array's last cycle: its bits "
                             "join the sign bits above them"))
    return tuple(out)


def with_slots(stage: StagePlan, slot_bits: int, holds: str, slots: int = -1) -> StagePlan:
    """``stage`` with its pipeline registers: ``slots`` words (default ceil(latency / II))
    of ``slot_bits`` bits."""
    if slots < 0:
        slots = -(-stage.latency // stage.ii) if stage.latency > 0 else 0
    return dataclasses.replace(stage, slots=slots, slot_bits=slot_bits, holds=holds)


def stage_offsets(stages: tuple[StagePlan, ...]) -> tuple[int, ...]:
    """Each stage's offset in the pipeline: the latencies of the stages before it. Word j,
    issued at tick t, is in stage s while offset_s < tick - t <= offset_s + latency_s."""
    out = []
    total = 0
    for st in stages:
        out.append(total)
        total += st.latency
    return tuple(out)


def pipeline_ii(stages: tuple[StagePlan, ...]) -> int:
    """The SVA's initiation interval: its slowest stage's."""
    return max(st.ii for st in stages)


def slot_ii(stages: tuple[StagePlan, ...]) -> int:
    """The SVA sequencer's slot II a: every slot (a pass's, a row's first r, a word's) passes
    the row read, the matching cost and the box filter, so slots go the largest of their IIs
    apart (words: the pipeline's II, :func:`pipeline_ii`)."""
    return max(st.ii for st in stages if st.name in ("row_read", "hamming", "box_filter"))


def flush_ii(stages: tuple[StagePlan, ...]) -> int:
    """Ticks between the median's flush slots (after a frame's last word its S slots drain
    the window; :func:`~sim.cycle.rules.sva_exit_item`): the median's II -- 1, or 2 with
    single-port row banks (each flush slot reads them, then the next may) -- and 1 without
    the median."""
    return next((st.ii for st in stages if st.name == "median"), 1)


def pipeline_latency(stages: tuple[StagePlan, ...]) -> int:
    """The SVA's latency (an output row ready -> its first word): the stages' latencies."""
    return sum(st.latency for st in stages)
