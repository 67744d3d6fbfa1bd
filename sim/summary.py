"""The summaries ``stereosim run``, ``eval`` and ``estimate`` print, built from their reports.

A run's summary is a few tables drawn with ``rich``: the run (scene, size, D, descriptor,
paths, wall time), throughput and latency (the work bound and the measured rate named as such,
every time with its unit, a stream's span apart from its frames' latencies), each block's
cycles in its own clock domain with the share of them it was busy, starved, blocked and idle,
the energy and the accuracy (a stream's: the mean over its frames). On a terminal the tables
have colour; anywhere else (a pipe, a file, a test) they are plain text 100 columns wide, the
same bytes for the same report. The eval table (``stereosim eval``) is plain aligned text
(:func:`sim.metrics.format_table`); in cycle mode it adds each scene's frame rates, latency and
bottleneck. The estimate's text (:func:`format_estimate`) is lines of ``key: figures``, from
:func:`sim.cycle.estimate.estimate`'s dict.
"""

from __future__ import annotations

import io
import math
import shutil
import sys
from collections.abc import Mapping, Sequence

from rich import box
from rich.console import Console
from rich.table import Table

from stereosim.core.config.backend import describe
from stereosim.sim.cycle.area import area_lines, area_rows
from stereosim.sim.cycle.lent import lent_lines
from stereosim.sim.metrics import DENSE_KEYS, format_table, mean_metrics
from stereosim.sim.plot import RATE_GAP

WIDTH = 100  # columns of the plain-text summary
ACTIVITIES = ("busy", "starved", "blocked", "idle")
# stereosim eval --mode cycle: the timing columns of each scene (report.json keys, flattened)
TIMING_KEYS = ("fps_bound", "fps_measured", "first_output_us", "frame_ms", "bottleneck")
# what the blocks table's two measures of a block's load mean (they differ: the SVA holds a
# word in its pipeline for its latency, longer than the II its work counts)
BLOCKS_CAPTION = ("busy %: cycles the block held work (the SVA: any word in its pipeline, its "
                  "fill and drain included); work ms: the cycles its critical resource is "
                  "occupied (NNA: its MAC array; SVA: words x its II), the figure that bounds "
                  "the frame rate")


# ---- formatting -------------------------------------------------------------------------------


def _fps(value) -> str:
    return "-" if value is None else f"{value:,.1f}"


def _energy(uj: float) -> str:
    """Energy in uJ, or in mJ from 1,000 uJ on."""
    return f"{uj / 1e3:,.3f} mJ" if uj >= 1e3 else f"{uj:,.3f} uJ"


def _int(value) -> str:
    return f"{int(value):,}"


def _pairs_table(title: str) -> Table:
    """A two-column table: what, value."""
    t = Table(title=title, title_justify="left", box=None, show_header=False, pad_edge=False)
    t.add_column("what", style="bold", no_wrap=True)
    t.add_column("value")
    return t


def render(tables: Sequence[Table], *, terminal: bool | None = None) -> str:
    """The tables as text: plain (no colour, ``WIDTH`` columns, ASCII rules) unless
    ``terminal`` (default: whether stdout is a terminal)."""
    if terminal is None:
        terminal = sys.stdout.isatty()
    buf = io.StringIO()
    if terminal:
        console = Console(file=buf, force_terminal=True, highlight=False, emoji=False,
                          width=shutil.get_terminal_size((WIDTH, 24)).columns)
    else:
        console = Console(file=buf, force_terminal=False, width=WIDTH, color_system=None,
                          no_color=True, highlight=False, emoji=False, legacy_windows=False)
    for i, t in enumerate(tables):
        if not terminal and t.show_header:
            t.box = _PLAIN_HEAD
        if i:
            console.print()
        console.print(t)
    return "\n".join(line.rstrip() for line in buf.getvalue().splitlines()) + "\n"


# a header rule of ASCII dashes and nothing else: plain text that reads like the eval table
_PLAIN_HEAD = box.Box("    \n    \n -- \n    \n    \n    \n    \n    \n", ascii=True)


# ---- one frame (and the common parts of a stream) ------------------------------------------------


def _run_rows(report: dict, seconds: float, t: Table) -> None:
    img, cfg = report["image"], report["config"]
    scene = report.get("scene")
    if scene:
        t.add_row("scene", f"{scene['name']} ({scene['source']})")
    engine = f" ({report['engine']} engine)" if report.get("engine") else ""
    t.add_row("mode", f"{report['mode']}{engine}")
    frames = f", {report['frames']} frames" if "frames" in report else ""
    t.add_row("size", f"{img['width']} x {img['height']} pixels{frames}")
    t.add_row("disparities D", str(cfg["sva"]["disparities"]))
    t.add_row("descriptor", _descriptor(report["descriptor"]))
    weights = _weights(report["descriptor"])
    if weights:
        t.add_row("matching cost", weights)
    backend = report["descriptor"].get("backend")
    if backend:
        changed = backend["changed"]
        t.add_row("SVA back end", f"{describe(backend)}: {backend['tuned_with']}"
                  + (f", but for {', '.join(changed)} (set by the configuration)" if changed
                     else ""))
    t.add_row("SGM paths", str(cfg["sva"]["paths"]))
    t.add_row("wall time", f"{seconds:.2f} s")
    out = report.get("output", {})
    if "invalid_percent" in out:
        t.add_row("valid pixels", f"{100 - out['invalid_percent']:.2f} %")
    elif "last_frame_invalid_percent" in out:
        t.add_row("valid pixels (last frame)", f"{100 - out['last_frame_invalid_percent']:.2f} %")


def _weights(d: dict) -> str:
    """The hybrid's cost: ``3 x cnn + 1 x census, largest 128 (13-bit box sums); automatic:
    frame noisy (statistic 40.2 > 31): 2 x cnn + 0 x census``; "" for one part."""
    w = d.get("weights")
    if not w:
        return ""
    kinds = [p["kind"] for p in d["parts"]]

    def cost(ws):
        return " + ".join(f"{x} x {k}" for x, k in zip(ws, kinds, strict=True))

    text = f"{cost(w['cost_weights'])}, largest {d['cost_max']} ({d['cost_bits']}-bit box sums)"
    frames = [d["frame"]] if "frame" in d else d.get("frames", [])
    if w["mode"] == "auto":
        text += f"; automatic, noisy frames {cost(w['noisy_weights'])}"
        noisy = [f for f in frames if f.get("noise", {}).get("noisy")]
        if "frame" in d:
            n = d["frame"]["noise"]
            text += (f"; this frame {'noisy' if n['noisy'] else 'clean'} (statistic "
                     f"{n['mean']:.1f} {'>' if n['noisy'] else '<='} {n['threshold']})")
        elif frames:
            text += f"; {len(noisy)} of {len(frames)} frames noisy"
    return text


def _descriptor(d: dict) -> str:
    """``cnn: mixed5x5-wide-n6.int8 (5x5x1x32, 3x3x32x32, ...; 19,232 MACs a pixel), 32 bits``."""
    net = d.get("network")
    if not net:
        return f"{d['kind']} ({d['bits']} bits)"
    bits = f"{d['bits']} bits"
    census = next((p for p in d.get("parts", []) if p["kind"] == "census"), None)
    if census:  # the hybrid: the network's bits beside the census's
        bits = (f"{d['bits']} bits = {d['parts'][0]['bits']} cnn + {census['bits']} census "
                f"{census['window'][0]}x{census['window'][1]} {census['census_kind']}")
    return (f"{d['kind']}: {net['name']} ({len(net['layers'])} layer"
            f"{'s' if len(net['layers']) > 1 else ''} {', '.join(net['layers'])}; "
            f"{net['macs_per_pixel']:,} MACs a pixel), {bits}")


def _measured(st: dict) -> str:
    """Frames completed, the sustained rate and the drops of a stream (or of one pair's)."""
    fps = st["sustained_fps"]
    dropped = st["dropped_frames"]
    shown = ", ".join(str(f) for f in dropped[:10])
    if len(dropped) > 10:
        shown += f", ... {len(dropped) - 10} more"
    rate = f"sustained {fps:,.3f} fps" if fps else "one frame"
    return (f"{st['frames_completed']} of {st['frames']} frames completed, {rate}, "
            f"{len(dropped)} dropped{' (frames ' + shown + ')' if dropped else ''}")


def _latency_ms(st: dict) -> str:
    lat = st.get("latency_ms", {})
    return (f"min {lat.get('min', 0):.3f} / median {lat.get('median', 0):.3f} / p99 "
            f"{lat.get('p99', 0):.3f} / max {lat.get('max', 0):.3f} ms")


def _throughput_table(report: dict) -> Table:
    thr, lat = report["throughput"], report["latency"]
    t = _pairs_table("throughput and latency")
    st = report.get("stream", {})
    if st.get("frames", 1) > 1:
        t.add_row("stream, measured", _measured(st))
        t.add_row("latency per frame, measured", _latency_ms(st))
    for p in st.get("pairs", ()):
        t.add_row(f"camera pair {p['pair']}", f"{_measured(p)}; latency {_latency_ms(p)}")
    t.add_row("work bound (fps)", f"{_fps(thr['fps_bound'])} (the busiest block's work alone: "
              "a bound)")
    alone = "first frame alone" if st.get("frames", 1) > 1 else "one frame alone"
    t.add_row(f"{alone}, measured (fps)", _fps(thr.get("fps_measured")))
    t.add_row("bottleneck", thr["bottleneck"])
    cyc = report["cycles"]
    t.add_row("cycles per clock domain", ", ".join(
        f"{d} {_int(n)} @ {cyc['clock_mhz'][d]:g} MHz" for d, n in cyc["total"].items()))
    t.add_row("first output latency", f"{lat['first_output_us']:,.3f} us (first input pixel "
              "-> first disparity)")
    if "frame_ms" in lat:  # one frame: its span is its latency
        t.add_row("frame latency", f"{lat['frame_ms']:,.3f} ms (first input pixel -> last "
                  "disparity)")
    else:  # a stream: its span, not a frame's latency (that is the row per frame above)
        t.add_row("stream span", f"{st['span_ms']:,.3f} ms (first input pixel -> the last "
                  "frame's last disparity)")
    if "dram" in report and report["dram"].get("read_bound_fps"):
        d = report["dram"]
        used = "-" if d["utilisation"] is None else f"{100 * d['utilisation']:.1f} %"
        t.add_row("DRAM", f"{used} of {d['peak_gbps']} GB/s used; its read slots bound "
                  f"{_fps(d['read_bound_fps'])} fps")
    slow = thr.get("fps_measured")
    bound = thr["fps_bound"]
    camera = thr.get("camera_fps")
    if camera:
        t.add_row("camera (fps)", f"{_fps(camera)} (its pixel clock over the whole raster, "
                  "blanking included: no stream from it is faster)")
    if slow and camera and slow > camera and st.get("frames", 1) == 1:
        t.add_row("note", f"one frame alone measures {_fps(slow)} fps, above the camera's "
                  f"{_fps(camera)}: a lone frame skips the vertical blanking between frames; "
                  "a stream (--frames N) measures the rate the chip sustains")
    elif slow and bound and abs(slow / bound - 1) > RATE_GAP and st.get("frames", 1) == 1:
        t.add_row("note", f"one frame alone runs at {_fps(slow)} fps, {abs(slow / bound - 1):.0%} "
                  f"off the {_fps(bound)} fps work bound (the pipeline's fill, and blocks "
                  "waiting on each other: the blocked column below)")
    return t


def _blocks_table(report: dict) -> Table:
    """Each block's cycles in its clock domain, and what share of them it spent how."""
    work = report["throughput"].get("work_ms_per_frame", {})
    t = Table(title="blocks (cycles of each block's own clock, % of them, work per frame)",
              title_justify="left", caption=BLOCKS_CAPTION, caption_justify="left",
              box=box.SIMPLE_HEAD, pad_edge=False, show_edge=False)
    t.add_column("block", no_wrap=True)
    t.add_column("clock", no_wrap=True)
    t.add_column("cycles", justify="right")
    for a in ACTIVITIES:
        t.add_column(f"{a} %", justify="right")
    t.add_column("work ms", justify="right")
    for name, b in report["blocks"].items():
        pct = b["percent"]
        t.add_row(name, f"{b['clock_domain']} @ {b['clock_mhz']:g} MHz", _int(b["cycles_total"]),
                  *(f"{pct[a]:.2f}" for a in ACTIVITIES),
                  f"{work[name]:.4f}" if name in work else "-")
    return t


def _chip_table(report: dict) -> Table:
    """The chip's totals a user can quote: its SRAM (every submodule instance, by block), and
    the lent network's rate and DRAM load."""
    t = _pairs_table("chip")
    sram = report["architecture"]["chip_sram"]
    parts = ", ".join(f"{k} {v / 1e6:,.2f}" for k, v in sram["by_block"].items() if v)
    t.add_row("SRAM", f"{sram['total'] / 1e6:,.2f} Mbit ({sram['total']:,} bits): {parts} "
              f"Mbit; each of the {sram['nna_submodules']} NNA submodules "
              f"{sram['nna_per_submodule']:,} bits")
    lent = report.get("lent_network")
    if lent:
        t.add_row("lent network", f"{lent['file']}: {lent['fps']:,.3f} fps (at most "
                  f"{lent['fps_max']:,.3f}) on {lent['submodules_used']} of "
                  f"{lent['submodules_lent']} lent submodules; DRAM "
                  f"{lent['dram_bytes_per_frame']['total']:,} bytes a frame, "
                  f"{lent['dram_gbps']:,.3f} GB/s")
    return t


def _area_table(area: dict) -> Table:
    """The chip's area and leakage at the configured node (:func:`~sim.cycle.area.area_rows`)."""
    t = _pairs_table(f"area ({area['node']}; logic from the RTL twin's synthesis, SRAM macros)")
    for what, figures in area_rows(area):
        t.add_row(what, figures)
    return t


def _energy_table(energy: dict) -> Table:
    e = energy["per_frame_uj"]
    t = _pairs_table(f"energy ({energy['table']['node']})")
    t.add_row("per frame", _energy(e["total"]))
    t.add_row("by block", ", ".join(f"{k} {_energy(v)}" for k, v in e["by_block"].items() if v))
    if energy["power_mw"] is not None:
        t.add_row("average power", f"{energy['power_mw']:,.1f} mW at "
                  f"{_fps(energy['power_at_fps'])} fps, {energy['fps_basis']}")
    return t


def _power_table(power: dict) -> Table:
    """The run's power from its own activity (:func:`~sim.cycle.power.power_report`)."""
    t = _pairs_table(f"power ({power['node']}; clock gating {power['clock_gating']}, unused "
                     f"submodules {'gated' if power['gate_unused'] else 'on'})")
    e = power["per_frame_pj"]
    t.add_row("per frame", f"{_energy(power['energy_per_frame_uj'])}: dynamic "
              f"{_energy(e['dynamic'] / 1e6)}, clock {_energy(e['clock'] / 1e6)}, leakage "
              f"{_energy(e['leakage'] / 1e6)}")
    avg = power["average_power_mw"]
    t.add_row("power", ("-" if avg is None else f"average {avg:,.1f} mW")
              + f", peak {power['peak_power_mw']:,.1f} mW ({power['peak_window']}), leakage "
              f"{power['leakage_power_mw']:,.1f} mW")
    return t


def _metrics_table(metrics: dict, frames: int | None = None) -> Table:
    """The accuracy per mask: of the frame, or the mean over a stream's ``frames``."""
    what = "accuracy" if frames is None else f"accuracy, mean of {frames:,} frames"
    title = f"{what} (thresholds in pixels of the GT's resolution)"
    t = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False,
              show_edge=False, min_width=len(title))  # the title on one line
    cols = (("bad2", "bad2 %"), ("invalid", "invalid %"), ("totbad", "totbad %"),
            ("avgerr", "avgerr px"), ("rms", "rms px"))
    t.add_column("mask", no_wrap=True)
    for _, head in cols:
        t.add_column(head, justify="right")
    for mask, m in metrics.items():
        t.add_row(mask, *(_metric(m.get(k)) for k, _ in cols))
    return t


def _metric(value) -> str:
    return "-" if value is None or math.isnan(value) else f"{value:.3f}"


def summary_tables(report: dict, seconds: float) -> list[Table]:
    """The tables of a run's summary (one frame or a stream), from its report."""
    run = _pairs_table(f"stereosim {report['mode']}" + (" stream" if "frames" in report else ""))
    _run_rows(report, seconds, run)
    tables = [run]
    if "throughput" in report:
        tables += [_throughput_table(report), _blocks_table(report)]
    if "chip_sram" in report.get("architecture", {}):
        tables.append(_chip_table(report))
    if "area" in report:
        tables.append(_area_table(report["area"]))
    if "energy" in report:
        tables.append(_energy_table(report["energy"]))
    if "power" in report:
        tables.append(_power_table(report["power"]))
    if report.get("metrics"):
        tables.append(_metrics_table(report["metrics"]))
    if report.get("metrics_mean"):
        tables.append(_metrics_table(report["metrics_mean"], len(report["metrics_per_frame"])))
    return tables


def summary_text(report: dict, seconds: float, *, terminal: bool | None = None) -> str:
    """A run's summary as text (plain unless ``terminal``; default: stdout is a terminal)."""
    return render(summary_tables(report, seconds), terminal=terminal)


def print_summary(report: dict, seconds: float) -> None:
    sys.stdout.write(summary_text(report, seconds))


# ---- stereosim estimate ------------------------------------------------------------------------


def sram_lines(chip: dict) -> list[str]:
    """The chip's SRAM total (:func:`~sim.cycle.figures.chip_sram`), by block and by kind."""
    by_block = ", ".join(f"{k} {v:,}" for k, v in chip["by_block"].items() if v)
    by_kind = ", ".join(f"{k} {v:,}" for k, v in chip["by_kind"].items() if v)
    return [f"chip SRAM: {chip['total']:,} bits ({chip['total'] / 1e6:.2f} Mbit; "
            f"{chip['nna_submodules']} NNA submodules of {chip['nna_per_submodule']:,} bits "
            f"each); by block: {by_block}",
            f"chip SRAM by kind: {by_kind}"]


def energy_lines(energy: dict) -> list[str]:
    """Energy a frame by block and the power at the delivered rate
    (:func:`~sim.cycle.energy.estimate_energy`)."""
    per = energy["per_frame_uj"]
    blocks = ", ".join(f"{k} {v / 1e3:.3f}" for k, v in per["by_block"].items())
    return [f"energy: {per['total'] / 1e3:.3f} mJ a frame ({blocks} mJ); power "
            f"{energy['power_mw'] / 1e3:.3f} W at {energy['power_at_fps']:g} fps "
            f"({energy['fps_basis']}; table: {energy['table']['node']})"]


def format_estimate(est: dict) -> str:
    """The human-readable summary ``stereosim estimate`` prints."""
    img, thr, lat = est["image"], est["throughput"], est["latency"]
    sram = est["sram_bits_total"]
    lines = [
        f"estimate: {img['width']}x{img['height']}, D={est['config']['sva']['disparities']}, "
        f"{est['config']['sva']['paths']} paths, descriptor {est['config']['nna']['descriptor']}",
        f"work bound {thr['fps_bound']} fps (bottleneck {thr['bottleneck']}); latency: first "
        f"output {lat['first_output_us']:.3f} us, frame {lat['frame_ms']:.4f} ms",
        "work per frame by block: " + ", ".join(
            f"{n} {ms:.4f} ms (bound {thr['fps_bound_per_block'][n]} fps)"
            for n, ms in thr["work_ms_per_frame"].items()
        ),
        f"delivered {thr['fps_delivered']} fps: {thr['fps_delivered_basis']}",
        f"SRAM: NNA {sram['nna_per_submodule']} bits per submodule ({sram['nna_stereo']} for the "
        f"pair), SVA {sram['sva']} bits, FIFOs {sram['fifos']} bits",
        *sram_lines(est["chip_sram"]),
        *energy_lines(est["energy"]),
        *(area_lines(est["area"]) if "area" in est else ()),
        "FIFO bytes per frame: " + ", ".join(
            f"{n} {b}" for n, b in est["fifo_bytes_per_frame"].items()
        ),
        f"MACs per frame (both cameras): {est['macs_per_frame']}",
    ]
    for lay in est.get("nna_layers", ()):
        lines.append(
            f"NNA layer {lay['layer']}: {lay['kernel']}x{lay['kernel']}x{lay['channels_in']}"
            f"x{lay['channels_out']}, {lay['macs_per_pixel']} MACs a pixel on "
            f"{lay['mac_share']} MACs: {lay['cycles_per_pixel']} cycles a pixel; line buffer "
            f"{lay['line_buffer_rows']} rows, {lay['line_buffer_bits']} bits")
    if "lent_network" in est:
        lines += lent_lines(est["lent_network"])
    need = thr.get("submodules_for_camera")
    if need is not None:
        lines.append(
            f"to keep up with the camera's {need['fps']:g} fps: nna.stereo_submodules = "
            f"{need['stereo_submodules']} ({need['per_camera']} a camera; the NNA then bounds "
            f"{need['nna_fps']:g} fps), nna.submodules >= {need['submodules']}"
            + (f", fifo.nna_to_merge_depth >= {need['merge_depth_needed']}"
               if need["merge_depth_needed"] is not None else ""))
    elif thr.get("camera_fps") is not None:
        lines.append(f"no nna.stereo_submodules up to the key's largest keeps up with the "
                     f"camera's {thr['camera_fps']:g} fps at this frame size")
    if thr["merge_depth_needed"] is not None:
        lines.append(
            f"merge FIFOs: fifo.nna_to_merge_depth = "
            f"{est['config']['fifo']['nna_to_merge_depth']}; the column tiles reach the work "
            f"bound from {thr['merge_depth_needed']} on"
        )
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


# ---- stereosim eval ------------------------------------------------------------------------------


def eval_timing(report: dict) -> dict | None:
    """A scene's cycle figures for the eval table (None in functional mode)."""
    if "throughput" not in report:
        return None
    thr, lat = report["throughput"], report["latency"]
    return {"fps_bound": thr["fps_bound"], "fps_measured": thr.get("fps_measured"),
            "first_output_us": round(lat["first_output_us"], 6),
            "frame_ms": round(lat["frame_ms"], 6), "bottleneck": thr["bottleneck"]}


def eval_line(name: str, metrics: dict, timing: dict | None = None) -> str:
    """The line ``stereosim eval`` prints when a scene is done."""
    parts = [f"{mask} totbad {m['totbad']:.2f} bad2 {m['bad2']:.2f}" for mask, m in
             metrics.items()]
    if timing:
        parts.append(f"work bound {_fps(timing['fps_bound'])} fps, one frame measured "
                     f"{_fps(timing['fps_measured'])} fps, frame {timing['frame_ms']:.3f} ms "
                     f"(bottleneck {timing['bottleneck']})")
    return f"{name}: " + "; ".join(parts)


def _timing_summary(timings: list[dict]) -> dict:
    """The mean of each timing figure over the scenes, and the total frame time."""
    out: dict = {}
    for key in ("fps_bound", "fps_measured", "first_output_us", "frame_ms"):
        values = [t[key] for t in timings if t.get(key) is not None]
        out[key] = round(sum(values) / len(values), 6) if values else None
    return {"mean": out, "total_frame_ms": round(sum(t["frame_ms"] for t in timings), 6)}


def eval_document(dataset: str, rows: Sequence[tuple], failed: Mapping[str, str]) -> dict:
    """What ``stereosim eval --json`` prints and ``--out`` writes; ``rows``: (scene, metrics,
    D, timing or None) per scored scene."""
    scenes = {}
    for name, m, d, timing in rows:
        scenes[name] = {"disparities": d, "metrics": m}
        if timing:
            scenes[name]["timing"] = timing
    scenes.update({name: {"error": reason, "metrics": None} for name, reason in failed.items()})
    doc = {"dataset": dataset, "scenes": scenes,
           "mean": mean_metrics([m for _, m, _, _ in rows]), "failed": len(failed)}
    timings = [t for *_, t in rows if t]
    if timings:
        doc["timing"] = _timing_summary(timings)
    return doc


def eval_tables(rows: Sequence[tuple], keys: Sequence[str]) -> str:
    """The tables ``stereosim eval`` prints at the end: the metrics per mask and, in cycle
    mode, the frame rates, latency and bottleneck of each scene with their mean (and the total
    frame time)."""
    out = []
    for mask in ("nonocc", "all"):
        table_rows = [(name, m[mask]) for name, m, _, _ in rows if mask in m]
        if table_rows:
            out.append(f"\n[{mask}]  (thresholds in pixels of the GT's resolution)\n")
            out.append(format_table(table_rows, keys))
    for mask in ("nonocc", "all"):  # the paper's table also scores the map made dense
        table_rows = [(name, m[mask]) for name, m, _, _ in rows
                      if mask in m and "dense_bad2" in m[mask]]
        if table_rows:
            out.append(f"\n[{mask}, dense]  (invalid pixels filled from their row's nearest "
                       "valid neighbours, the lower one, as Middlebury scores sparse results)\n")
            out.append(format_table(table_rows, [f"dense_{k}" for k in DENSE_KEYS]))
    timed = [(name, t) for name, _, _, t in rows if t]
    if timed:
        out.append("\n[cycle]  (work bound and one frame alone, measured, in fps; latency from "
                   "the first input pixel)\n")
        out.append(format_table(timed, TIMING_KEYS, totals=("frame_ms",)))
    return "".join(out)
