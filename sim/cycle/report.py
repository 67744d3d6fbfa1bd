"""What both cycle engines share: the chip's clock domains, a run's cycle budget, and the cycle
report assembled from what an engine measured."""

from __future__ import annotations

from nna.geometry import cycles_per_descriptor
from sim.config import ChipConfig
from sim.cycle.clock import ClockDomain

FS_PER_S = 10**15


def chip_domains(cfg: ChipConfig) -> dict[str, ClockDomain]:
    """The clock domains of the chip: ``nna`` and ``sva``, and ``camera`` with a camera source
    (a memory source runs in the ``nna`` domain)."""
    domains = {"nna": ClockDomain("nna", cfg.clocks.nna_mhz * 1e6),
               "sva": ClockDomain("sva", cfg.clocks.sva_mhz * 1e6)}
    if cfg.source.kind == "camera":
        domains["camera"] = ClockDomain("camera", cfg.clocks.camera_mhz * 1e6)
    return domains


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
