"""The analytic model of the chip: throughput, latency, memory and traffic without simulating.

:func:`estimate` answers, for a configuration and a frame size, the questions an architect screens
with before running the cycle model: the frame rate each block sustains and the bottleneck, the
first-output and whole-frame latency of one frame, SRAM bits per buffer and per FIFO, bytes per
frame through each FIFO, MACs per frame, and the paper's own arithmetic (four 3x3 layers vs one
9x9 layer; float vs binary descriptors). It mirrors the cycle model (``sim/chip.py``) rule for
rule, in arithmetic per image row instead of per cycle:

- **Throughput.** A block's *work* per frame is the cycles its critical resource is busy --
  the figure ``sim.cycle.chip.assemble_report`` ranks: descriptors x ``ceil(K*K*C / macs)`` per NNA
  submodule (census: 1 cycle), words x ``cycles_per_pixel`` for the SVA, one beat per pixel for a
  merge, ``max(N, ceil(N f / B))`` cycles for a memory source (N pixels, f its clock, B its
  bandwidth in bytes/s) and ``H (W + hblank)`` pixel clocks for a camera. The block with
  the largest work time sets the frame rate. Exact (the same integers the simulator counts),
  except a bandwidth-limited memory source that is also back-pressured (its tokens pile up
  while blocked, so it works less than the formula says; it is then not the bottleneck).
- **Latency.** Times are carried per image row: the cycle each stage receives the first and the
  last beat of a row. A stage's output row y is ready the cycle after the input row it needs is
  complete (NNA: row min(y + h, H - 1), h the window's half height; SVA: row min(y + r + m,
  H - 1), r box and m median radius); its first word leaves ``max(ready + latency, previous
  word + II)`` and the rest of the row follows at the II. FIFOs add their visibility delay,
  ``first_edge_after(push instant) + latency + (sync - 1 if crossing) - 1`` consumer cycles,
  computed on the same femtosecond grid as :class:`sim.cycle.clock.ClockDomain`. The line buffer's
  room rule and the SVA's look-ahead window (row y_in enters once output row y_in - r - m - 2
  is complete) are applied. Exact (to the cycle) when no FIFO fills; see docs/whatif.md for
  what is approximated when one does.
- **FIFO rate.** A FIFO of depth d moves at most d items per round trip (push -> visible -> pop
  -> free seen by the producer): ``(latency + 1)`` cycles in one domain, about
  ``(latency + sync - 1.5) T_consumer + (sync - 0.5) T_producer`` across domains (half a period
  for the edge alignment on average). A link slower than its producer stretches the stream.
- **Memory, traffic, work.** SRAM bits per buffer and per-action counts come from
  :mod:`sim.cycle.architecture` (the numbers the simulator reports); the FIFO plan mirrors
  :func:`sim.cycle.chip.build_chip` (names, depths, widths, beats per frame).
"""

from __future__ import annotations

import math

from nna.geometry import Tile, cycles_per_descriptor, half_window, split_frame
from sim.config import ChipConfig, config_to_dict
from sim.cycle.architecture import (
    action_counts,
    buffer_bits,
    nna_to_sva_word_bits,
    output_word_bits,
)
from sim.errors import InputError

FS_PER_S = 10**15

# The paper's four-layer MC-CNN-fast descriptor net: 3x3 kernels, 1 -> 32 -> 32 -> 32 -> 32.
FOUR_LAYERS = ((3, 1, 32), (3, 32, 32), (3, 32, 32), (3, 32, 32))
SINGLE_LAYER = ((9, 1, 32),)


def _period_fs(mhz: float) -> int:
    """The clock period as :class:`sim.cycle.clock.ClockDomain` rounds it."""
    return round(FS_PER_S / (mhz * 1e6))


class _Domains:
    """Clock periods (fs) by domain name, and the FIFO visibility rule across them."""

    def __init__(self, cfg: ChipConfig):
        self.period = {"nna": _period_fs(cfg.clocks.nna_mhz), "sva": _period_fs(cfg.clocks.sva_mhz)}
        self.freq = {"nna": cfg.clocks.nna_mhz * 1e6, "sva": cfg.clocks.sva_mhz * 1e6}
        self.src = "nna"
        if cfg.source.kind == "camera":
            self.src = "camera"
            self.period["camera"] = _period_fs(cfg.clocks.camera_mhz)
            self.freq["camera"] = cfg.clocks.camera_mhz * 1e6
        self.latency = cfg.fifo.latency_cycles
        self.sync = cfg.fifo.sync_cycles

    def visible(self, cycle: float, src: str, dst: str) -> float:
        """The consumer cycle from which an item pushed in producer ``cycle`` can be popped."""
        if src == dst:
            return cycle + self.latency
        t_fs = round(cycle) * self.period[src]
        return t_fs // self.period[dst] + 1 + self.latency + self.sync - 2

    def round_trip_fs(self, src: str, dst: str) -> float:
        """Push -> visible -> pop -> free seen by the producer -> next push (module docstring)."""
        if src == dst:
            return (self.latency + 1) * self.period[src]
        return ((self.latency + self.sync - 1.5) * self.period[dst]
                + (self.sync - 0.5) * self.period[src])


# ----------------------------------------------------------------------------------------------
# the FIFOs and blocks of sim.cycle.chip.build_chip


def _tiles(cfg: ChipConfig, shape: tuple[int, int]) -> list[Tile]:
    parts = cfg.nna.stereo_submodules // 2
    h, w = shape
    if parts == 1:
        return [Tile(0, w, 0, h, 0, w, 0, h)]
    return split_frame(shape, parts, cfg.nna.split, cfg.nna)


def fifo_plan(cfg: ChipConfig, shape: tuple[int, int]) -> dict[str, dict]:
    """Every FIFO of the chip: depth, width, producer and consumer domain, beats per frame."""
    h, w = shape
    f = cfg.fifo
    tiles = _tiles(cfg, shape)
    src = "camera" if cfg.source.kind == "camera" else "nna"
    out: dict[str, dict] = {}

    def add(name, depth, width, a, b, beats):
        out[name] = {"depth": depth, "width_bits": width, "src": a, "dst": b, "beats": beats}

    for side in ("left", "right"):
        add(f"nna_{side}_to_sva", f.nna_to_sva_depth, nna_to_sva_word_bits(cfg), "nna", "sva", h * w)
        if len(tiles) == 1:
            add(f"src_{side}_to_nna", f.source_to_nna_depth, 8, src, "nna", h * w)
        else:
            for t, tile in enumerate(tiles):
                n_in = (tile.in_x1 - tile.in_x0) * (tile.in_y1 - tile.in_y0)
                add(f"src_{side}_to_nna{t}", f.source_to_nna_depth, 8, src, "nna", n_in)
                add(f"nna_{side}{t}_to_merge", f.nna_to_sva_depth, nna_to_sva_word_bits(cfg), "nna", "nna",
                    tile.shape[0] * tile.shape[1])
    add("sva_to_sink", f.sva_to_sink_depth, output_word_bits(cfg), "sva", "sva", h * w)
    return dict(sorted(out.items()))


def block_work(cfg: ChipConfig, shape: tuple[int, int]) -> dict[str, tuple[int, float]]:
    """Work per frame of every block as (cycles, clock in Hz), as the cycle report counts it.

    A camera's work is its frame period, ``(H + vblank) (W + hblank)`` pixel clocks, so a
    camera-bound rate is the camera's own frame rate.
    """
    h, w = shape
    n = h * w
    tiles = _tiles(cfg, shape)
    c = cycles_per_descriptor(cfg.nna)
    nna_hz = cfg.clocks.nna_mhz * 1e6
    out: dict[str, tuple[int, float]] = {}
    for side in ("left", "right"):
        if cfg.source.kind == "camera":
            # the camera's frame period: its whole raster, vertical blanking included
            raster = (h + cfg.source.camera_vblank) * (w + cfg.source.camera_hblank)
            out[f"camera_{side}"] = (raster, cfg.clocks.camera_mhz * 1e6)
        else:
            f_hz = round(nna_hz)
            b = round(cfg.source.memory_gbps * 1e9)
            out[f"memory_{side}"] = (max(n, -(-n * f_hz // b)), nna_hz)
        if len(tiles) == 1:
            out[f"nna_{side}"] = (n * c, nna_hz)
        else:
            for t, tile in enumerate(tiles):
                out[f"nna_{side}{t}"] = (tile.shape[0] * tile.shape[1] * c, nna_hz)
            out[f"merge_{side}"] = (n, nna_hz)
    out["sva"] = (n * cfg.sva.cycles_per_pixel, cfg.clocks.sva_mhz * 1e6)
    return out


# ----------------------------------------------------------------------------------------------
# latency: the row timeline


def _source_cycle(cfg: ChipConfig, w: int, k: int) -> int:
    """Cycle (source domain) in which pixel k (raster) leaves an unobstructed source."""
    if cfg.source.kind == "camera":
        y, x = divmod(k, w)
        return y * (w + cfg.source.camera_hblank) + x
    f_hz = round(cfg.clocks.nna_mhz * 1e6)
    b = round(cfg.source.memory_gbps * 1e9)
    return max(k, -(-(k + 1) * f_hz // b) - 1)


def _tile_rows(cfg: ChipConfig, shape, tile: Tile, dom: _Domains) -> dict[int, tuple[float, float]]:
    """NNA cycles of the first and last descriptor push of every output row of one submodule."""
    h_img, w_img = shape
    half = half_window(cfg.nna)
    c = cycles_per_descriptor(cfg.nna)
    rows = cfg.nna.line_buffer_rows
    tw_in = tile.in_x1 - tile.in_x0
    tw = tile.x1 - tile.x0
    # the source -> NNA link: one pop per NNA cycle, at most depth items per round trip
    ii_in = max(1.0, dom.round_trip_fs(dom.src, "nna") / cfg.fifo.source_to_nna_depth
                / dom.period["nna"])
    if dom.src != "nna":
        ii_in = max(ii_in, dom.period[dom.src] / dom.period["nna"])
    pop_end: dict[int, float] = {}
    out: dict[int, tuple[float, float]] = {}
    next_out = tile.y0
    prev_end = -1.0
    prev_out_last = -1.0
    for y_in in range(tile.in_y0, tile.in_y1):
        k0 = y_in * w_img + tile.in_x0
        k1 = y_in * w_img + tile.in_x1 - 1
        start = max(dom.visible(_source_cycle(cfg, w_img, k0), dom.src, "nna"), prev_end + 1)
        # line-buffer room: y_in - max(in_y0, y_out - h) + 1 <= rows
        if y_in - tile.in_y0 + 1 > rows:
            need = y_in - rows + 1 + half  # output row that must be in progress
            if need - 1 in out and need <= tile.y1:
                start = max(start, out[need - 1][1] + 1)
        end = max(dom.visible(_source_cycle(cfg, w_img, k1), dom.src, "nna"),
                  math.ceil(start + (tw_in - 1) * ii_in))
        pop_end[y_in] = end
        prev_end = end
        while next_out < tile.y1 and min(next_out + half, h_img - 1) <= y_in:
            ready = pop_end[min(next_out + half, h_img - 1)] + 1
            first = max(ready, prev_out_last + 1) + c - 1
            last = first + (tw - 1) * c
            out[next_out] = (first, last)
            prev_out_last = last
            next_out += 1
    return out


def _merged_rows(cfg: ChipConfig, shape, tiles: list[Tile], dom: _Domains):
    """First/last push (NNA cycles) of each row of one camera's descriptor stream towards the
    SVA, and the items-per-cycle the stream can sustain."""
    h, w = shape
    c = cycles_per_descriptor(cfg.nna)
    per_tile = [_tile_rows(cfg, shape, t, dom) for t in tiles]
    if len(tiles) == 1:
        return per_tile[0], float(c)
    d = cfg.fifo.nna_to_sva_depth
    rows: dict[int, tuple[float, float]] = {}
    prev_end = -1.0
    for y in range(h):
        first = None
        for t, tile in enumerate(tiles):
            if not tile.y0 <= y < tile.y1:
                continue
            tw = tile.x1 - tile.x0
            t_first, t_last = per_tile[t][y]
            start = max(dom.visible(t_first, "nna", "nna"), prev_end + 1)
            if cfg.nna.split == "rows" and y == tile.y0 and t > 0:
                # a band's FIFO holds d items while the merge drains the bands before it: the
                # band produced d + 1 descriptors ahead and makes the rest at its own II now
                n_band = tile.shape[0] * tile.shape[1]
                per_tile[t] = _delay_band(per_tile[t], tile, start, n_band, d, c)
                t_first, t_last = per_tile[t][y]
            end = max(start + tw - 1, dom.visible(t_last, "nna", "nna"))
            first = start if first is None else first
            prev_end = end
        rows[y] = (first, prev_end)
    if cfg.nna.split == "rows":
        # the merge drains a band at one beat per cycle; the band's own II is in its row times
        return rows, 1.0
    widest = max(t.x1 - t.x0 for t in tiles)
    return rows, max(1.0, c * widest / w)


def _delay_band(rows, tile: Tile, merge_start: float, n_band: int, depth: int, c: int):
    """A row band back-pressured by the merge until ``merge_start``: its descriptors after the
    first depth + 1 follow at its II from then on (approximation; docs/whatif.md)."""
    w = tile.x1 - tile.x0
    out = {}
    for y, (first, last) in rows.items():
        j0 = (y - tile.y0) * w
        lo = merge_start + (j0 - depth - 1) * c
        out[y] = (max(first, lo), max(last, lo + (w - 1) * c))
    return out


def timeline(cfg: ChipConfig, shape: tuple[int, int]) -> dict:
    """First and last output word of one frame (SVA cycles, as the sink pops them) and the
    cycles of intermediate events, from the row model of the module docstring."""
    h, w = shape
    dom = _Domains(cfg)
    tiles = _tiles(cfg, shape)
    nna_rows, nna_ii = _merged_rows(cfg, shape, tiles, dom)
    s = cfg.sva
    la = s.box_size // 2 + (s.median // 2 if s.median > 1 else 0)
    # the NNA -> SVA stream: one pop per SVA cycle, the producer's II, the FIFO's round trip
    rt = dom.round_trip_fs("nna", "sva") / cfg.fifo.nna_to_sva_depth
    ii_link = max(1.0, rt / dom.period["sva"])
    ii_in = max(ii_link, nna_ii * dom.period["nna"] / dom.period["sva"])
    # the SVA -> sink FIFO: the SVA's II, or depth words per round trip
    ii_out = max(float(s.cycles_per_pixel), (cfg.fifo.latency_cycles + 1) / cfg.fifo.sva_to_sink_depth)
    in_end: dict[int, float] = {}
    out_rows: dict[int, tuple[float, float]] = {}
    next_out = 0
    prev_end = -1.0
    prev_out = -math.inf
    for y in range(h):
        first, last = nna_rows[y]
        start = max(dom.visible(first, "nna", "sva"), prev_end + 1)
        ii_row = ii_link
        if y - la - 2 >= 0 and out_rows[y - la - 2][1] + 1 > start:
            # the look-ahead window held the row back: upstream was blocked and resumes at its
            # own II (its row times above are those of an unobstructed producer)
            start = out_rows[y - la - 2][1] + 1
            ii_row = ii_in
        end = max(dom.visible(last, "nna", "sva"), math.ceil(start + (w - 1) * ii_row))
        in_end[y] = end
        prev_end = end
        while next_out < h and min(next_out + la, h - 1) <= y:
            ready = in_end[min(next_out + la, h - 1)] + 1
            o_first = max(ready + s.pipeline_latency, prev_out + ii_out)
            o_first = math.ceil(o_first)
            o_last = math.ceil(o_first + (w - 1) * ii_out)
            out_rows[next_out] = (o_first, o_last)
            prev_out = o_last
            next_out += 1
    lat = cfg.fifo.latency_cycles
    return {
        "nna_first_push": nna_rows[0][0],
        "sva_first_ready": in_end[min(la, h - 1)] + 1,
        "first_output_cycle": out_rows[0][0] + lat,
        "last_output_cycle": out_rows[h - 1][1] + lat,
        "period_fs": dom.period,
        "stream_ii_sva_cycles": {"nna_to_sva": ii_in, "sva_to_sink": ii_out},
    }


# ----------------------------------------------------------------------------------------------
# the paper's arithmetic


def layer_macs_per_pixel(layers) -> int:
    return sum(k * k * c_in * c_out for k, c_in, c_out in layers)


def paper_analysis(shape: tuple[int, int]) -> dict:
    """Four 3x3 layers vs one 9x9 layer (MACs, weights, feature-map memory) and float vs binary
    descriptor traffic, for a frame of ``shape`` (the paper's figures are for 1280x720)."""
    h, w = shape
    n = h * w
    channels = 32
    four, one = layer_macs_per_pixel(FOUR_LAYERS), layer_macs_per_pixel(SINGLE_LAYER)
    return {
        "macs_per_pixel": {"four_layer_3x3": four, "single_layer_9x9": one},
        "macs_per_frame": {"four_layer_3x3": four * n, "single_layer_9x9": one * n},
        "weights": {"four_layer_3x3": four, "single_layer_9x9": one},
        # the paper keeps one intermediate feature map in memory at a time (float32)
        "feature_map_bytes": {
            "four_layer_float32_frame": n * channels * 4,
            "four_layer_int8_frame": n * channels,
            # streamed instead: each 3x3 layer needs 3 rows of its input (int8)
            "four_layer_int8_line_buffers": sum(3 * w * c_in for _, c_in, _ in FOUR_LAYERS),
            "single_layer_int8_line_buffer": 9 * w,
        },
        "descriptor_bytes_per_frame": {
            "float32_32ch": n * channels * 4,
            "binary_32bit": n * channels // 8,
        },
    }


# ----------------------------------------------------------------------------------------------
# the estimate


def estimate(cfg: ChipConfig, shape: tuple[int, int]) -> dict:
    """The analytic report for one frame of ``shape`` = (H, W) (module docstring); keys follow
    the cycle report's where both have the figure."""
    h, w = shape
    tl = timeline(cfg, shape)
    work = block_work(cfg, shape)
    work_s = {name: cycles / hz for name, (cycles, hz) in work.items()}
    bottleneck = max(sorted(work_s), key=lambda n: work_s[n])
    frame_s = work_s[bottleneck]
    p_sva = tl["period_fs"]["sva"]
    fifos = fifo_plan(cfg, shape)
    dom = _Domains(cfg)
    fifo_rate = {}
    for name, f in fifos.items():
        rt_s = dom.round_trip_fs(f["src"], f["dst"]) / FS_PER_S
        fifo_rate[name] = min(f["depth"] / rt_s, dom.freq[f["src"]], dom.freq[f["dst"]])
    buffers = buffer_bits(cfg, w)
    warnings = []
    if cfg.source.kind == "camera":
        line_s = (w + cfg.source.camera_hblank) / (cfg.clocks.camera_mhz * 1e6)
        c = cycles_per_descriptor(cfg.nna)
        widest = max(t.x1 - t.x0 for t in _tiles(cfg, shape))
        if widest * c / (cfg.clocks.nna_mhz * 1e6) > line_s:
            warnings.append(
                "the NNA needs more time per row than the camera gives it: the camera will "
                "overflow the source FIFO (more nna.stereo_submodules, nna.macs or clocks.nna_mhz)"
            )
    tiles = _tiles(cfg, shape)
    if len(tiles) > 1 and cfg.nna.split == "columns":
        widest = max(t.x1 - t.x0 for t in tiles)
        if cfg.fifo.nna_to_sva_depth < widest:
            warnings.append(
                f"the merge FIFOs (fifo.nna_to_sva_depth={cfg.fifo.nna_to_sva_depth}) hold less "
                f"than a tile row ({widest} descriptors): the merge drains the tiles in raster "
                "order, so each tile waits for the others and a frame takes longer than this "
                "latency estimate (its fps is an upper bound"
                + ("; a camera can overflow while they do" if cfg.source.kind == "camera" else "")
                + f"); run the cycle model, or use a depth of at least {widest}"
            )
    if cfg.nna.line_buffer_rows < 2 * half_window(cfg.nna) + 2:
        warnings.append(
            "nna.line_buffer_rows holds only the window: a row waits for the window to move "
            "(latency estimate approximate)"
        )
    return {
        "image": {"width": w, "height": h},
        "config": config_to_dict(cfg),
        "throughput": {
            "fps": round(1.0 / frame_s, 3),
            "bottleneck": bottleneck,
            "work_ms_per_frame": {n: round(v * 1e3, 6) for n, v in sorted(work_s.items())},
            "fps_per_block": {n: round(1.0 / v, 3) for n, v in sorted(work_s.items())},
            "fifo_items_per_s": {n: round(v, 1) for n, v in sorted(fifo_rate.items())},
            # a camera's real frame rate: its whole raster, vertical blanking included
            "camera_fps": round(cfg.clocks.camera_mhz * 1e6 / ((h + cfg.source.camera_vblank)
                                * (w + cfg.source.camera_hblank)), 3)
            if cfg.source.kind == "camera" else None,
        },
        "latency": {
            "first_output_ms": tl["first_output_cycle"] * p_sva / 1e12,
            "frame_ms": tl["last_output_cycle"] * p_sva / 1e12,
            "first_output_sva_cycle": round(tl["first_output_cycle"]),
            "last_output_sva_cycle": round(tl["last_output_cycle"]),
        },
        "sram_bits": buffers,
        "sram_bits_total": {
            "nna_per_submodule": sum(v for k, v in buffers.items() if k.startswith("nna.")),
            "nna_stereo": cfg.nna.stereo_submodules
            * sum(v for k, v in buffers.items() if k.startswith("nna.")),
            "sva": sum(v for k, v in buffers.items() if k.startswith("sva.")),
            "fifos": sum(f["depth"] * f["width_bits"] for f in fifos.values()),
        },
        "fifo_sram_bits": {n: f["depth"] * f["width_bits"] for n, f in fifos.items()},
        "fifo_bytes_per_frame": {n: f["beats"] * f["width_bits"] // 8 for n, f in fifos.items()},
        "actions": action_counts(cfg, shape),
        "macs_per_frame": 2 * action_counts(cfg, shape)["nna_per_camera"]["macs"],
        "paper": paper_analysis(shape),
        "warnings": warnings,
    }


def parse_size(text: str) -> tuple[int, int]:
    """``"1280x720"`` -> (720, 1280) = (H, W); raises InputError on anything else."""

    wh = text.lower().split("x")
    if len(wh) != 2 or not all(p.strip().isdigit() for p in wh):
        raise InputError(f"size {text!r} is not WIDTHxHEIGHT, e.g. 1280x720")
    w, h = int(wh[0]), int(wh[1])
    if w < 2 or h < 1 or w * h > 1 << 26:
        raise InputError(f"size {text!r}: give at least 2x1 and at most 64 M pixels")
    return h, w


def format_estimate(est: dict) -> str:
    """The human-readable summary ``stereosim estimate`` prints."""
    img, thr, lat = est["image"], est["throughput"], est["latency"]
    sram = est["sram_bits_total"]
    lines = [
        f"estimate: {img['width']}x{img['height']}, D={est['config']['sva']['disparities']}, "
        f"{est['config']['sva']['paths']} paths, descriptor {est['config']['nna']['descriptor']}",
        f"fps {thr['fps']} (bottleneck {thr['bottleneck']}); first output "
        f"{lat['first_output_ms']:.4f} ms, frame {lat['frame_ms']:.4f} ms",
        "per block: " + ", ".join(
            f"{n} {ms:.4f} ms ({thr['fps_per_block'][n]} fps)"
            for n, ms in thr["work_ms_per_frame"].items()
        ),
        f"SRAM: NNA {sram['nna_per_submodule']} bits per submodule ({sram['nna_stereo']} for the "
        f"pair), SVA {sram['sva']} bits, FIFOs {sram['fifos']} bits",
        "FIFO bytes per frame: " + ", ".join(
            f"{n} {b}" for n, b in est["fifo_bytes_per_frame"].items()
        ),
        f"MACs per frame (both cameras): {est['macs_per_frame']}",
    ]
    p = est["paper"]
    lines.append(
        f"paper: MACs/frame four 3x3 layers {p['macs_per_frame']['four_layer_3x3']:.4g} vs one 9x9 "
        f"layer {p['macs_per_frame']['single_layer_9x9']:.4g}; feature map float32 "
        f"{p['feature_map_bytes']['four_layer_float32_frame'] / 1e6:.1f} MB; descriptors float32 "
        f"{p['descriptor_bytes_per_frame']['float32_32ch'] / 1e6:.1f} MB vs binary "
        f"{p['descriptor_bytes_per_frame']['binary_32bit'] / 1e6:.2f} MB per frame"
    )
    lines += [f"warning: {m}" for m in est["warnings"]]
    return "\n".join(lines)
