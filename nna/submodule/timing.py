"""The NNA submodule's timing rule: its layers' stages -- each layer's line buffer (a bank per
row), its MAC array (m_l multiply-accumulates an output pixel on its share of the MACs: II_l =
ceil(m_l / share) cycles) and its requantise or sign stage -- as the RTL builds them
(nna_submodule.sv). The window and share arithmetic they read is :mod:`nna.geometry`'s; the chip
plan collects the stages (:mod:`sim.cycle.plan`)."""

from __future__ import annotations

from dataclasses import dataclass

from numba.extending import register_jitable

from stereosim.core.config import NnaConfig
from stereosim.core.timing import BufferPlan, StagePlan
from stereosim.nna.descriptor import NnaSpec, as_nna_spec
from stereosim.nna.geometry import (
    Tile,
    census_rows,
    layer_rows,
    layer_tiles,
    line_buffer_bits,
    mac_shares,
)


@dataclass(frozen=True)
class LayerPlan:
    """One layer's stage of an NNA submodule (:mod:`nna.geometry` gives its rules): ``tile``
    its regions (output [x0, x1) x [y0, y1), input in_*), ``half`` its half kernel h_l,
    ``rows`` its line buffer's rows, ``macs`` its MAC share of ``macs_per_pixel`` = m_l MACs
    an output pixel, ``cycles`` = II_l per output pixel, ``channels_in`` / ``channels_out``,
    ``buffer`` its line buffer (rows x its widest input region x C_in x 8 bits)."""

    index: int
    tile: Tile
    half: int
    rows: int
    macs: int
    macs_per_pixel: int
    ii: int
    channels_in: int
    channels_out: int
    buffer: BufferPlan

    @property
    def items(self) -> int:
        """Output pixels of its region per frame."""
        return self.tile.shape[0] * self.tile.shape[1]


def nna_layers(spec: NnaSpec, tile: Tile, shape: tuple[int, int], widths: tuple[int, ...]
               ) -> tuple[LayerPlan, ...]:
    """The layer stages of a submodule serving ``tile`` of a frame of ``shape``, each line
    buffer sized for ``widths[l]``, the widest input region of layer l over the camera's
    tiles. A bank per row: per output pixel the window's next column is read, one word of C_in
    activations (8 bits each; layer 0: the pixel) from each of its 2 h_l + 1 rows' banks, and
    per input pixel one word is written. One layer: the buffer ``nna.line_buffer``, else
    ``nna.layer<l>.line_buffer``."""
    halves = spec.halves
    if spec.cnn is None:
        channels = [(1, 1)]
    else:
        channels = [(int(w.shape[1]), int(w.shape[0])) for w in spec.cnn.weights]
    single = len(halves) == 1
    out = []
    for i, (t, h, rows, share, m, ii, (c_in, c_out)) in enumerate(zip(
            layer_tiles(tile, spec, shape), halves, layer_rows(spec), mac_shares(spec),
            spec.layer_macs, layer_cycles(spec), channels, strict=True)):
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
        out.append(LayerPlan(i, t, h, rows, share, m, ii, c_in, c_out, buf))
    return tuple(out)


def nna_stages(spec: NnaSpec, layers: tuple[LayerPlan, ...]) -> tuple[StagePlan, ...]:
    """An NNA submodule's stages, per layer: its line buffer (a bank per row: each output pixel
    takes the next column of the layer's window, one word from each of its 2 h + 1 banks,
    while the arriving one is written), its MAC array (m_l multiply-accumulates an output
    pixel on its share of the MACs, II_l = ceil(m_l / share) cycles; the census unit: 1
    cycle) and its requantise stage (per channel a multiply-shift and the ReLU clamp; the last
    layer: the sign bit), in the MAC array's last cycle. One layer: ``line_buffer``,
    ``mac_array`` (or ``census_unit``), ``requantise_sign``; more: the same names prefixed
    ``layer<l>.``, the last layer's requantise stage named ``layer<l>.sign``."""
    n = spec.cfg
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
            m, ii, share = lay.macs_per_pixel, lay.ii, lay.macs
            mac = StagePlan(
                f"{pre}mac_array", ii, ii,
                f"II = latency = ceil({m} MACs / {share}) = {ii}; {m / ii:g} MACs per cycle, "
                f"{100 * m / (ii * share):.1f} % of {'the array' if single else 'its MACs'} "
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
                  f"its own {census_rows(spec)} input rows (nna.census_rows)")
        out.append(StagePlan("census_unit", 1, 0,
                             f"the {c.window[0]}x{c.window[1]} {c.kind} census of the output "
                             f"pixel from {source}, in the MAC array's last cycle: its bits "
                             "join the sign bits above them"))
    return tuple(out)


# ---- the MAC array's timing rule ----------------------------------------------------------------
# An output pixel occupies its layer's MAC array from the cycle it starts (its input rows in, the
# previous output gone) to the cycle it may leave, both included: cycles_per_pixel of them. Both
# engines and the estimate read the plan's LayerPlan.cycles, and the compiled walkers and the
# estimate place the push with mac_done.


def cycles_per_descriptor(spec: NnaSpec | NnaConfig) -> int:
    """The submodule's initiation interval, cycles per descriptor: its slowest layer's cycles
    per output pixel, max_l II_l (:func:`layer_cycles`; one layer: ceil(K*K*C / macs)), 1 for
    the census unit."""
    return max(layer_cycles(spec))


def cycles_per_pixel(macs_per_pixel: int, share: int) -> int:
    """Cycles a layer's MAC array of ``share`` units spends on one output pixel of
    ``macs_per_pixel`` MACs: ceil(m_l / macs_l)."""
    return -(-macs_per_pixel // share)


def pipeline_cycles(items: tuple[int, ...], cycles: tuple[int, ...]) -> int:
    """Cycles of a frame of a layer pipeline whose layers run side by side: the busiest layer's
    output pixels x cycles per pixel, max_l items_l II_l."""
    return max(i * c for i, c in zip(items, cycles, strict=True))


def layer_cycles(spec: NnaSpec | NnaConfig) -> tuple[int, ...]:
    """Cycles each layer's MAC array spends on one output pixel: II_l = ceil(m_l / macs_l)
    (:func:`mac_shares`, :func:`cycles_per_pixel`); the census unit: 1. One layer:
    :func:`cycles_per_descriptor`."""
    spec = as_nna_spec(spec)
    if spec.cnn is None:
        return (1,)
    return tuple(cycles_per_pixel(m, share) for m, share in
                 zip(spec.layer_macs, mac_shares(spec), strict=True))


@register_jitable
def mac_done(start, cycles):
    """The MAC cycle in which the output started in cycle ``start`` is done and may leave (room
    permitting), on an array that spends ``cycles`` cycles an output
    (:func:`cycles_per_pixel`): start + cycles - 1. This is what an array's ``cycles`` mean
    (the readable MacArray counts them as its phase); the rule that sets them is
    :func:`cycles_per_pixel`."""
    return start + cycles - 1
