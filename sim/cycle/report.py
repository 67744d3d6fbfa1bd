"""The cycle report of a frame, from the chip plan and what an engine measured (both engines
build it here, so the keys and the arithmetic are the same)."""

from __future__ import annotations

import numpy as np

from stereosim.sim.cycle.area import chip_area
from stereosim.sim.cycle.energy import energy_report
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sim.cycle.power import power_report
from stereosim.sim.cycle.rules import FS_PER_S


def throughput(plan: ChipPlan, work: dict[str, int]) -> dict:
    """Frame rate and bottleneck from each block's work per frame (cycles of its clock).

    A block's work per frame is the cycles its critical resource is occupied
    (:meth:`ChipPlan.work_cycles`); in a stream of frames the block with the most work time
    sets the frame rate (``fps_bound``, a bound: it assumes no block waits on another beyond
    that); ``fps_bound_per_block`` is the rate each block alone would sustain.
    """
    work_s = {name: cycles / plan.domains[plan.block(name).domain].freq_hz
              for name, cycles in work.items()}
    bottleneck = max(sorted(work_s), key=lambda n: work_s[n])
    frame_s = work_s[bottleneck]
    return {
        "fps_bound": round(1.0 / frame_s, 3) if frame_s > 0 else None,
        "bottleneck": bottleneck,
        "work_ms_per_frame": {n: round(v * 1e3, 6) for n, v in sorted(work_s.items())},
        # the frame rate each block alone would sustain (1 / its work time per frame)
        "fps_bound_per_block": {n: round(1.0 / v, 3) if v > 0 else None
                          for n, v in sorted(work_s.items())},
        # a camera's own rate, blanking included: a lone frame skips the vertical blanking
        # and can measure faster, no stream from it is
        **({"camera_fps": round(plan.camera_fps, 3)} if plan.camera else {}),
    }


def stream_report(plan: ChipPlan, frame_times) -> dict:
    """The measured figures of a stream (``frame_times``: (3, frames): per frame the chip took,
    the instants in fs of its first input pixel and last output word, and the camera frame it
    is): frames completed and dropped (a camera with frame buffers); the **sustained** frame
    rate -- frames completed per second of simulated time after the first, (N - 1) / (end of
    frame N-1 - end of frame 0), None for a single frame -- and each frame's latency, first
    pixel in to last disparity out (min, median, p99, max and every frame's, in ms). With
    ``sva.pairs`` > 1, ``pairs`` gives the same figures for each camera pair's frames (camera
    frame f is pair f % pairs's). :func:`cycle_report` adds the stream's ``span_ms``."""
    first, last, cam = (np.asarray(frame_times[i]) for i in range(3))
    out = _stream_figures(first, last, cam, range(plan.frames))
    if plan.pairs > 1:
        out["pairs"] = []
        for p in range(plan.pairs):
            mine = (cam >= 0) & (cam % plan.pairs == p)
            out["pairs"].append({"pair": p, **_stream_figures(
                first[mine], last[mine], cam[mine], range(p, plan.frames, plan.pairs))})
    return out


def _stream_figures(first, last, cam, frames) -> dict:
    """:func:`stream_report`'s figures of the frames taken (their instants and camera frames)
    among the camera frames ``frames``."""
    taken = {int(f) for f in cam if f >= 0}
    done = last >= 0
    n_done = int(done.sum())
    lat_ms = (last[done] - first[done]) / 1e12
    dropped = [f for f in frames if f not in taken]
    out: dict = {"frames": len(frames), "frames_completed": n_done,
                 "frames_dropped": len(dropped), "dropped_frames": dropped}
    if n_done > 1:
        span_s = (last[done][-1] - last[done][0]) / FS_PER_S
        out["sustained_fps"] = round(float((n_done - 1) / span_s), 3)
    else:
        out["sustained_fps"] = None
    if n_done:
        out["latency_ms"] = {
            "min": round(float(lat_ms.min()), 6),
            "median": round(float(np.median(lat_ms)), 6),
            "p99": round(float(np.percentile(lat_ms, 99, method="higher")), 6),
            "max": round(float(lat_ms.max()), 6),
        }
        out["latency_ms_per_frame"] = [round(float(v), 6) for v in lat_ms]
    return out


def cycle_report(plan: ChipPlan, first_cycle: int, last_cycle: int, stats: dict,
                 buffers: dict, frame_times) -> dict:
    """The cycle report from the sink's first and last pop (SVA cycles), the kernel
    statistics (``Simulator.stats()`` or the compiled engine's equal dict) and the row
    windows' peaks (:func:`sim.cycle.buffers.buffer_report`).

    ``throughput.fps_measured`` is the measured rate of frames run one at a time (1 / the
    time from the first input pixel at t = 0 to the first frame's last output word): far below
    the work bound ``fps_bound`` when blocks hold work they cannot hand on (column tiles behind
    merge FIFOs shallower than a tile row, say). A stream's measured rate is
    ``stream.sustained_fps`` (:func:`stream_report`). ``stream.span_ms`` is the run's span, first
    input pixel to last output word; ``latency.frame_ms``, the same instant, only when the run
    is one frame -- a stream's frames have their own latencies, ``stream.latency_ms``. Times
    name their unit (``_us``, ``_ms``); every block's cycles say their clock domain
    (:func:`block_report`); see docs/report.md for every key.
    """
    period = plan.domains["sva"].period_fs
    first_fs = first_cycle * period
    last_fs = last_cycle * period
    work = {b.name: plan.work_cycles(b, stats["blocks"][b.name]["busy"])
            for b in plan.blocks if b.kind != "sink"}
    thr = throughput(plan, work)
    # frames one at a time, first input pixel to last output word: a stream overlaps frames
    # and reaches `fps_bound` unless blocks wait on each other (see blocks.*.blocked)
    frame0_fs = int(frame_times[1][0]) if frame_times[1][0] >= 0 else last_fs
    thr["fps_measured"] = round(FS_PER_S / frame0_fs, 3) if frame0_fs > 0 else None
    fifos = stats["fifos"]
    # a stream's span (first input pixel to its last word) is not a frame's latency: the
    # frames' latencies are stream.latency_ms; latency.frame_ms is reported for one frame alone
    stream = {**stream_report(plan, frame_times), "span_ms": last_fs / 1e12}
    latency = {"first_output_us": first_fs / 1e9}
    if plan.frames == 1:
        latency["frame_ms"] = stream["span_ms"]
    extra = {}
    if plan.dram is not None:
        taken = int(np.count_nonzero(np.asarray(frame_times[2]) >= 0))
        extra["dram"] = dram_report(plan, stats, last_fs, taken)
    if "nna_layers" in stats:
        extra["nna_layers"] = nna_layer_report(plan, stats["nna_layers"], buffers)
    energy = energy_report(plan, stats, *power_basis(thr, stream))
    area = chip_area(plan, plan.cfg.power.node)
    return {
        **extra,
        "cycles": {
            "total": dict(sorted(stats["cycles"].items())),
            "clock_mhz": {d: _mhz(plan, d) for d in sorted(stats["cycles"])},
            "first_output": {"sva": first_cycle, "time_us": first_fs / 1e9},
            "last_output": {"sva": last_cycle, "time_ms": last_fs / 1e12},
        },
        "latency": latency,
        "throughput": dict(sorted(thr.items())),
        "blocks": block_report(plan, stats),
        "fifos": {n: fifo_report(plan, n, fifos[n]) for n in sorted(fifos)},
        "fifo_bytes_per_frame": {n: fifos[n]["bits_transferred"] // 8 for n in sorted(fifos)},
        "fifo_sram_bits": {f.name: f.sram_bits for f in sorted(plan.fifos, key=lambda f: f.name)},
        "buffers": {b: buffers[b] for b in sorted(buffers)},
        "sva_stages": sva_stage_activity(plan, stats["stages"]["sva"]),
        "stream": stream,
        "energy": energy,
        "area": area,
        "power": power_report(plan, stats, energy, frame_times, area),
    }


ACTIVITY_ORDER = ("busy", "starved", "blocked", "idle")


def nna_layer_report(plan: ChipPlan, layers: dict, buffers: dict) -> dict:
    """Per NNA submodule, per layer of its pipeline (a network of several layers): MACs per
    output pixel, MAC share, cycles per output pixel, its MAC array's cycles busy, starved (on
    its input rows), blocked (a finished output waiting for room in the next line buffer or
    the output FIFO) and idle, the cycles its first and last output left (NNA cycles: the
    first is the layer's first-row latency) and its line buffer's capacity and peak."""
    out = {}
    for name in sorted(layers):
        entry = plan.block(name)
        out[name] = [{
            "layer": lay.index, "macs_per_pixel": lay.macs_per_pixel, "mac_share": lay.macs,
            "cycles_per_pixel": lay.ii, "output_pixels": lay.items,
            **{a: counts[a] for a in ACTIVITY_ORDER},
            "first_output_cycle": counts["first_output_cycle"],
            "last_output_cycle": counts["last_output_cycle"],
            "line_buffer": {"name": lay.buffer.name, **buffers[name][lay.buffer.name]},
        } for lay, counts in zip(entry.layers, layers[name], strict=True)]
    return out


def _mhz(plan: ChipPlan, domain: str) -> float:
    return round(plan.domains[domain].freq_hz / 1e6, 6)


def block_report(plan: ChipPlan, stats: dict) -> dict:
    """Each block's cycles by activity (``stats["blocks"]``), in the cycles of the block's own
    clock domain (``clock_domain``, ``clock_mhz``, ``cycles_total``: that domain's cycles over
    the run), and as ``percent`` of them (busy, starved, blocked and idle add up to 100 but
    for rounding)."""
    out = {}
    for name in sorted(stats["blocks"]):
        counts = stats["blocks"][name]
        domain = plan.block(name).domain
        total = int(stats["cycles"][domain])
        out[name] = {
            **counts,
            "clock_domain": domain,
            "clock_mhz": _mhz(plan, domain),
            "cycles_total": total,
            "percent": {a: round(100.0 * counts[a] / total, 2) if total else 0.0
                        for a in ACTIVITY_ORDER},
        }
    return out


def fifo_report(plan: ChipPlan, name: str, counts: dict) -> dict:
    """A FIFO's statistics with the domains they count in -- ``cycles_full`` in the
    ``producer_domain``, ``cycles_empty`` in the ``consumer_domain`` -- and its occupancy
    histogram made explicit: ``occupancy`` (the bins, 0..depth items) beside ``cycles`` (the
    consumer's cycles that began with that many items), counted in ``clock_domain`` (the
    consumer's; the cycles add up to that domain's cycles over the run)."""
    fifo = next(f for f in plan.fifos if f.name == name)
    hist = counts["occupancy_histogram"]
    return {
        **counts,
        "consumer_domain": fifo.dst,
        "producer_domain": fifo.src,
        "occupancy_histogram": {
            "clock_domain": fifo.dst,
            "clock_mhz": _mhz(plan, fifo.dst),
            "cycles": list(hist),
            "occupancy": list(range(len(hist))),
        },
    }


def dram_report(plan: ChipPlan, stats: dict, end_fs: int, frames_taken: int) -> dict:
    """The DRAM channel over the run (``end_fs``: the last word's instant): per client its slots
    per round and the bandwidth they give it, the bytes it moved and their rate over the run,
    the cycles the memory sources and the sink waited on it, the channel's utilisation (bytes
    moved / what the peak could move) and the frame rate its read slots bound."""
    d = plan.dram
    h, w = plan.shape
    n = h * w
    span_s = end_fs / FS_PER_S if end_fs > 0 else None
    moved = {"read": 2 * n * frames_taken, "camera_write": 2 * n * frames_taken,
             "write_back": -(-n * plan.word_bits // 8) * frames_taken}
    clients = {}
    total = 0.0
    for c in d.clients:
        if c.name == "lent":  # a load at the lent network's rate, over the run
            nbytes = plan.lent.gbps * 1e9 * span_s if span_s else 0.0
        elif c.name == "spill":
            nbytes = c.bytes_per_pixel * n * frames_taken
        else:
            nbytes = moved[c.name]
        total += nbytes
        clients[c.name] = {
            "what": c.what, "slots_per_round": c.count,
            "slot_gbps": round(d.gbps(c), 6),
            "bytes": round(nbytes),
            "gbps": round(nbytes / span_s / 1e9, 6) if span_s else None,
        }
    waits = stats["dram"]
    stalls = {"sink": waits["write_stall_cycles"]}
    if d.reads is not None:
        stalls.update({"memory_left": waits["read_stall_cycles"][0],
                       "memory_right": waits["read_stall_cycles"][1]})
    return {
        "model": "tdm", "peak_gbps": plan.cfg.dram.gbps, "burst_bytes": d.burst_bytes,
        "slot_ns": d.slot_fs / 1e6, "round_slots": d.round_slots,
        "latency_ns": d.latency_fs / 1e6,
        "clients": clients,
        "stall_cycles": dict(sorted(stalls.items())),
        "utilisation": round(total / (plan.cfg.dram.gbps * 1e9 * span_s), 6) if span_s else None,
        "read_bound_fps": d.read_bound_fps(n),
    }


def power_basis(throughput: dict, stream: dict) -> tuple[float | None, str]:
    """The frame rate the average power is given at: a stream's measured sustained rate, or
    for one frame the work bound."""
    if stream.get("sustained_fps"):
        return stream["sustained_fps"], "sustained (measured)"
    return throughput["fps_bound"], "work bound (one frame)"


def sva_stage_activity(plan: ChipPlan, stages: dict) -> dict:
    """Each SVA stage's cycles over the run as the engine counted them (``stats["stages"]``):
    busy while it holds a word and the pipeline advances, blocked while it holds one and the
    pipeline stalls, starved while it holds none, idle once the frame's last word has left it;
    the most words it held beside what its registers hold; utilisation = busy / (busy +
    starved + blocked)."""
    out = {}
    for st in plan.block("sva").stages:
        c = stages[st.name]
        active = c["busy"] + c["starved"] + c["blocked"]
        out[st.name] = {"busy": c["busy"], "starved": c["starved"], "blocked": c["blocked"],
                        "idle": c["idle"], "peak_words": c["peak_words"],
                        "capacity_words": st.slots,
                        "utilization_percent": round(100 * c["busy"] / active, 2)
                        if active else 0.0}
    return out
