"""The chip assembled from clocked blocks: sources -> NNA submodules -> SVA -> sink.

:func:`run_cycle` simulates one stereo frame on the readable two-phase kernel
(:mod:`sim.cycle.clock`) and returns the output words with a cycle report. Domains: ``nna`` and
``sva`` (and ``camera`` with a camera source; a memory source runs in the ``nna`` domain).
FIFOs, named by where data flows: ``src_left_to_nna``, ``src_right_to_nna``,
``nna_left_to_sva``, ``nna_right_to_sva`` (crossing nna -> sva), ``sva_to_sink``.
"""

from __future__ import annotations

import numpy as np

from nna.descriptor import descriptor_bits
from nna.geometry import split_frame
from sim.config import ChipConfig
from sim.cycle.architecture import nna_to_sva_word_bits, output_word_bits
from sim.cycle.blocks.nna import Merge, NnaSubmodule
from sim.cycle.blocks.sources import CameraSource, MemorySource, Sink
from sim.cycle.blocks.sva import SvaBlock
from sim.cycle.fifo import Fifo
from sim.cycle.kernel import Simulator
from sim.cycle.report import assemble_report, chip_domains, frame_budget

FS_PER_S = 10**15


class Chip:
    """The blocks, FIFOs and domains of one frame's simulation (built by :func:`build_chip`)."""

    def __init__(self, sim: Simulator, domains: dict, fifos: dict, blocks: dict, sink: Sink):
        self.sim = sim
        self.domains = domains
        self.fifos = fifos
        self.blocks = blocks
        self.sink = sink


def build_chip(left: np.ndarray, right: np.ndarray, cfg: ChipConfig, *, order_seed=None,
               sink_stall=None, trace=None) -> Chip:
    shape = left.shape
    bits = descriptor_bits(cfg.nna)
    dtype = np.uint32 if bits <= 32 else np.uint64
    sim = Simulator(order_seed=order_seed, trace=trace)
    domains = {name: sim.add_domain(d) for name, d in chip_domains(cfg).items()}
    nna, sva = domains["nna"], domains["sva"]
    src_domain = domains.get("camera", nna)
    f = cfg.fifo
    fifos = {}

    def fifo(name, depth, width, src, dst):
        fifos[name] = sim.add_fifo(Fifo(name, depth, width, f.latency_cycles, src=src, dst=dst,
                                        sync_cycles=f.sync_cycles))
        return fifos[name]

    word_bits = output_word_bits(cfg)
    desc_bits = nna_to_sva_word_bits(cfg)
    blocks = {}
    outs = {}
    parts = cfg.nna.stereo_submodules // 2
    tiles = split_frame(shape, parts, cfg.nna.split, cfg.nna)
    for side, image in (("left", left), ("right", right)):
        out = fifo(f"nna_{side}_to_sva", f.nna_to_sva_depth, desc_bits, nna, sva)
        if parts == 1:
            src_fifos = [fifo(f"src_{side}_to_nna", f.source_to_nna_depth, 8, src_domain, nna)]
            sub_outs = [out]
        else:
            src_fifos = [fifo(f"src_{side}_to_nna{t}", f.source_to_nna_depth, 8, src_domain, nna)
                         for t in range(parts)]
            sub_outs = [fifo(f"nna_{side}{t}_to_merge", f.nna_to_sva_depth, desc_bits, nna, nna)
                        for t in range(parts)]
        targets = src_fifos[0] if parts == 1 else list(zip(src_fifos, tiles))
        if cfg.source.kind == "camera":
            source = CameraSource(f"camera_{side}", src_domain, image, targets,
                                  cfg.source.camera_hblank, cfg.source.camera_vblank)
        else:
            source = MemorySource(f"memory_{side}", src_domain, image, targets,
                                  round(cfg.source.memory_gbps * 1e9))
        blocks[source.name] = sim.add_block(source)
        for t in range(parts):
            name = f"nna_{side}" if parts == 1 else f"nna_{side}{t}"
            sub = NnaSubmodule(name, nna, shape, src_fifos[t], sub_outs[t], cfg.nna,
                               tile=tiles[t] if parts > 1 else None)
            blocks[name] = sim.add_block(sub)
        if parts > 1:
            merge = Merge(f"merge_{side}", nna, shape, sub_outs, tiles, out)
            blocks[merge.name] = sim.add_block(merge)
        outs[side] = out
    to_sink = fifo("sva_to_sink", f.sva_to_sink_depth, word_bits, sva, sva)
    blocks["sva"] = sim.add_block(
        SvaBlock("sva", sva, shape, outs["left"], outs["right"], to_sink, cfg.sva, bits, dtype)
    )
    sink = Sink("sink", sva, to_sink, shape, stall=sink_stall)
    blocks["sink"] = sim.add_block(sink)
    return Chip(sim, domains, fifos, blocks, sink)


def run_cycle(left: np.ndarray, right: np.ndarray, cfg: ChipConfig, *, order_seed=None,
              sink_stall=None, trace=None) -> tuple[np.ndarray, dict, Chip]:
    """Simulate one frame; returns (output words (H, W) int32, cycle report, the chip)."""
    chip = build_chip(left, right, cfg, order_seed=order_seed, sink_stall=sink_stall, trace=trace)
    stats = chip.sim.run(lambda: chip.sink.done, budget_cycles=frame_budget(left.shape, cfg, chip.domains),
                         watchdog_cycles=cfg.sim.watchdog_cycles)
    return chip.sink.words.copy(), cycle_report(chip, stats), chip


def cycle_report(chip: Chip, stats: dict) -> dict:
    """Cycle counts, latency, throughput and bottleneck, per-block activity, FIFO statistics."""
    work = {name: (block.work_cycles(), block.domain.freq_hz)
            for name, block in chip.blocks.items() if name != "sink"}
    return assemble_report(chip.domains["sva"], chip.sink.first_cycle, chip.sink.last_cycle,
                           work, stats)


