"""The network on the lent NNA submodules (``nna.lent_network``; docs/lent.md): the plan's lent
part, built once with the chip plan (``ChipPlan.lent``).

The lent submodules are copies of the stereo pair's: ``nna.macs`` MAC units each, the line
buffer SRAM the plan gives a stereo submodule (its layers' line buffers, sized for the
configured frame) and its weight store (``nna.weights``: the stereo network's weights, free
while the submodule is lent). The network's layers run as the stereo NNA's layers do
(:mod:`nna.geometry`: the same rules, extended for stride), mapped so:

- **a layer pipeline across the submodules**: the layers are cut into at most
  ``nna.lent_submodules`` contiguous groups, one per submodule, each group a layer pipeline on
  its submodule; feature maps stream from one submodule to the next on chip. The cut is the one
  whose busiest submodule has the fewest cycles per frame (ties: fewer submodules, then the
  earlier cut); submodules beyond the layer count stay idle;
- **a layer l** of kernel K, stride s, C_in -> C_out on an input of H x W makes
  ceil(H / s) x ceil(W / s) output pixels (items_l, :func:`~nna.geometry.strided_size`) of
  m_l = K^2 C_in C_out MACs; its submodule's MACs are shared over its group in proportion to
  m_l items_l (:func:`~nna.geometry.share_macs`), II_l = ceil(m_l / share)
  (:func:`~nna.submodule.timing.cycles_per_pixel`); a submodule's frame takes max_l items_l II_l
  over its group (:func:`~nna.submodule.timing.pipeline_cycles`), the network's frame its busiest
  submodule's: fps_max = f_nna / that. ``fps = "max"`` runs at fps_max; a target runs there
  (refused when above fps_max);
- **line buffers**: layer l holds K_l + slack s_l rows (:func:`~nna.geometry.buffer_rows`,
  the stereo submodule's slack, ``nna.line_buffer_rows`` - K_0) of its whole input width,
  rows x W x C_in x 8 bits (:func:`~nna.geometry.line_buffer_bits`). A submodule keeps its
  group's layers on chip in order while their buffers fit its line-buffer SRAM; a layer that
  does not fit **spills**: the layer before writes its feature map to DRAM and the layer reads
  it back, H W C_in bytes each way per frame (read once: a lower bound; layer 0 reads its input
  from DRAM anyway, so its spill adds nothing);
- **weights**: K^2 C_in C_out int8 weights and 8 bytes per output channel (an int32 bias, a
  32-bit multiply-shift) per layer. A group whose weights fit its submodule's weight store is
  loaded once when lent; otherwise its weights are read from DRAM once per frame (the least
  any schedule reads: each weight is needed once a frame; a schedule that re-reads them per row
  reads more, not modelled);
- **DRAM traffic** per frame: the input (H W C bytes read), the last layer's output (written),
  the spills and the weights read per frame; at the network's fps it is
  :attr:`LentPlan.gbps`, the DRAM channel's ``lent`` client (:mod:`sim.cycle.dram`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from stereosim.core.config import ChipConfig, LentLayer, LentNetwork, read_lent_network
from stereosim.core.errors import ConfigError
from stereosim.core.timing import BufferPlan
from stereosim.nna.geometry import buffer_rows, line_buffer_bits, share_macs, strided_size
from stereosim.nna.submodule.timing import cycles_per_pixel, pipeline_cycles
from stereosim.sim.cycle.dram import DramPlan

BYTES_PER_CHANNEL = 8  # an int32 bias and a 32-bit multiply-shift per output channel


@dataclass(frozen=True)
class LentLayerPlan:
    """A layer of the lent network on its submodule: ``in_shape`` / ``out_shape`` (H, W), its
    MAC ``share`` of the submodule, ``ii`` (cycles per output pixel), its line buffer's ``rows`` and
    ``buffer_bits``, and whether the buffer is ``on_chip`` (else the layer spills)."""

    index: int
    layer: LentLayer
    submodule: int
    in_shape: tuple[int, int]
    out_shape: tuple[int, int]
    share: int
    ii: int
    rows: int
    buffer_bits: int
    on_chip: bool

    @property
    def items(self) -> int:
        """Output pixels per frame."""
        return self.out_shape[0] * self.out_shape[1]

    @property
    def frame_cycles(self) -> int:
        """Its MAC array's cycles per frame: items x cycles per pixel."""
        return self.items * self.ii

    @property
    def spill_bytes(self) -> int:
        """DRAM bytes per frame its spill moves: its input feature map written and read back
        (0 on chip, and for layer 0, whose input is in DRAM anyway)."""
        if self.on_chip or self.index == 0:
            return 0
        return 2 * self.in_shape[0] * self.in_shape[1] * self.layer.channels_in

    @property
    def weight_bytes(self) -> int:
        return self.layer.macs_per_pixel + BYTES_PER_CHANNEL * self.layer.channels_out


@dataclass(frozen=True)
class LentPlan:
    """The lent network on its submodules (module docstring)."""

    network: LentNetwork
    submodules: int  # lent
    layers: tuple[LentLayerPlan, ...]
    sram_budget_bits: int  # line-buffer SRAM of a submodule
    weight_store_bits: int  # weight store of a submodule
    nna_hz: float

    @property
    def used(self) -> int:
        """Submodules the layers occupy."""
        return self.layers[-1].submodule + 1

    def group(self, sub: int) -> tuple[LentLayerPlan, ...]:
        return tuple(lay for lay in self.layers if lay.submodule == sub)

    @cached_property
    def submodule_cycles(self) -> tuple[int, ...]:
        """Each used submodule's cycles per frame: its group's busiest layer."""
        return tuple(max(lay.frame_cycles for lay in self.group(s)) for s in range(self.used))

    @property
    def frame_cycles(self) -> int:
        """The network's cycles per frame: its busiest submodule's."""
        return max(self.submodule_cycles)

    @property
    def fps_max(self) -> float:
        return self.nna_hz / self.frame_cycles

    @property
    def fps(self) -> float:
        """Its frame rate: the file's target, or fps_max ("max")."""
        return self.network.fps if self.network.fps is not None else self.fps_max

    def weights_resident(self, sub: int) -> bool:
        """Do submodule ``sub``'s weights fit its weight store (loaded once)?"""
        return 8 * sum(lay.weight_bytes for lay in self.group(sub)) <= self.weight_store_bits

    @cached_property
    def bytes_per_frame(self) -> dict[str, int]:
        """DRAM bytes of a frame: input, output, spill, weights."""
        lent_cnn, last = self.network, self.layers[-1]
        return {
            "input": lent_cnn.width * lent_cnn.height * lent_cnn.channels,
            "output": last.items * last.layer.channels_out,
            "spill": sum(lay.spill_bytes for lay in self.layers),
            "weights": sum(lay.weight_bytes for lay in self.layers
                           if not self.weights_resident(lay.submodule)),
        }

    @property
    def gbps(self) -> float:
        """Its DRAM traffic at its fps, GB/s."""
        return sum(self.bytes_per_frame.values()) * self.fps / 1e9

    @property
    def macs_per_frame(self) -> int:
        return sum(lay.items * lay.layer.macs_per_pixel for lay in self.layers)


def _group_cycles(items: list[int], mpp: list[int], macs: int) -> tuple[int, tuple[int, ...]]:
    """A group of layers on one submodule: its cycles per frame and the MAC shares."""
    shares = share_macs(macs, tuple(m * i for m, i in zip(mpp, items, strict=True)))
    ii = tuple(cycles_per_pixel(m, s) for m, s in zip(mpp, shares, strict=True))
    return pipeline_cycles(tuple(items), ii), shares


def cut_layers(items: list[int], mpp: list[int], macs: int, submodules: int
               ) -> tuple[int, ...]:
    """The submodule of each layer: the contiguous cut into at most ``submodules`` groups
    whose busiest group has the fewest cycles per frame (ties: fewer groups, then the earlier
    cut); a group of more layers than ``macs`` cannot be built."""
    n = len(items)
    inf = float("inf")
    cost = {(i, j): (_group_cycles(items[i:j], mpp[i:j], macs)[0] if j - i <= macs else inf)
            for i in range(n) for j in range(i + 1, n + 1)}
    # best[g][j]: the least bottleneck of layers 0..j-1 on g groups, and where its last cut is
    best = [[(inf, -1)] * (n + 1) for _ in range(min(submodules, n) + 1)]
    best[0][0] = (0, -1)
    for g in range(1, len(best)):
        for j in range(g, n + 1):
            best[g][j] = min(((max(best[g - 1][i][0], cost[i, j]), i) for i in range(g - 1, j)),
                             key=lambda t: t[0])
    g = min(range(1, len(best)), key=lambda k: best[k][n][0])
    if best[g][n][0] == inf:
        raise ConfigError(f"the lent network's {n} layers cannot share {submodules} lent "
                          f"submodules of nna.macs={macs} MACs (a layer needs one MAC unit): "
                          "lend more submodules")
    out, j = [0] * n, n
    for k in range(g, 0, -1):
        i = best[k][j][1]
        out[i:j] = [k - 1] * (j - i)
        j = i
    return tuple(out)


def lent_plan(cfg: ChipConfig, stereo_buffers: tuple[BufferPlan, ...], slack: int
              ) -> LentPlan | None:
    """The plan of ``nna.lent_network`` on ``nna.lent_submodules`` submodules whose SRAM is a
    stereo submodule's (``stereo_buffers``: its line buffers, with rows, and its weight store)
    and whose line buffers have ``slack`` rows beyond the window; None when none is lent."""
    if not cfg.nna.lent_network:
        return None
    lent_cnn = read_lent_network(cfg.nna.lent_network)
    shapes, shape = [], (lent_cnn.height, lent_cnn.width)
    for lay in lent_cnn.layers:
        out = (strided_size(shape[0], lay.stride), strided_size(shape[1], lay.stride))
        shapes.append((shape, out))
        shape = out
    items = [o[0] * o[1] for _, o in shapes]
    mpp = [lay.macs_per_pixel for lay in lent_cnn.layers]
    subs = cut_layers(items, mpp, cfg.nna.macs, cfg.nna.lent_submodules)
    budget = sum(b.bits for b in stereo_buffers if b.rows)
    layers = []
    for s in range(subs[-1] + 1):
        idx = [i for i in range(len(subs)) if subs[i] == s]
        _, shares = _group_cycles([items[i] for i in idx], [mpp[i] for i in idx], cfg.nna.macs)
        used = 0
        for i, share in zip(idx, shares, strict=True):
            lay, (inp, out) = lent_cnn.layers[i], shapes[i]
            (rows,) = buffer_rows((lay.kernel,), (lay.stride,), slack)
            bits = line_buffer_bits(rows, inp[1], lay.channels_in)
            fits = used + bits <= budget
            used += bits if fits else 0
            layers.append(LentLayerPlan(i, lay, s, inp, out, share,
                                        cycles_per_pixel(mpp[i], share), rows, bits, fits))
    plan = LentPlan(lent_cnn, cfg.nna.lent_submodules, tuple(layers), budget,
                    sum(b.bits for b in stereo_buffers if b.name == "nna.weights"),
                    cfg.clocks.nna_mhz * 1e6)
    if lent_cnn.fps is not None and lent_cnn.fps > plan.fps_max:
        raise ConfigError(
            f"lent network {lent_cnn.path}: fps = {lent_cnn.fps:g} but it reaches only "
            f"{plan.fps_max:.3f} fps on {cfg.nna.lent_submodules} lent submodules (clocks."
            "nna_mhz, nna.macs): lower fps, give \"max\" or lend more submodules")
    return plan


def lent_report(lent: LentPlan, dram: DramPlan | None, pixels: int) -> dict:
    """The ``lent_network`` section of the reports (both modes) and the estimate: the network,
    per layer its mapping, cycles, line buffer and spill, per submodule its cycles and SRAM,
    the frame rate, the DRAM bytes and GB/s, and what the stereo pair (``pixels`` a view)
    loses on the DRAM channel: the lent client's slots and the read-bound fps with and
    without them."""
    lent_cnn = lent.network
    layers = [{
        "layer": lay.index, "submodule": lay.submodule, "kernel": lay.layer.kernel,
        "stride": lay.layer.stride, "channels_in": lay.layer.channels_in,
        "channels_out": lay.layer.channels_out,
        "input": [lay.in_shape[1], lay.in_shape[0]], "output": [lay.out_shape[1],
                                                                lay.out_shape[0]],
        "macs_per_pixel": lay.layer.macs_per_pixel, "mac_share": lay.share,
        "cycles_per_pixel": lay.ii, "cycles_per_frame": lay.frame_cycles,
        "line_buffer_rows": lay.rows, "line_buffer_bits": lay.buffer_bits,
        "on_chip": lay.on_chip, "spill_bytes_per_frame": lay.spill_bytes,
        "weight_bytes": lay.weight_bytes} for lay in lent.layers]
    subs = [{"submodule": s, "layers": [lay.index for lay in lent.group(s)],
             "cycles_per_frame": lent.submodule_cycles[s],
             "line_buffer_bits": sum(lay.buffer_bits for lay in lent.group(s) if lay.on_chip),
             "weights_resident": lent.weights_resident(s)} for s in range(lent.used)]
    per_frame = lent.bytes_per_frame
    out = {
        "file": lent_cnn.path, "about": lent_cnn.about,
        "input": {"width": lent_cnn.width, "height": lent_cnn.height,
                  "channels": lent_cnn.channels},
        "fps_target": lent_cnn.fps if lent_cnn.fps is not None else "max",
        "submodules_lent": lent.submodules, "submodules_used": lent.used,
        "sram_budget_bits_per_submodule": lent.sram_budget_bits,
        "weight_store_bits_per_submodule": lent.weight_store_bits,
        "layers": layers, "submodules": subs,
        "cycles_per_frame": lent.frame_cycles,
        "fps_max": round(lent.fps_max, 3), "fps": round(lent.fps, 3),
        "busy_percent": round(100 * lent.fps / lent.fps_max, 3),
        "macs_per_frame": lent.macs_per_frame,
        "dram_bytes_per_frame": {**per_frame, "total": sum(per_frame.values())},
        "dram_gbps": round(lent.gbps, 6),
    }
    if dram is None:
        out["stereo_pair"] = {"dram_channel": False, "note": "dram.model = none: no channel is "
                              "modelled, the lent traffic takes no slot from the stereo pair"}
        return out
    client = dram.client("lent")  # None (or no slot) for a traffic too light to take a slot
    slots = client.count if client is not None else 0
    out["stereo_pair"] = {
        "dram_channel": True,
        "lent_slots_per_round": slots, "round_slots": dram.round_slots,
        "lent_slot_gbps": round(dram.gbps(client), 6) if client is not None else 0.0,
        "lent_share_of_channel": round(slots / dram.round_slots, 6),
        "read_bound_fps": dram.read_bound_fps(pixels),
        "read_bound_fps_without_lent": dram.read_bound_fps(pixels, without="lent"),
    }
    if not slots:
        out["stereo_pair"]["note"] = (
            f"its traffic, {lent.gbps:.3g} GB/s, takes no slot of the DRAM channel's round: the "
            "stereo pair loses nothing to it")
    return out


def lent_lines(rep: dict) -> list[str]:
    """The lent network in a few lines of text (``stereosim estimate`` and ``config plan``)."""
    inp = rep["input"]
    lines = [f"lent network {rep['file']}: {inp['width']}x{inp['height']}x{inp['channels']}, "
             f"{len(rep['layers'])} layers on {rep['submodules_used']} of "
             f"{rep['submodules_lent']} lent submodules: {rep['cycles_per_frame']} cycles a "
             f"frame, {rep['fps_max']} fps at most, runs at {rep['fps']} fps "
             f"({rep['busy_percent']} % busy); DRAM {rep['dram_bytes_per_frame']['total']} "
             f"bytes a frame, {rep['dram_gbps']} GB/s"]
    for lay in rep["layers"]:
        where = "on chip" if lay["on_chip"] else f"spills {lay['spill_bytes_per_frame']} B"
        lines.append(
            f"  layer {lay['layer']} (submodule {lay['submodule']}): {lay['kernel']}x"
            f"{lay['kernel']}/{lay['stride']} {lay['channels_in']}->{lay['channels_out']}, "
            f"{lay['input'][0]}x{lay['input'][1]} -> {lay['output'][0]}x{lay['output'][1]}: "
            f"{lay['mac_share']} MACs, {lay['cycles_per_pixel']} cycles a pixel, "
            f"{lay['cycles_per_frame']} a frame; line buffer {lay['line_buffer_rows']} rows, "
            f"{lay['line_buffer_bits']} bits, {where}")
    st = rep["stereo_pair"]
    if st["dram_channel"] and st["lent_slots_per_round"]:
        lines.append(f"  the stereo pair gives it {st['lent_slots_per_round']} of "
                     f"{st['round_slots']} DRAM slots a round ({st['lent_slot_gbps']} GB/s); "
                     f"read-bound fps {st['read_bound_fps']} (without it "
                     f"{st['read_bound_fps_without_lent']})")
    else:
        lines.append(f"  {st['note']}")
    return lines
