"""The chip assembled from clocked blocks: sources -> NNA submodules -> SVA -> sink.

:func:`run_cycle` simulates one stereo frame on the readable two-phase kernel
(:mod:`sim.clock`) and returns the output words with a cycle report. Domains: ``nna`` and
``sva`` (and ``camera`` with a camera source; a memory source runs in the ``nna`` domain).
FIFOs, named by where data flows: ``src_left_to_nna``, ``src_right_to_nna``,
``nna_left_to_sva``, ``nna_right_to_sva`` (crossing nna -> sva), ``sva_to_sink``.
"""

from __future__ import annotations

import numpy as np

from nna.blocks import Merge, NnaSubmodule, cycles_per_descriptor, split_frame
from nna.descriptor import descriptor_bits
from sim.architecture import nna_to_sva_word_bits, output_word_bits
from sim.clock import ClockDomain, Simulator
from sim.config import ChipConfig
from sim.fifo import Fifo
from sim.sources import CameraSource, MemorySource, Sink
from sva.blocks import SvaBlock

FS_PER_S = 10**15


class Chip:
    """The blocks, FIFOs and domains of one frame's simulation (built by :func:`build_chip`)."""

    def __init__(self, sim: Simulator, domains: dict, fifos: dict, blocks: dict, sink: Sink):
        self.sim = sim
        self.domains = domains
        self.fifos = fifos
        self.blocks = blocks
        self.sink = sink


def chip_domains(cfg: ChipConfig) -> dict[str, ClockDomain]:
    """The clock domains of the chip: ``nna`` and ``sva``, and ``camera`` with a camera source
    (a memory source runs in the ``nna`` domain)."""
    domains = {"nna": ClockDomain("nna", cfg.clocks.nna_mhz * 1e6),
               "sva": ClockDomain("sva", cfg.clocks.sva_mhz * 1e6)}
    if cfg.source.kind == "camera":
        domains["camera"] = ClockDomain("camera", cfg.clocks.camera_mhz * 1e6)
    return domains


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


def frame_budget(shape, cfg: ChipConfig, domains: dict) -> dict[str, int]:
    """A generous cycle budget: 20x a frame at the slowest block's rate, per domain."""
    h, w = shape
    per_pixel_s = max(
        cycles_per_descriptor(cfg.nna) / (cfg.clocks.nna_mhz * 1e6),
        cfg.sva.cycles_per_pixel / (cfg.clocks.sva_mhz * 1e6),
        (w + cfg.source.camera_hblank) / w / (cfg.clocks.camera_mhz * 1e6)
        if cfg.source.kind == "camera" else 0.0,
    )
    frame_s = (h + 16) * w * per_pixel_s + 1e-6
    return {name: int(20 * frame_s * d.freq_hz) + 100_000 for name, d in domains.items()}


def run_cycle(left: np.ndarray, right: np.ndarray, cfg: ChipConfig, *, order_seed=None,
              sink_stall=None, trace=None) -> tuple[np.ndarray, dict, Chip]:
    """Simulate one frame; returns (output words (H, W) int32, cycle report, the chip)."""
    chip = build_chip(left, right, cfg, order_seed=order_seed, sink_stall=sink_stall, trace=trace)
    stats = chip.sim.run(lambda: chip.sink.done, budget_cycles=frame_budget(left.shape, cfg, chip.domains),
                         watchdog_cycles=cfg.sim.watchdog_cycles)
    return chip.sink.words.copy(), cycle_report(chip, stats), chip


def fast_engine_models(cfg: ChipConfig) -> bool:
    """The compiled steps (sim/fast.py) cover one NNA submodule per camera; the schedule engine
    (sim/schedule.py) covers splits too."""
    return cfg.nna.stereo_submodules == 2


def simulate(left: np.ndarray, right: np.ndarray, cfg: ChipConfig) -> tuple[np.ndarray, dict]:
    """One frame on the engine ``sim.engine`` selects: (output words, cycle report).

    ``readable``: the reference kernel. ``fast`` and ``auto``: the compiled engine -- the
    schedule engine for a frame that completes, the compiled steps (one submodule per camera)
    or the readable kernel (splits) for one that stops early, which they report exactly. Every
    engine gives identical words, reports and statistics (tests/sim/test_fast.py,
    tests/sim/test_schedule.py); the readable one runs ~5e4 cycles/s, the others millions.
    """
    engine = "readable" if cfg.sim.engine == "readable" else "fast"
    if engine == "fast" and fast_engine_models(cfg):
        from sim.fast import run_cycle_fast

        words, report, _ = run_cycle_fast(left, right, cfg)
    else:
        done = None
        if engine == "fast":
            from sim.schedule import run_schedule

            done = run_schedule(left, right, cfg)
        if done is None:
            engine = "readable"
            words, report, _ = run_cycle(left, right, cfg)
        else:
            words, report, _ = done
    report["engine"] = engine
    return words, report


def cycle_report(chip: Chip, stats: dict) -> dict:
    """Cycle counts, latency, throughput and bottleneck, per-block activity, FIFO statistics."""
    work = {name: (block.work_cycles(), block.domain.freq_hz)
            for name, block in chip.blocks.items() if name != "sink"}
    return assemble_report(chip.domains["sva"], chip.sink.first_cycle, chip.sink.last_cycle,
                           work, stats)


def assemble_report(sva: ClockDomain, first_cycle: int, last_cycle: int,
                    work: dict[str, tuple[int, float]], stats: dict) -> dict:
    """The cycle report from what either engine measured: the sink's first and last pop (SVA
    cycles), each block's work (cycles, clock in Hz) and the kernel statistics.

    A block's work per frame is the cycles its critical resource is occupied (the MAC array,
    the SVA's output pipeline, a source's port); in a stream of frames the block with the most
    work time sets the frame rate (``fps``) -- if no block waits on another beyond that.
    ``fps_frame`` is the rate of frames run one at a time (the first input pixel at t = 0 to the
    last output word): far below ``fps`` when blocks hold work they cannot hand on (column tiles
    behind merge FIFOs shallower than a tile row, say).
    """
    first_fs = sva.edge_fs(first_cycle)
    last_fs = sva.edge_fs(last_cycle)
    work_s = {name: cycles / freq for name, (cycles, freq) in work.items()}
    bottleneck = max(sorted(work_s), key=lambda n: work_s[n])
    frame_s = work_s[bottleneck]
    fifos = stats["fifos"]
    return {
        "cycles": {
            "total": dict(sorted(stats["cycles"].items())),
            "first_output": {"sva": first_cycle, "ns": first_fs / 1e6},
            "last_output": {"sva": last_cycle, "ns": last_fs / 1e6},
        },
        "latency": {"first_output_ns": first_fs / 1e6, "frame_ns": last_fs / 1e6},
        "throughput": {
            "fps": round(1.0 / frame_s, 3) if frame_s > 0 else None,
            # frames one at a time, first input pixel to last output word: a stream overlaps
            # frames and reaches `fps` unless blocks wait on each other (see blocks.*.blocked)
            "fps_frame": round(FS_PER_S / last_fs, 3) if last_fs > 0 else None,
            "bottleneck": bottleneck,
            "work_ms_per_frame": {n: round(v * 1e3, 6) for n, v in sorted(work_s.items())},
            # the frame rate each block alone would sustain (1 / its work time per frame)
            "fps_per_block": {n: round(1.0 / v, 3) if v > 0 else None
                              for n, v in sorted(work_s.items())},
        },
        "blocks": {n: stats["blocks"][n] for n in sorted(stats["blocks"])},
        "fifos": {n: fifos[n] for n in sorted(fifos)},
        "fifo_bytes_per_frame": {n: fifos[n]["bits_transferred"] // 8 for n in sorted(fifos)},
        "fifo_sram_bits": {n: fifos[n]["depth"] * fifos[n]["width_bits"] for n in sorted(fifos)},
    }
