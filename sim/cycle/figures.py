"""The report's static figures of a chip plan: what its buffers hold, what a frame costs in
actions, and the ``architecture`` section every report carries (both modes and the estimate).

Split from :mod:`sim.cycle.plan`, which builds the plan; everything here reads a built plan:
:func:`sram_bits` per buffer, :func:`chip_sram` the chip's SRAM with every instance counted
once, :func:`action_counts` per frame, :func:`architecture_report` and its parts (the NNA's
layers and submodules, the SVA's pipeline).
"""

from __future__ import annotations

import dataclasses
import functools

from stereosim.core.config import ChipConfig
from stereosim.core.errors import ConfigError
from stereosim.nna.descriptor import file_identity, weights_file
from stereosim.nna.geometry import macs_per_descriptor, window_rows
from stereosim.nna.submodule.timing import cycles_per_descriptor
from stereosim.sim.cycle.plan import ChipPlan, build_plan
from stereosim.sim.rtl_synth import silicon_section


def sram_bits(plan: ChipPlan) -> dict[str, int]:
    """SRAM bits of every buffer (per instance; NNA: per submodule, sized for the widest tile
    it serves)."""
    out: dict[str, int] = {}
    for b in plan.blocks:
        for buf in b.buffers:
            out[buf.name] = max(out.get(buf.name, 0), buf.bits)
    return out


def chip_sram(plan: ChipPlan) -> dict:
    """The chip's SRAM in bits, every instance counted once: the figure to quote for the chip.

    The NNA's ``nna.submodules`` submodules are one design instantiated that many times, so
    each holds the buffers of the widest tile (:func:`sram_bits`) whether it serves the stereo
    pair, is lent to another network (whose line buffers and weight store are the same
    SRAM) or idles. ``by_block``: the NNA's submodules split by their use (``nna_stereo``,
    ``nna_lent``, ``nna_idle``; how many of each: ``nna_instances``), the SVA and the FIFOs
    (depth x width each); ``by_kind``: the NNA's line buffers and weight stores, each SVA
    buffer, and the FIFOs; ``total``: their sum."""
    n = plan.cfg.nna
    buffers = sram_bits(plan)
    nna = {k: v for k, v in buffers.items() if k.startswith("nna.")}
    per_sub = sum(nna.values())
    fifos = sum(f.sram_bits for f in plan.fifos)
    instances = {"nna_stereo": n.stereo_submodules, "nna_lent": n.lent_submodules,
                 "nna_idle": n.submodules - n.stereo_submodules - n.lent_submodules}
    by_block = {**{k: count * per_sub for k, count in instances.items()},
                "sva": sum(v for k, v in buffers.items() if k.startswith("sva.")),
                "fifos": fifos}
    weights = sum(v for k, v in nna.items() if k == "nna.weights")
    by_kind = {"nna.line_buffers": n.submodules * (per_sub - weights),
               "nna.weight_stores": n.submodules * weights,
               **{k: v for k, v in sorted(buffers.items()) if k.startswith("sva.")},
               "fifos": fifos}
    return {"total": sum(by_block.values()), "nna_per_submodule": per_sub,
            "nna_submodules": n.submodules, "nna_instances": instances, "by_block": by_block,
            "by_kind": by_kind}


def action_counts(plan: ChipPlan) -> dict[str, dict[str, int]]:
    """Per-frame counts of MACs and SRAM reads/writes per block (per camera for the NNA), from
    the buffers' declared accesses (:class:`~core.timing.BufferPlan`: per output pixel).

    NNA: K*K*C MACs and (CNN) C requantising multiplies per descriptor; its line buffer writes
    each pixel once and reads the window's next column (2h + 1 pixels) per descriptor. A
    network of several layers: per layer m_l MACs and C_out,l multiplies per output pixel of
    its region (a split frame's halos computed by every tile that needs them; per layer in
    ``nna_layers``), each line buffer's accesses per pixel. SVA: D Hamming costs per pixel, and
    its SRAM banks' accesses per pixel.
    """
    cfg = plan.cfg
    h, w = plan.shape
    n = h * w
    nna = next(b for b in plan.blocks_of("nna"))
    sva = plan.block("sva")

    def accesses(block, attr):
        return sum(n * getattr(buf, attr) for buf in block.buffers)

    cnn = plan.spec.nna.cnn
    requant = 0 if cnn is None else n * sum(w.shape[0] for w in cnn.weights)
    layers = {}
    if len(nna.layers) > 1:  # each layer over its regions, one camera's tiles
        subs = [b for b in plan.blocks_of("nna") if b.side == 0]
        for i, lay in enumerate(nna.layers):
            items = sum(b.layers[i].items for b in subs)
            layers[f"layer{i}"] = {"macs": items * lay.macs_per_pixel,
                                   "requant_multiplies": items * lay.channels_out}
    per_camera = {"macs": n * macs_per_descriptor(plan.spec.nna),
                  "requant_multiplies": requant}
    if layers:
        per_camera = {k: sum(lay[k] for lay in layers.values()) for k in per_camera}
    return {
        "nna_per_camera": {**per_camera,
                           "sram_writes": accesses(nna, "pixel_writes"),
                           "sram_reads": accesses(nna, "pixel_reads")},
        **({"nna_layers": layers} if layers else {}),
        "sva": {
            "hamming_costs": n * cfg.sva.disparities,
            "sram_writes": accesses(sva, "pixel_writes"),
            "sram_reads": accesses(sva, "pixel_reads"),
        },
    }


def architecture_report(plan: ChipPlan) -> dict:
    """The ``architecture`` section of every report (both modes)."""
    h, w = plan.shape
    buffers = sram_bits(plan)
    return {
        "descriptor_bits": plan.descriptor_bits,
        "nna_cycles_per_descriptor": cycles_per_descriptor(plan.spec.nna),
        "nna_window_rows": window_rows(plan.spec.nna),
        "sram_bits": buffers,
        "sram_bits_total": {
            "nna_per_submodule": sum(v for k, v in buffers.items() if k.startswith("nna.")),
            "sva": sum(v for k, v in buffers.items() if k.startswith("sva.")),
        },
        "descriptor_bytes_per_frame_per_camera": h * w * plan.descriptor_bits // 8,
        "actions": action_counts(plan),
        "sva_pipeline": sva_pipeline_report(plan),
        "nna_pipeline": [{"name": st.name, "ii": st.ii, "latency": st.latency,
                          "formula": st.formula} for st in plan.blocks_of("nna")[0].stages],
        "nna_submodules": submodule_report(plan),
        "chip_sram": chip_sram(plan),
        "silicon": silicon_section(plan.cfg),
        **({"nna_layers": layer_report(plan)} if len(plan.blocks_of("nna")[0].layers) > 1
           else {}),
    }


def layer_report(plan: ChipPlan) -> list[dict]:
    """The layer pipeline of the (first) NNA submodule (a network of several layers): per
    layer its kernel and channels, MACs per output pixel, MAC share, cycles per output pixel,
    its line buffer (rows, bits) and its output region per frame."""
    out = []
    for lay in plan.blocks_of("nna")[0].layers:
        out.append({"layer": lay.index, "kernel": 2 * lay.half + 1,
                    "channels_in": lay.channels_in, "channels_out": lay.channels_out,
                    "macs_per_pixel": lay.macs_per_pixel, "mac_share": lay.macs,
                    "cycles_per_pixel": lay.ii, "line_buffer": lay.buffer.name,
                    "line_buffer_rows": lay.rows, "line_buffer_bits": lay.buffer.bits,
                    "output_pixels": lay.items})
    return out


def submodule_report(plan: ChipPlan) -> dict:
    """How many NNA submodules the stereo pair uses, how many are lent, and what the others
    could give: the NNA's frame rate (its work bound) with every submodule on the pair (the
    largest even count, none lent; None when the frame cannot be split that far)."""
    n = plan.cfg.nna
    most = n.submodules - n.submodules % 2
    out = {"on_chip": n.submodules, "stereo": n.stereo_submodules, "lent": n.lent_submodules,
           "idle": n.submodules - n.stereo_submodules - n.lent_submodules,
           "nna_fps": nna_fps(plan)}
    if most > n.stereo_submodules:
        fps = _nna_fps_with_all(plan.cfg, plan.shape, _network_identity(plan.cfg))
        out["with_all"] = None if fps is None else {"stereo_submodules": most, "nna_fps": fps}
    return out


def nna_fps(p: ChipPlan) -> float:
    """The NNA's work bound of plan ``p`` in frames a second (its busiest submodule's)."""
    sub = max(p.blocks_of("nna"), key=lambda b: b.items)
    return round(p.domains["nna"].freq_hz / p.work_cycles(sub, 0), 3)


def _network_identity(cfg: ChipConfig) -> tuple | None:
    """What identifies the CNN's weight file as it is now (:func:`nna.descriptor.file_identity`;
    None for the census): a cache of figures that follow from the network keys on it."""
    if cfg.nna.descriptor == "census":
        return None
    return file_identity(weights_file(cfg.nna.cnn.weights))


@functools.lru_cache(maxsize=64)
def _nna_fps_with_all(cfg: ChipConfig, shape: tuple[int, int], network: tuple | None
                      ) -> float | None:
    """:func:`nna_fps` of ``cfg`` with every submodule on the pair (the largest even count,
    none lent), None when the frame cannot be split that far. A whole plan to build for one
    figure of every report: kept for the configurations, shapes and weight files seen
    (``network``, :func:`_network_identity`: a file rewritten since is another key)."""
    n = cfg.nna
    most = n.submodules - n.submodules % 2
    other = dataclasses.replace(cfg, nna=dataclasses.replace(
        n, stereo_submodules=most, lent_submodules=0, lent_network=""))
    try:
        return nna_fps(build_plan(other, shape))
    except ConfigError:
        return None  # more tiles than the frame has columns or rows


def sva_pipeline_report(plan: ChipPlan) -> dict:
    """The SVA's stages: II and latency of each, with the arithmetic, its registers (words in
    flight and their bits), and the pipeline's."""
    sva = plan.block("sva")
    return {
        "lanes": min(plan.cfg.sva.lanes, plan.cfg.sva.disparities),
        "initiation_interval": sva.ii,
        "latency": sva.latency,
        "register_bits": sum(st.register_bits for st in sva.stages),
        "stages": [{"name": st.name, "ii": st.ii, "latency": st.latency, "formula": st.formula,
                    "register_words": st.slots, "register_bits": st.register_bits,
                    "word_holds": st.holds} for st in sva.stages],
    }
