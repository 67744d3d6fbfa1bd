"""The guide to a sweep's ``results.csv``: what each column is, its unit, its clock domain and
whether a rate is a work bound or a measurement.

``results.csv`` flattens one report per point x scene (docs/report.md lists the report's keys;
:func:`sim.sweep.flatten`), so it has hundreds of columns. :func:`guide_text` describes the
columns of a header, grouped, as Markdown; a sweep writes it beside the CSV as ``columns.md``
(:data:`sim.sweep_results.GUIDE_NAME`). Each column is described by the first rule of
:data:`RULES` its name matches, with the block's or FIFO's clock domain read from the rows
themselves; a configuration key gets the help text it is declared with (:mod:`core.config`). A
column no rule describes is listed under "not described" -- tests/sim/test_columns.py runs small
sweeps of every mode and requires that none is, and that every rule still describes some column,
so the guide cannot drift from the keys the reports have.
"""

from __future__ import annotations

import dataclasses
import functools
import re

from stereosim.core.config import load_config

# the groups of the guide, in the order it lists them
GROUPS = (
    "the run",
    "swept keys",
    "keys the sweep file sets",
    "frame rate",
    "latency",
    "accuracy",
    "SRAM",
    "silicon",
    "blocks",
    "FIFOs",
    "buffers",
    "SVA stages",
    "cycles",
    "stream",
    "energy",
    "DRAM",
    "lent network",
    "architecture",
    "analytic estimate",
    "output and report",
    "configuration",
    "not described",
)

ACTIVITY = {
    "busy": "busy (working)",
    "starved": "starved (waiting for input)",
    "blocked": "blocked (holding an output it cannot hand on)",
    "idle": "idle (nothing left to do)",
}

# the parts of the lent network's DRAM bytes a frame (sim.cycle.lent.LentPlan.bytes_per_frame)
LENT_BYTES = {
    "input": "its input, read",
    "output": "its last layer's output, written",
    "spill": "the feature maps of layers that do not fit on chip, written and read back",
    "weights": "weights read each frame (those of a submodule whose weight store cannot hold "
    "them; 0 when every submodule's fit)",
    "total": "input + output + spill + weights",
}

MEASURED = "**measured** by the cycle model"
BOUND = "**work bound** (the busiest block's work alone; not a measurement)"

# (pattern, group, description): the first pattern that matches a column describes it. The
# description is formatted with the pattern's named groups and, for a block or FIFO, ``dom``
# (its clock domain and clock, read from the rows); ``act`` is the activity's meaning, ``how``
# how a figure that both models give was obtained.
RULES: tuple[tuple[str, str, str], ...] = (
    (r"point", "the run", "the point's number in the sweep's grid (the same on every scene)"),
    (r"scene", "the run", "the scene: default, WxH (a synthetic pair) or a scene folder"),
    (r"status", "the run", "ok, or error (then see error)"),
    (r"error", "the run", "why the run failed, in one line; empty when ok"),
    (r"point_id", "the run", "a hash of scene, mode and overrides: a rerun skips the ids "
     "already ok"),
    (r"throughput\.fps_bound", "frame rate", f"frames/s, {BOUND}: 1 / the busiest block's work "
     "time per frame; it assumes no block waits on another"),
    (r"throughput\.fps_measured", "frame rate", f"frames/s, {MEASURED}, one frame alone: 1 / "
     "(first input pixel -> the frame's last output word); below fps_bound when blocks wait "
     "on each other. The sweep's plots and its Pareto front use it"),
    (r"throughput\.bottleneck", "frame rate", "the block with the most work time per frame "
     "(the one that sets fps_bound)"),
    (r"throughput\.work_ms_per_frame\.(?P<b>.+)", "frame rate", "ms: {b}'s work per frame "
     "(the time its busy resource needs, the figure behind the bound)"),
    (r"throughput\.fps_bound_per_block\.(?P<b>.+)", "frame rate", f"frames/s, {BOUND} of {{b}} "
     "alone"),
    (r"throughput\.camera_fps", "frame rate", "frames/s: the camera's own rate (its whole "
     "raster, blanking included); empty without a camera"),
    (r"throughput\.fifo_items_per_s\.(?P<f>.+)", "frame rate", "items/s {f} can move (its "
     "depth per round trip; analytic)"),
    (r"throughput\.fps_delivered", "frame rate", "frames/s the chip delivers (analytic: the "
     "work bound, the camera's rate when the camera is the bottleneck, fewer with one frame "
     "buffer); the estimate's power is given at it"),
    (r"throughput\.fps_delivered_basis", "frame rate", "why fps_delivered is that rate"),
    (r"throughput\.submodules_for_camera\.(?P<k>stereo_submodules|per_camera|submodules)",
     "frame rate", "with a camera: the {k} of the least even nna.stereo_submodules whose NNA "
     "work bound reaches the camera's rate (analytic; empty when none does)"),
    (r"throughput\.submodules_for_camera\.(?P<k>fps|nna_fps|merge_depth_needed)", "frame rate",
     "with a camera: at that count, its {k} (the camera's rate, the NNA's work bound, the "
     "merge depth its column tiles need; analytic)"),
    (r"throughput\.submodules_for_camera", "frame rate", "empty: no camera, so no rate to "
     "keep up with"),
    (r"throughput\.merge_depth_needed", "frame rate", "descriptors: the least "
     "fifo.nna_to_merge_depth at which column tiles reach fps_bound (analytic; empty without "
     "column tiles)"),
    (r"latency\.first_output_us", "latency", "us from the first input pixel (t = 0) to the "
     "first disparity word ({how})"),
    (r"latency\.frame_ms", "latency", "ms from the first input pixel to the last disparity "
     "word ({how})"),
    (r"latency\.(?P<which>first|last)_output_sva_cycle", "latency", "SVA cycle of the sink's "
     "{which} pop (analytic)"),
    (r"cycles\.total\.(?P<d>.+)", "cycles", "cycles of the {d} clock the run took (measured)"),
    (r"cycles\.clock_mhz\.(?P<d>.+)", "cycles", "MHz: the {d} clock"),
    (r"cycles\.(?P<which>first|last)_output\.sva", "cycles", "SVA cycle of the sink's {which} "
     "pop (measured)"),
    (r"cycles\.(?P<which>first|last)_output\.time_(?P<u>us|ms)", "cycles", "{u}: the sink's "
     "{which} pop, from t = 0 (measured)"),
    (r"blocks\.(?P<b>[^.]+)\.(?P<a>busy|starved|blocked|idle)", "blocks", "cycles of {dom} in "
     "which {b} was {act}; measured"),
    (r"blocks\.(?P<b>[^.]+)\.cycles_total", "blocks", "cycles of {dom} over the run (busy + "
     "starved + blocked + idle)"),
    (r"blocks\.(?P<b>[^.]+)\.percent\.(?P<a>busy|starved|blocked|idle)", "blocks", "% of {b}'s "
     "cycles in which it was {act}"),
    (r"blocks\.(?P<b>[^.]+)\.clock_domain", "blocks", "the clock domain {b}'s cycles count in"),
    (r"blocks\.(?P<b>[^.]+)\.clock_mhz", "blocks", "MHz: {b}'s clock"),
    (r"fifos\.(?P<f>[^.]+)\.depth", "FIFOs", "entries {f} holds"),
    (r"fifos\.(?P<f>[^.]+)\.width_bits", "FIFOs", "bits per entry of {f}"),
    (r"fifos\.(?P<f>[^.]+)\.(?P<op>pushes|pops)", "FIFOs", "items of {f}: {op} over the run"),
    (r"fifos\.(?P<f>[^.]+)\.bits_transferred", "FIFOs", "bits moved through {f}"),
    (r"fifos\.(?P<f>[^.]+)\.max_occupancy", "FIFOs", "the most items {f} held (measured)"),
    (r"fifos\.(?P<f>[^.]+)\.max_producer_occupancy", "FIFOs", "the most slots {f}'s producer "
     "saw taken, freed slots not yet seen included: the depth this run used (measured)"),
    (r"fifos\.(?P<f>[^.]+)\.cycles_full", "FIFOs", "cycles of {dom} (its producer's) in which "
     "{f} was full (measured)"),
    (r"fifos\.(?P<f>[^.]+)\.cycles_empty", "FIFOs", "cycles of {dom} (its consumer's) in which "
     "{f} was empty (measured)"),
    (r"fifos\.(?P<f>[^.]+)\.(?P<end>producer|consumer)_domain", "FIFOs", "the clock domain of "
     "{f}'s {end}"),
    (r"fifo_bytes_per_frame\.(?P<f>.+)", "FIFOs", "bytes per frame through {f}"),
    (r"fifo_sram_bits\.(?P<f>.+)", "SRAM", "bits of SRAM of {f} (depth x width)"),
    (r"buffers\.(?P<b>[^.]+)\.(?P<buf>.+)\.capacity_(?P<u>bits|rows|words)", "buffers",
     "{u}: the capacity of {buf} in {b}"),
    (r"buffers\.(?P<b>[^.]+)\.(?P<buf>.+)\.peak_(?P<u>bits|rows|words)", "buffers", "{u}: the "
     "most {buf} in {b} held (measured)"),
    (r"sva_stages\.(?P<s>[^.]+)\.(?P<a>busy|starved|blocked|idle)", "SVA stages", "cycles of "
     "the sva clock in which the {s} stage was {act}; measured"),
    (r"sva_stages\.(?P<s>[^.]+)\.capacity_words", "SVA stages", "words the {s} stage holds"),
    (r"sva_stages\.(?P<s>[^.]+)\.peak_words", "SVA stages", "the most words the {s} stage "
     "held (measured)"),
    (r"sva_stages\.(?P<s>[^.]+)\.utilization_percent", "SVA stages", "% of the run's sva "
     "cycles in which the {s} stage was busy"),
    (r"sram_bits", "SRAM", "bits of the chip's SRAM: NNA buffers x stereo submodules + SVA "
     "buffers + FIFOs (from the chip plan; what the Pareto plot's x axis shows)"),
    (r"(architecture\.)?sram_bits\.(?P<buf>.+)", "SRAM", "bits of SRAM of the buffer {buf} "
     "(one instance)"),
    (r"(architecture\.)?sram_bits_total\.nna_per_submodule", "SRAM", "bits of SRAM of one NNA "
     "submodule"),
    (r"(architecture\.)?sram_bits_total\.nna_stereo", "SRAM", "bits of SRAM of every stereo "
     "NNA submodule together"),
    (r"(architecture\.)?sram_bits_total\.sva", "SRAM", "bits of SRAM of the SVA"),
    (r"(architecture\.)?sram_bits_total\.fifos", "SRAM", "bits of SRAM of every FIFO"),
    (r"(architecture\.)?chip_sram\.total", "SRAM", "bits of the chip's SRAM, every instance "
     "counted once: all nna.submodules NNA submodules (stereo, lent or idle, each sized for the "
     "widest tile), the SVA's buffers and every FIFO (the figure to quote for the chip)"),
    (r"(architecture\.)?chip_sram\.nna_per_submodule", "SRAM", "bits of SRAM of one NNA "
     "submodule instance"),
    (r"(architecture\.)?chip_sram\.nna_submodules", "SRAM", "NNA submodule instances on the "
     "chip (nna.submodules)"),
    (r"(architecture\.)?chip_sram\.nna_instances\.(?P<use>.+)", "SRAM", "NNA submodule "
     "instances of the use {use} (stereo pair, lent, idle)"),
    (r"(architecture\.)?chip_sram\.by_block\.(?P<blk>.+)", "SRAM", "bits of the chip's SRAM "
     "in {blk}"),
    (r"(architecture\.)?chip_sram\.by_kind\.(?P<kind>.+)", "SRAM", "bits of the chip's SRAM "
     "of the kind {kind}, every instance counted"),
    (r"area_mm2", "silicon", "mm^2: the chip's area at power.node, logic + SRAM macros "
     "(sim.cycle.area.chip_area; no wires, clock tree or pads; docs/area.md); empty where the "
     "node has no SRAM figure. A Pareto axis (stereosim plot --x area_mm2)"),
    (r"logic_mm2", "silicon", "mm^2: the chip's logic at power.node (the RTL twin's gate "
     "equivalents and flip-flops; blocks without RTL or a checked area rule not costed)"),
    (r"power_mw", "silicon", "mW: the chip's average power over the run (the report's "
     "power.average_power_mw, sim.cycle.power; a cycle run's only; docs/energy.md). A Pareto "
     "axis (stereosim plot --pareto --x power_mw)"),
    (r"sram_mm2", "silicon", "mm^2: the chip's SRAM macros at power.node; empty where the "
     "node has no SRAM figure"),
    (r"(architecture\.)?silicon\.library", "silicon", "the standard-cell library of the RTL "
     "twin's synthesis figures (docs/rtl-synth.md)"),
    (r"(architecture\.)?silicon\.table", "silicon", "the cached synthesis table the figures "
     "come from (a run never synthesises)"),
    (r"(architecture\.)?silicon\.config\.(?P<key>.+)", "silicon", "the configuration's {key} "
     "the table's rows are looked up by"),
    (r"(architecture\.)?silicon\.clock_mhz", "silicon", "the SVA clock the stages are judged "
     "against (clocks.sva_mhz)"),
    (r"(architecture\.)?silicon\.nand2_logic", "silicon", "NAND2 equivalents of the logic of "
     "the SVA stages synthesised at this configuration (flip-flops apart)"),
    (r"(architecture\.)?silicon\.nand2_flip_flops", "silicon", "NAND2 equivalents of the "
     "flip-flops of the SVA stages synthesised at this configuration"),
    (r"(architecture\.)?silicon\.meets_clock", "silicon", "whether every stage synthesised at "
     "this configuration meets the SVA clock (empty: none is)"),
    (r"(architecture\.)?silicon\.stages\.(?P<stage>[^.]+)\.(?P<what>.+)", "silicon",
     "{what} of the SVA stage {stage} at this configuration (rtl: its RTL exists; config_row: "
     "the table has this configuration; off: the stage is off; in_row: the stage whose row "
     "holds it; gates, flip-flops, NAND2 equivalents, depth in gate levels, fmax)"),
    (r"(architecture\.)?silicon\.compare_levels\.(?P<kind>[^.]+)\.(?P<what>.+)", "silicon",
     "{what} of sva.compare_levels levels of {kind} operators against the SVA clock (the "
     "synthesised probes: gates a level, gate delay, levels that fit, whether it holds)"),
    (r"(architecture\.)?actions\.(?P<who>[^.]+)\.(?P<what>.+)", "architecture", "{what} per "
     "frame ({who}), as the energy model counts them"),
    (r"macs_per_frame", "architecture", "multiply-accumulates per frame, both cameras"),
    (r"architecture\.descriptor_bits", "architecture", "bits per descriptor"),
    (r"architecture\.descriptor_bytes_per_frame_per_camera", "architecture", "bytes of "
     "descriptors per frame and camera"),
    (r"architecture\.nna_cycles_per_descriptor", "architecture", "NNA cycles per descriptor "
     "(the MAC array's initiation interval)"),
    (r"architecture\.nna_window_rows", "architecture", "image rows the NNA's window spans"),
    (r"architecture\.nna_pipeline", "architecture", "the NNA's stages (JSON: name, II, "
     "latency, formula)"),
    (r"architecture\.sva_pipeline\.stages", "architecture", "the SVA's stages (JSON: name, "
     "II, latency, formula)"),
    (r"architecture\.sva_pipeline\.initiation_interval", "architecture", "SVA cycles per "
     "output word"),
    (r"architecture\.sva_pipeline\.lanes", "architecture", "disparities the SVA handles per "
     "cycle"),
    (r"architecture\.sva_pipeline\.latency", "architecture", "SVA cycles from a row being "
     "ready to its first word"),
    (r"architecture\.sva_pipeline\.register_bits", "architecture", "bits of the SVA "
     "pipeline's registers"),
    (r"architecture\.nna_submodules\.(?P<k>stereo|on_chip|lent|idle)", "architecture", "NNA "
     "submodules: {k}"),
    (r"architecture\.nna_submodules\.nna_fps", "architecture", f"frames/s, {BOUND} of the "
     "NNA submodules in use"),
    (r"architecture\.nna_submodules\.with_all\.nna_fps", "architecture", f"frames/s, {BOUND} "
     "of the NNA with every submodule on the chip"),
    (r"architecture\.nna_submodules\.with_all\.stereo_submodules", "architecture", "NNA "
     "submodules on the chip"),
    (r"energy\.per_frame_uj\.total", "energy", "uJ per frame (the table energy.table.*)"),
    (r"energy\.per_frame_uj\.by_(?P<by>block|action)\.(?P<x>.+)", "energy", "uJ per frame: "
     "{by} {x}"),
    (r"energy\.power_mw", "energy", "mW at energy.power_at_fps frames/s"),
    (r"energy\.power_at_fps", "energy", "frames/s the power is given at (energy.fps_basis "
     "says which rate)"),
    (r"energy\.fps_basis", "energy", "which rate energy.power_at_fps is"),
    (r"energy\.table\.(?P<k>node|source)", "energy", "the energy table's {k}"),
    (r"energy\.items", "energy", "the energy table's entries (JSON)"),
    (r"energy\.analytic", "energy", "what the estimate's clock counts are (every other count is "
     "the chip plan's, as a run counts it)"),
    (r"stream\.(?P<k>.+)", "stream", "the stream's figure {k} (docs/report.md, stream): a "
     "sweep runs one frame, so there is no sustained rate"),
    (r"dram\.read_bound_fps", "DRAM", f"frames/s, {BOUND} of the channel's read slots"),
    (r"dram\.utilisation", "DRAM", "bytes all clients moved / what the peak could move in "
     "the run (measured)"),
    (r"dram\.stall_cycles\.(?P<b>[^.]+)", "DRAM", "cycles of {dom} in which {b} waited on "
     "the channel (measured)"),
    (r"dram\.clients\.(?P<c>[^.]+)\.gbps", "DRAM", "GB/s the client {c} moved over the run "
     "(measured)"),
    (r"dram\.clients\.(?P<c>[^.]+)\.bytes", "DRAM", "bytes the client {c} moved (measured)"),
    (r"dram\.clients\.(?P<c>[^.]+)\.slot_gbps", "DRAM", "GB/s the client {c}'s slots give "
     "it"),
    (r"dram\.clients\.(?P<c>[^.]+)\.slots_per_round", "DRAM", "slots of the client {c} in "
     "every round"),
    (r"dram\.clients\.(?P<c>[^.]+)\.what", "DRAM", "what the client {c} moves"),
    (r"dram\.(?P<k>model|peak_gbps|burst_bytes|slot_ns|round_slots|latency_ns)", "DRAM",
     "the channel's {k} (docs/dram.md; units as the name says)"),
    (r"lent_network\.file", "lent network", "the lent network's file (nna.lent_network; "
     "docs/lent.md); the lent submodules' figures are the plan's arithmetic in every mode (they "
     "are not clocked blocks)"),
    (r"lent_network\.about", "lent network", "the file's about text"),
    (r"lent_network\.input\.(?P<k>width|height|channels)", "lent network", "the lent "
     "network's input: its {k}"),
    (r"lent_network\.fps_target", "lent network", "the file's fps: frames/s, or max (as fast "
     "as it can)"),
    (r"lent_network\.fps_max", "lent network", f"frames/s, {BOUND} of the lent network: the "
     "nna clock / cycles_per_frame"),
    (r"lent_network\.fps", "lent network", "frames/s the lent network runs at: its target, or "
     "fps_max for max"),
    (r"lent_network\.busy_percent", "lent network", "% of the time the lent network's busiest "
     "submodule works: fps / fps_max"),
    (r"lent_network\.cycles_per_frame", "lent network", "cycles of the nna clock a frame of "
     "the lent network takes: its busiest submodule's"),
    (r"lent_network\.macs_per_frame", "lent network", "multiply-accumulates per frame of the "
     "lent network"),
    (r"lent_network\.submodules_lent", "lent network", "NNA submodules lent to it "
     "(nna.lent_submodules)"),
    (r"lent_network\.submodules_used", "lent network", "lent submodules its layers occupy "
     "(the rest stay idle)"),
    (r"lent_network\.sram_budget_bits_per_submodule", "lent network", "bits of line-buffer "
     "SRAM of a lent submodule (a stereo submodule's)"),
    (r"lent_network\.weight_store_bits_per_submodule", "lent network", "bits of a lent "
     "submodule's weight store"),
    (r"lent_network\.layers", "lent network", "its layers (JSON: per layer its submodule, "
     "kernel, stride, channels, input and output size, MACs a pixel, MAC share, cycles a pixel "
     "and a frame, line buffer rows and bits, on_chip, spill bytes a frame, weight bytes)"),
    (r"lent_network\.submodules", "lent network", "the lent submodules in use (JSON: per "
     "submodule its layers, cycles a frame, line-buffer bits and whether its weights stay "
     "resident)"),
    (r"lent_network\.dram_bytes_per_frame\.(?P<lb>input|output|spill|weights|total)",
     "lent network", "bytes of DRAM traffic a frame of the lent network: {what}"),
    (r"lent_network\.dram_gbps", "lent network", "GB/s of DRAM traffic of the lent network at "
     "its fps (the DRAM channel's lent client)"),
    (r"lent_network\.stereo_pair\.dram_channel", "lent network", "True when a DRAM channel "
     "is modelled (dram.model), whose slots the lent traffic shares with the stereo pair"),
    (r"lent_network\.stereo_pair\.note", "lent network", "why the lent traffic takes nothing "
     "from the stereo pair (no DRAM channel, or too light a traffic for a slot); empty when it "
     "takes slots"),
    (r"lent_network\.stereo_pair\.lent_slots_per_round", "lent network", "DRAM slots of the "
     "lent client in every round"),
    (r"lent_network\.stereo_pair\.round_slots", "lent network", "DRAM slots in a round"),
    (r"lent_network\.stereo_pair\.lent_slot_gbps", "lent network", "GB/s the lent client's "
     "slots take (whole slots, so more than its dram_gbps; 0 without a slot)"),
    (r"lent_network\.stereo_pair\.lent_share_of_channel", "lent network", "the fraction "
     "(0..1) of the DRAM channel's slots the lent client takes"),
    (r"lent_network\.stereo_pair\.read_bound_fps", "lent network", f"frames/s, {BOUND} of "
     "the stereo pair's DRAM reads beside the lent client"),
    (r"lent_network\.stereo_pair\.read_bound_fps_without_lent", "lent network", f"frames/s, "
     f"{BOUND} of the stereo pair's DRAM reads without the lent client"),
    (r"metrics\.(?P<m>[^.]+)\.(?P<k>.+)", "accuracy", "{metric} ({m} mask; docs/metrics.md)"),
    (r"output\.valid_pixels", "output and report", "pixels with a disparity"),
    (r"output\.invalid_percent", "output and report", "% of the pixels without a disparity"),
    (r"output\.fractional_bits", "output and report", "fractional bits of the disparity words"),
    (r"descriptor\.kind", "output and report", "the NNA's descriptor"),
    (r"descriptor\.bits", "output and report", "bits per descriptor"),
    (r"descriptor\.parts", "output and report", "the descriptor's parts in bit order (JSON: "
     "each its kind and bits; the census's window, kind and stride)"),
    (r"descriptor\.cost_max", "output and report", "the largest matching cost of a pixel (the "
     "hybrid's: its parts' bits weighted by the heaviest weight set)"),
    (r"descriptor\.cost_bits", "output and report", "bits of the aggregated cost register "
     "(sva.cost_bits)"),
    (r"descriptor\.weights\.(?P<key>mode|cost_weights|noisy_weights|noise_threshold|"
     r"noise_gradient)", "output and report", "the hybrid's weight registers: sva.{key} "
     "(mode: sva.weight_mode)"),
    (r"descriptor\.weights\.band_rows", "output and report", "rows of the left view the "
     "noise statistic reads (box and median radius + 1)"),
    (r"descriptor\.frame\.weights", "output and report", "the weights [cnn, census] the "
     "frame was matched with"),
    (r"descriptor\.frame\.cost_max", "output and report", "the frame's largest matching cost"),
    (r"descriptor\.frame\.noise\.(?P<k>sum|count)", "output and report", "the noise "
     "statistic's {k}: sum of |Laplacian| (S) or pixels counted (N)"),
    (r"descriptor\.frame\.noise\.mean", "output and report", "the noise statistic S / N "
     "(grey levels of |Laplacian|)"),
    (r"descriptor\.frame\.noise\.threshold", "output and report", "sva.noise_threshold"),
    (r"descriptor\.frame\.noise\.noisy", "output and report", "the frame counted as noisy "
     "(S > threshold x N): matched with sva.noisy_weights"),
    (r"descriptor\.network\.file", "output and report", "the CNN's weight file "
     "(nna.cnn.weights; default: the shipped nna/conv/single9x9.npz)"),
    (r"descriptor\.network\.name", "output and report", "the CNN's weight file's name "
     "without .npz"),
    (r"descriptor\.network\.layers", "output and report", "the CNN's layers (JSON: each as "
     "KxKxC_inxC_out)"),
    (r"descriptor\.network\.macs_per_pixel", "output and report", "multiply-accumulates of "
     "the CNN per pixel"),
    (r"descriptor\.backend\.(?P<key>p1|p2|p2_adaptive|p2_slope|box_size)", "output and report",
     "the SVA back end the run used: sva.{key}"),
    (r"descriptor\.backend\.tuned_with", "output and report", "what the back end was tuned "
     "with: the network's weight file (which carries its back end) or the descriptor's "
     "defaults"),
    (r"descriptor\.backend\.changed", "output and report", "the back-end keys the "
     "configuration changed from what it was tuned with (JSON)"),
    (r"image\.(?P<k>width|height)", "output and report", "pixels: the frame's {k}"),
    (r"report_version", "output and report", "the report's layout (docs/report.md)"),
    (r"stereosim", "output and report", "the simulator's version"),
    (r"mode", "output and report", "functional or cycle (an estimate sweep has no mode column)"),
    (r"engine", "output and report", "which cycle-model engine ran"),
    (r"warnings", "output and report", "the estimate's warnings (JSON)"),
)

_COMPILED = tuple((re.compile(p), g, d) for p, g, d in RULES)


def _metric(key: str) -> str:
    """What a per-mask accuracy key measures (docs/metrics.md defines each)."""
    if key.startswith("dense_"):
        return _metric(key[6:]) + ", the map's holes filled first"
    t = re.fullmatch(r"(bad|T|M|F)([0-9.]+)", key)
    if t:
        kind, th = t.groups()
        return {
            "bad": f"% of the evaluated pixels wrong by more than {th} px",
            "T": f"% of the valid pixels wrong by more than {th} px",
            "M": f"% of the valid pixels within 1 px wrong by more than {th} px",
            "F": f"F-score (0..1) at {th} px",
        }[kind]
    return {
        "n": "pixels evaluated",
        "invalid": "% of the evaluated pixels without a disparity",
        "totbad": "% bad2 + invalid: missing disparities counted as wrong",
        "avgerr": "px: mean absolute error of the valid pixels",
        "rms": "px: RMS error of the valid pixels",
        "rms_valid": "px: RMS error of the valid pixels (the paper's RMSv)",
        "fill_factor": "% of the evaluated pixels with a disparity",
    }.get(key, key)


@functools.cache
def config_help() -> dict[str, str]:
    """Every configuration key (dotted) and the help text it is declared with."""
    out: dict[str, str] = {}

    def walk(obj, prefix: str) -> None:
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            name = f"{prefix}{f.name}"
            if dataclasses.is_dataclass(value):
                walk(value, name + ".")
            else:
                out[name] = f.metadata.get("help", "")

    walk(load_config(), "")
    return out


def _domains(rows: list[dict]) -> dict[str, str]:
    """The clock (domain and MHz) of every block (``blocks.<b>``) and FIFO end
    (``fifos.<f>.producer`` / ``.consumer``), read from the rows' own columns; where rows
    differ (a camera in some points, a memory source in others), which column says."""
    seen: dict[str, dict[str, str]] = {}
    for row in rows:
        for col, value in row.items():
            if not value or not isinstance(col, str):
                continue
            if col.startswith("blocks.") and col.endswith(".clock_domain"):
                base = col.removesuffix(".clock_domain")
            elif col.startswith("fifos.") and col.endswith("_domain"):
                base = col.removesuffix("_domain")
            else:
                continue
            mhz = row.get(f"cycles.clock_mhz.{value}", "")
            clock = f"the {value} clock" + (f" ({float(mhz):g} MHz)" if mhz else "")
            seen.setdefault(base, {}).setdefault(clock, col)
    return {base: next(iter(clocks)) if len(clocks) == 1 else
            f"its clock ({' or '.join(sorted(clocks))}, as {next(iter(clocks.values()))} says)"
            for base, clocks in seen.items()}


def describe(column: str, axes=(), overrides=(), domains: dict[str, str] | None = None,
             analytic: bool = False) -> tuple[str, str]:
    """(group, description) of a column of results.csv (``analytic``: a figure of the
    analytic estimate, ``estimate.*``)."""
    helps = config_help()
    if column in axes:
        return "swept keys", f"swept: {helps.get(column, column)}"
    if column in overrides:
        return "keys the sweep file sets", helps.get(column, column)
    if column.startswith("config.") and column[7:] in helps:
        return "configuration", helps[column[7:]] or "a configuration key"
    if column.startswith("estimate."):
        group, text = describe(column[9:], domains=domains, analytic=True)
        if group != "not described":
            return "analytic estimate", f"the estimate (stereosim estimate) of: {text}"
    domains = domains or {}
    for pattern, group, text in _COMPILED:
        m = pattern.fullmatch(column)
        if not m:
            continue
        parts = {k: v for k, v in m.groupdict().items() if v is not None}
        parts["how"] = "analytic" if analytic else "cycle sweep: measured; estimate sweep: analytic"
        if "a" in parts:
            parts["act"] = ACTIVITY[parts["a"]]
        if "lb" in parts:
            parts["what"] = LENT_BYTES[parts["lb"]]
        if "k" in parts and group == "accuracy":
            parts["metric"] = _metric(parts["k"])
        if "b" in parts:
            parts["dom"] = domains.get(f"blocks.{parts['b']}", "its clock")
        if "f" in parts and group == "FIFOs":
            end = "producer" if column.endswith("cycles_full") else "consumer"
            parts["dom"] = domains.get(f"fifos.{parts['f']}.{end}", f"its {end}'s clock")
        return group, text.format(**parts)
    return "not described", "see docs/report.md"


def rule_of(column: str) -> str | None:
    """The pattern of :data:`RULES` that describes ``column`` (None: another way or none)."""
    for pattern, _, _ in _COMPILED:
        if pattern.fullmatch(column):
            return pattern.pattern
    return None


def guide_text(header: list[str], rows: list[dict], axes=(), overrides=()) -> str:
    """The guide to the columns of ``header`` (Markdown), grouped as :data:`GROUPS` orders
    them, each group's columns in the header's order."""
    domains = _domains(rows)
    grouped: dict[str, list[tuple[str, str]]] = {g: [] for g in GROUPS}
    for col in header:
        group, text = describe(col, axes, overrides, domains)
        grouped[group].append((col, text))
    lines = [
        "# The columns of results.csv",
        "",
        f"Written by `stereosim sweep` beside results.csv: its {len(header)} columns, grouped. "
        "A frame rate says whether it is a **work bound** or **measured**; a cycle count names "
        "its clock; a time its unit. results.csv flattens one report per point x scene (nested "
        "keys joined with dots): docs/report.md describes the report's keys.",
    ]
    for group in GROUPS:
        if not grouped[group]:
            continue
        lines += ["", f"## {group} ({len(grouped[group])})", "", "| column | what it is |",
                  "|---|---|"]
        lines += [f"| `{col}` | {text} |" for col, text in grouped[group]]
    return "\n".join(lines) + "\n"
