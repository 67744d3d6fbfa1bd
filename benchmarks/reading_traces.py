"""The runs, windows and figures of docs/reading-traces.md, found in the runs themselves.

Each section of the page is a trace of the embedded default scene (Middlebury 2014 Motorcycle,
741x500) centred on an instant of interest: the line buffer filling, the SVA's first ready
row, the first stall of a 4-deep NNA-to-SVA FIFO, the frame's first output word. Cycle numbers
typed into a script drift whenever the model's timing changes, so this module runs the chip
(a traced pass over the frame's first rows, through :func:`stereosim.run`), finds those
instants in the trace and gives, per section, both

* the generated block of figures the page quotes (``benchmarks/doc_figures.py`` writes and
  checks it), and
* the pictures: the options of the ``stereosim run --vcd`` and ``stereosim wave`` that draw
  them (``docs/make_trace_pictures.py`` runs those commands).

The prose of the page explains why the chip behaves as the figures say. Where a run stops
telling that story -- a FIFO that no longer stalls, a row that becomes ready at another input
row -- :class:`StoryChanged` names the claim that failed, so the page gets rewritten rather
than its figures silently regenerated under stale prose.

    python benchmarks/reading_traces.py     # print every block (each names its commands)
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from stereosim.core.config import ChipConfig
from stereosim.core.datasets import default_scene
from stereosim.sim.api import run
from stereosim.sim.cycle.plan import ChipPlan, build_plan
from stereosim.sim.tracing import TraceRequest
from stereosim.traces.gtkw import STATUS_NAMES
from stereosim.traces.log import TraceLog, changes_of

DOC = "reading-traces.md"
BUSY, BLOCKED = STATUS_NAMES.index("busy"), STATUS_NAMES.index("blocked")

# The chips the page traces, as configuration overrides (``--set KEY=VALUE`` on the command
# line): the default chip (the CNN descriptor), the census descriptor, and the census one with
# a 4-deep FIFO between NNA and SVA.
DEFAULT: tuple[tuple[str, object], ...] = ()
CENSUS = (("nna.descriptor", "census"),)
SHALLOW = (("nna.descriptor", "census"), ("fifo.nna_to_sva_depth", 4))

NNA = "top.nna.left.sub0"
FIFO = "top.fifo.nna_left_to_sva"


class StoryChanged(RuntimeError):
    """A run no longer shows what docs/reading-traces.md says it shows."""


def _claim(ok: bool, section: str, what: str) -> None:
    if not ok:
        raise StoryChanged(f"docs/{DOC} section {section}: {what} -- the model changed: "
                           "look at the new pictures (python docs/make_trace_pictures.py) and "
                           "rewrite the section")


@dataclass(frozen=True)
class Picture:
    """One picture of the page: the PNG (in docs/img/), the chip (overrides), the window of
    ``stereosim run --trace-window``, the ``--signals`` and ``--window`` of ``stereosim
    wave`` (None: the whole dump) and its title."""

    png: str
    overrides: tuple[tuple[str, object], ...]
    run_window: str
    signals: str
    wave_window: str | None
    title: str


def set_options(overrides) -> list[str]:
    """The ``stereosim run`` options of a chip's overrides."""
    return [opt for key, value in overrides for opt in ("--set", f"{key}={value}")]


@dataclass(frozen=True)
class Section:
    """What one section of the page quotes (the generated block's lines) and draws."""

    lines: list[str]
    pictures: tuple[Picture, ...]


class Trace:
    """A traced run: its log, and the chip's report, configuration and plan (:func:`traced`),
    with queries on the signals' values (times in fs, the log's unit)."""

    def __init__(self, log: TraceLog, report: dict, cfg: ChipConfig, plan: ChipPlan):
        self.log, self.report, self.cfg, self.plan = log, report, cfg, plan
        self.index = {s.path: i for i, s in enumerate(log.signals)}
        self.period = {c.name: c.period_fs for c in log.clocks}

    def changes(self, path: str) -> tuple[np.ndarray, np.ndarray]:
        """The signal's value at the window's start and at each change."""
        return changes_of(self.log, self.index[path])

    def at(self, path: str, t_fs: int) -> int:
        """The signal's value at the instant ``t_fs`` (after the changes at it)."""
        t, v = self.changes(path)
        return int(v[np.searchsorted(t, t_fs, side="right") - 1])

    def when(self, path: str, test: Callable[[int], bool], after: int = 0) -> int | None:
        """The first instant at or after ``after`` at which the signal takes a value passing
        ``test`` (None if it never does in the window)."""
        t, v = self.changes(path)
        k = np.searchsorted(t, after, side="right")  # the changes after `after`
        if k > 0 and test(int(v[k - 1])):  # the value at `after` itself
            return max(after, int(t[0]))
        for ti, vi in zip(t[k:], v[k:]):
            if test(int(vi)):
                return int(ti)
        return None

    def steps(self, path: str) -> np.ndarray:
        """The instants at which the signal changes (the window's start excluded)."""
        return self.changes(path)[0][1:]

    def rises(self, path: str, start: int, end: int) -> int:
        """How many times a 1-bit signal turns 1 in ``[start, end)`` (a 1 it holds at the
        window's start counts once)."""
        t, v = self.changes(path)
        sel = (t >= start) & (t < end) & (v == 1)
        return int(np.count_nonzero(sel))

    def values(self, path: str, start: int, end: int) -> tuple[int, int]:
        """The smallest and largest value the signal holds in ``[start, end)``."""
        t, v = self.changes(path)
        k0 = max(np.searchsorted(t, start, side="right") - 1, 0)
        k1 = np.searchsorted(t, end, side="left")
        held = v[k0:k1]
        return int(held.min()), int(held.max())

    def cycle(self, t_fs: int, domain: str = "sva") -> int:
        """The cycle of ``domain`` an instant falls in (cycle k starts at its rising edge k)."""
        return t_fs // self.period[domain]

    def mhz(self, domain: str) -> str:
        return f"{self.plan.domains[domain].freq_hz / 1e6:g} MHz"


@cache
def traced(overrides, window: str) -> Trace:
    """The default scene on the chip of ``overrides``, traced over ``window`` (the
    ``--trace-window`` syntax); one run per chip and window, which the sections share."""
    scene = default_scene()
    res = run(scene["left"], scene["right"], overrides=dict(overrides),
              trace=TraceRequest(window=window))
    return Trace(res.trace, res.report, res.config,
                 build_plan(res.config, scene["left"].shape[:2]))


def _us(t_fs: float) -> str:
    return f"{t_fs / 1e9:.3f} us"


def _ns(t_fs: float) -> str:
    return f"{t_fs / 1e6:.1f} ns"


def _cycles_window(kind: str, start: int, end: int) -> str:
    return f"{kind}:{start}:{end}"


def _table(rows: list[tuple[str, str]]) -> list[str]:
    return ["| instant | what the trace shows |", "|---|---|",
            *(f"| {a} | {b} |" for a, b in rows)]


def _commands(*pics: Picture) -> str:
    """The run of a section's pictures (they share it) and each picture's wave window."""
    pic = pics[0]
    opts = " ".join([*set_options(pic.overrides), "--trace-window", pic.run_window])
    text = f"`stereosim run {opts} --vcd t.vcd`"
    windows = [f"`--window {p.wave_window}`" for p in pics if p.wave_window]
    if windows:
        text += f", drawn with `stereosim wave t.vcd {windows[0][1:-1]}`"
        text += "".join(f" and {w}" for w in windows[1:])
    return text


# ---- 1. the line buffer fills ----------------------------------------------------------------


@cache
def line_buffer_fill() -> Section:
    """Section 1 (default chip): the left NNA submodule's line buffer filling from the memory
    source, its first descriptor, the buffer full and the source blocked, the first row the
    MAC array frees."""
    tr = traced(DEFAULT, "rows:0:3")
    nna = tr.plan.block("nna_left")
    src = tr.plan.fifo("src_left_to_nna")
    row_in, fill = f"{NNA}.line_buffer.row_in", f"{NNA}.line_buffer.fill"
    rows_at = tr.steps(row_in)
    row_fs = rows_at[1] - rows_at[0]
    w = tr.plan.shape[1]
    _claim(tr.at("top.memory_left.status", 0) == BUSY
           and abs(row_fs - w * tr.period["nna"]) < tr.period["nna"], "1",
           "the memory source sends one pixel per NNA cycle from the start")
    first = tr.when(f"{NNA}.out.valid", lambda v: v == 1)
    _claim(first is not None and tr.at(row_in, first) == nna.half + 1, "1",
           f"the first descriptor leaves once image rows 0 to {nna.half} are in")
    full = tr.when(fill, lambda v: v == nna.rows)
    blocked = tr.when("top.memory_left.status", lambda v: v == BLOCKED)
    _claim(full is not None and blocked is not None and full <= blocked
           and tr.at(f"top.fifo.{src.name}.occupancy", blocked) == src.depth, "1",
           "the memory source blocks once the line buffer and its FIFO are full")
    _claim(tr.values(f"top.fifo.{src.name}.occupancy", 0, full) == (1, 1), "1",
           "the source FIFO holds one pixel while the line buffer fills")
    mac = tr.steps(f"{NNA}.mac.row")
    freed = tr.when(fill, lambda v: v < nna.rows, after=full)
    _claim(freed is not None and tr.at(f"{NNA}.mac.row", freed) == nna.half + 1, "1",
           f"image row 0 leaves the line buffer when the MAC array starts descriptor row "
           f"{nna.half + 1}")
    resumed = tr.when("top.memory_left.status", lambda v: v == BUSY, after=blocked)
    refilled = tr.when(fill, lambda v: v == nna.rows, after=freed)
    sva_first = tr.when("top.sva.status", lambda v: v == BUSY)
    t, v = tr.changes("top.sva.status")
    busy = np.flatnonzero((v[:-1] == BUSY) & (t[:-1] >= sva_first) & (t[:-1] < full))
    _claim(busy.size > 0 and bool(np.all(t[busy + 1] - t[busy] == tr.period["sva"])), "1",
           "the SVA takes each descriptor pair in one cycle")
    end_us = 5 * math.ceil((refilled + row_fs) / 5e9)  # a row past the refill, in 5 us
    mac_stage = next(st for st in nna.stages if st.name == "mac_array")
    pic = Picture("trace_line_buffer_fill.png", DEFAULT, f"0:{end_us}us",
                  f"top.memory_left.status,top.fifo.{src.name}.occupancy,{NNA}.line_buffer.*,"
                  f"{NNA}.status,{NNA}.mac.row,{NNA}.out.valid,top.sva.status", None,
                  "1. The line buffer fills, then the MAC array starts (default chip)")
    lines = [
        f"{_commands(pic)}: the default chip ({tr.cfg.nna.descriptor.upper()} descriptor, "
        f"{2 * nna.half + 1}x{2 * nna.half + 1} window), NNA clock {tr.mhz('nna')}, "
        f"`nna.line_buffer_rows` = {nna.rows}, `fifo.source_to_nna_depth` = {src.depth}.",
        "",
        *_table([
            ("0", "`memory_left.status` busy: one pixel per NNA cycle into the line buffer"),
            (f"every {_us(row_fs)}", f"`line_buffer.row_in` advances: a row of {w} pixels"),
            (_us(first), f"the first descriptor (`out.valid`), as `row_in` reaches "
                         f"{nna.half + 1}: rows 0 to {nna.half} are in"),
            (_us(sva_first), "`sva.status` busy for the first time: one cycle per "
                             "descriptor pair, starved in between"),
            (_us(full), f"`fill` = {nna.rows}: the line buffer is full"),
            (_us(blocked), f"the source FIFO holds {src.depth} pixels: `memory_left.status` "
                           "blocked"),
            (f"every {_us(mac[1] - mac[0])}", f"`mac.row` advances: {w} descriptors of "
                                              f"{nna.ii} NNA cycles ("
                                              f"{mac_stage.formula.split(';')[0]})"),
            (_us(freed), f"`mac.row` = {nna.half + 1}: image row 0 is free, `fill` = "
                         f"{nna.rows - 1}"),
            (_us(resumed), "`memory_left.status` busy again"),
            (_us(refilled), f"image row {tr.at(row_in, refilled) - 1} is in: `fill` = "
                            f"{nna.rows}, the source blocked again"),
        ]),
    ]
    return Section(lines, (pic,))


# ---- 2. the SVA's row delay ------------------------------------------------------------------


@cache
def sva_row_delay() -> Section:
    """Section 2 (default chip): the SVA's first ready row, its first words, one output row
    per input row after that."""
    window = "rows:0:3"
    tr = traced(DEFAULT, window)
    _claim(tr.report["throughput"]["bottleneck"].startswith("nna"), "2",
           "the NNA is the default chip's bottleneck")
    sva = tr.plan.block("sva")
    cfg = tr.cfg.sva
    w = tr.plan.shape[1]
    rows_in = tr.steps("top.sva.input.row")
    ready = tr.when("top.sva.input.rows_ready", lambda v: v == 1)
    _claim(ready is not None and tr.at("top.sva.input.row", ready) == sva.lookahead + 1, "2",
           f"output row 0 becomes ready once input rows 0 to {sva.lookahead} are in")
    for t in rows_in[rows_in >= ready]:
        _claim(tr.at("top.sva.input.rows_ready", t) == tr.at("top.sva.input.row", t)
               - sva.lookahead, "2", "rows_ready follows the input rows "
               f"{sva.lookahead} behind")
    first_word = tr.when("top.sva.output.valid", lambda v: v == 1)
    first_sink = tr.when("top.sink.count", lambda v: v >= 1)
    row1 = tr.when("top.sva.output.row", lambda v: v == 1)
    # output.row and .col name the next word to leave: row 1 from the push of row 0's last
    words0 = tr.rises("top.sva.output.valid", first_word, row1 + 1)
    rejects0 = tr.rises("top.sva.lr_check.reject", first_word, row1 + 1)
    _claim(words0 == w, "2", f"output row 0 is {w} words")
    per_row = w * sva.ii
    end = tr.log.end_fs
    pic = Picture("trace_sva_row_delay.png", DEFAULT, window,
                  "top.sva.input.row,top.sva.input.rows_ready,top.sva.status,"
                  "top.sva.output.row,top.sva.output.valid,top.sva.lr_check.reject,"
                  "top.sink.count", None,
                  "2. The SVA's row delay: box filter and median (default chip)")
    lines = [
        f"{_commands(pic)}: `sva.box_size` = {cfg.box_size} (radius {cfg.box_size // 2}), "
        f"`sva.median` = {cfg.median} (radius {cfg.median // 2}): an output row needs "
        f"{sva.lookahead} input rows below it; the SVA clock is {tr.mhz('sva')}, its II "
        f"{sva.ii} cycles; the report's bottleneck: "
        f"`{tr.report['throughput']['bottleneck']}`.",
        "",
        *_table([
            (f"every {_us(rows_in[1] - rows_in[0])}", "`sva.input.row` advances: a row of "
                                                      f"{w} descriptor pairs"),
            (_us(ready), f"`input.row` reaches {sva.lookahead + 1} (rows 0 to {sva.lookahead} "
                         "in): `rows_ready` = 1, and from then on `input.row` - "
                         f"{sva.lookahead}"),
            (_us(first_word), f"the first word leaves the SVA (`output.valid`), "
                              f"{tr.cycle(first_word - ready)} SVA cycles later (section 4 "
                              "takes them apart)"),
            (_us(first_sink), "the sink holds it (`sink.count` = 1; the report's first "
                              f"output: {tr.report['latency']['first_output_us']:.3f} us)"),
            (_us(row1), f"row 0 is out: {w} words, one every {sva.ii} SVA cycles "
                        f"({per_row} cycles, {_us(per_row * tr.period['sva'])}); "
                        f"`lr_check.reject` pulsed {rejects0} times"),
            (_us(end), f"the window ends with row 2 in the sink: `sink.count` = "
                       f"{tr.at('top.sink.count', end - 1)}"),
        ]),
    ]
    return Section(lines, (pic,))


# ---- 3. a stall ------------------------------------------------------------------------------


@cache
def fifo_stall(chip=SHALLOW) -> Section:
    """Section 3 (census, a 4-deep NNA-to-SVA FIFO): the first stall, from the SVA's last pop
    to the NNA's first push after it."""
    tr = traced(chip, "rows:0:6")
    _claim(tr.report["throughput"]["bottleneck"] == "sva", "3", "the SVA is the bottleneck")
    sva = tr.plan.block("sva")
    r = sva.lookahead
    fifo = tr.plan.fifo("nna_left_to_sva")
    w = tr.plan.shape[1]
    full = tr.when(f"{FIFO}.full", lambda v: v == 1)
    _claim(full is not None, "3", f"the {fifo.depth}-deep FIFO fills")
    # the SVA's last pop before the stall: pop falls in the cycle after it
    pops = tr.changes(f"{FIFO}.pop")
    stop = int(pops[0][(pops[0] <= full) & (pops[1] == 0)][-1])
    nna_stop = tr.when(f"{NNA}.out.valid", lambda v: v == 0, after=full)
    resume = tr.when(f"{FIFO}.pop", lambda v: v == 1, after=stop)
    push = tr.when(f"{FIFO}.push", lambda v: v == 1, after=resume)
    _claim(tr.at("top.sva.input.row", stop) == 2 * r + 3, "3",
           f"the SVA stops taking input at row {2 * r + 3} (its row buffers hold 2r + 3 rows)")
    issued = tr.rises("top.sva.pipeline.issue", 0, resume)
    _claim(issued == (r + 2) * w, "3",
           f"the SVA takes input again once box row {r + 1} is issued")
    nna_full = tr.when(f"{NNA}.status", lambda v: v == BLOCKED, after=nna_stop)
    _claim(nna_full is not None and nna_full < push
           and tr.values(f"{NNA}.status", nna_stop, nna_full) == (BUSY, BUSY)
           and tr.values(f"{NNA}.status", nna_full, push) == (BLOCKED, BLOCKED), "3",
           "the NNA stays busy, its line buffer taking pixels, until the buffer is full; then "
           "it is blocked until the stall ends")
    p_nna = tr.period["nna"]
    cross = push - resume
    _claim(cross <= fifo.sync_cycles * p_nna, "3",
           f"the NNA pushes within {fifo.sync_cycles} NNA cycles of the first pop")
    full_off = tr.when(f"{FIFO}.full", lambda v: v == 0, after=resume)
    _claim(full_off is not None and tr.period["nna"] > tr.period["sva"], "3",
           "after the stall the faster SVA clock drains the FIFO by a slot")
    again = tr.when(f"{FIFO}.full", lambda v: v == 1, after=full_off)
    _claim(again is not None and tr.at("top.sva.input.row", again) == 2 * r + 4, "3",
           "the next stall comes with the next input row")
    c_stop, c_resume = tr.cycle(stop), tr.cycle(resume)
    before, after = 16, 24
    refilled = tr.values(f"{FIFO}.occupancy", push + tr.period["sva"],
                         (c_resume + after) * tr.period["sva"])
    run_window = _cycles_window("sva", c_stop - before, c_resume + after)
    signals = (f"clocks.*,{NNA}.status,{NNA}.out.valid,{FIFO}.*,top.sva.status,"
               "top.sva.output.valid")
    pics = (Picture("trace_stall.png", chip, run_window, signals,
                    _cycles_window("sva", c_stop - before, c_stop + after),
                    "3a. A 4-deep FIFO between NNA and SVA: the stall begins (census)"),
            Picture("trace_stall_end.png", chip, run_window, signals,
                    _cycles_window("sva", c_resume - before, c_resume + after),
                    "3b. The stall ends: the SVA pops, the NNA pushes (census)"))
    lines = [
        f"{_commands(*pics)}: `nna.descriptor` = {tr.cfg.nna.descriptor} "
        f"({tr.plan.block('nna_left').ii} NNA cycle per descriptor at {tr.mhz('nna')}; "
        f"the SVA issues a word every {sva.ii} cycles at {tr.mhz('sva')}; the report's "
        f"bottleneck: `{tr.report['throughput']['bottleneck']}`), "
        f"`fifo.nna_to_sva_depth` = {fifo.depth}, `fifo.sync_cycles` = {fifo.sync_cycles}.",
        "",
        "| instant | SVA cycle | what the trace shows |", "|---|---|---|",
        f"| {_us(stop)} | {c_stop} | the SVA's first cycle without a pop (`pop` low): it "
        f"holds input rows 0 to {2 * r + 2} (its ring of 2r + 3 = {2 * r + 3} rows; r = {r}) "
        f"and is issuing box row {r + 1}, which still reads row 0 (the row leaving its column "
        "sums) |",
        f"| {_us(full)} | {tr.cycle(full)} | `full` rises: {fifo.depth} descriptors in the FIFO "
        "as the NNA sees it |",
        f"| {_us(nna_stop)} | {tr.cycle(nna_stop)} | the NNA's first cycle without a push "
        "(`out.valid` low): the stall begins |",
        f"| {_us(nna_full)} | {tr.cycle(nna_full)} | the NNA's line buffer is full "
        f"({tr.plan.block('nna_left').rows} rows): `status` blocked, and the memory source "
        "behind it soon after |",
        f"| {_us(resume)} | {c_resume} | the SVA pops again, every cycle: all {w} words of "
        f"box row {r + 1} have been issued |",
        f"| {_us(push)} | {tr.cycle(push)} | the NNA pushes again, {_ns(cross)} after the "
        f"first pop; the stall lasted {round((push - nna_stop) / p_nna)} NNA cycles "
        f"({_us(push - nna_stop)}); `full` stays up, `occupancy` moves between "
        f"{refilled[0]} and {refilled[1]} |",
        f"| {_us(full_off)} | {tr.cycle(full_off)} | `full` falls: the faster SVA clock has "
        "gained a slot on the NNA |",
        f"| {_us(again)} | {tr.cycle(again)} | `full` rises again: the next stall, input row "
        f"{2 * r + 4} waiting for box row {r + 2} to be issued |",
    ]
    return Section(lines, pics)


# ---- 4. inside the SVA -----------------------------------------------------------------------


@cache
def sva_stages() -> Section:
    """Section 4 (census): the SVA's stages around the frame's first output word."""
    tr = traced(CENSUS, "rows:0:1")
    _claim(tr.report["throughput"]["bottleneck"] == "sva", "4", "the SVA is the bottleneck")
    sva = tr.plan.block("sva")
    d = tr.cfg.sva.disparities
    ready = tr.when("top.sva.input.rows_ready", lambda v: v == 1)
    issue = tr.when("top.sva.pipeline.issue", lambda v: v == 1)
    out = tr.when("top.sva.output.valid", lambda v: v == 1)
    t_iss, v_iss = tr.changes("top.sva.pipeline.issue")
    issue_s = int(t_iss[v_iss == 1][sva.skew])  # word S's issue
    c_ready, c_issue, c_out = tr.cycle(ready), tr.cycle(issue), tr.cycle(out)
    c_issue_s = tr.cycle(issue_s)
    _claim(c_issue - c_ready >= sva.lookahead, "4",
           f"the first word goes r = {sva.lookahead} slots or more after box row 0 is ready")
    _claim(c_out - c_issue_s == sva.latency, "4",
           f"the first word leaves L = {sva.latency} cycles after word S = {sva.skew}'s issue")
    before, after = 16, 12
    p_sva = tr.period["sva"]
    a, b = (c_out - before) * p_sva, (c_out + after) * p_sva
    _claim(tr.values("top.sva.pipeline.stall", a, b) == (0, 0), "4",
           "the pipeline does not stall around the first output word")
    _claim(tr.values("top.sva.stage.sgm.status", a, b) == (BUSY, BUSY)
           and [st.name for st in sva.stages if st.ii == sva.ii] == ["sgm"], "4",
           "the SGM stage alone sets the II and is busy in every cycle")
    for st in sva.stages:  # once the first word has left, each holds latency / II words
        lo, hi = tr.values(f"top.sva.stage.{st.name}.words", out + p_sva, b)
        _claim(st.latency // sva.ii <= lo and hi <= -(-st.latency // sva.ii), "4",
               f"the {st.name} stage holds its latency over the II in words")
    lr = tr.values("top.sva.stage.lr_check.words", a, b)
    _claim(lr[1] == d, "4", "the LR check fills to D words")
    window = _cycles_window("sva", c_out - before, c_out + after)
    pic = Picture("trace_sva_stages.png", CENSUS, window,
                  "top.sva.pipeline.*,top.sva.stage.*.words,top.sva.stage.sgm.status,"
                  "top.sva.output.valid", window,
                  "4. Inside the SVA: the stages around the first output word (census)")
    lines = [
        f"{_commands(pic)}: `nna.descriptor` = {tr.cfg.nna.descriptor}, D = {d}; the SVA "
        f"issues a word every II = {sva.ii} cycles.",
        "",
        "| SVA cycle | what the trace shows |", "|---|---|",
        f"| {c_ready} | `rows_ready` = 1: box row 0 is ready (input rows 0 to "
        f"{sva.lookahead} in) |",
        f"| {c_issue} | the first word enters the pipeline (`pipeline.issue`) after the column "
        f"sums' {sva.passes} passes and the row's r = {sva.lookahead} look-ahead slots, then "
        f"one every {sva.ii} cycles (a row's first max({sva.ii}, r + 1) after the "
        "last) |",
        f"| {c_issue_s} | word S = m W + m = {sva.skew} enters: with it the median's window "
        "around word 0 is complete |",
        f"| {c_out} | word 0 leaves (`output.valid`): L = {c_out - c_issue_s} cycles after "
        "word S's issue |",
        f"| {tr.report['cycles']['first_output']['sva']} | the sink pops it (the report's "
        "first output) |",
        "",
        "| stage | latency (cycles) | stage II | latency / II | words it holds in the picture |",
        "|---|---|---|---|---|",
        *(f"| {st.name} | {st.latency} | {st.ii} | {st.latency / sva.ii:g} | "
          f"{_held(tr, f'top.sva.stage.{st.name}.words', a, b)} |" for st in sva.stages),
        f"| **pipeline** (the stages' words and the median's S = {sva.skew}) | **L = "
        f"{sva.latency}** | **II = {sva.ii}** | | "
        f"**{_held(tr, 'top.sva.pipeline.words', a, b)}** |",
    ]
    return Section(lines, (pic,))


def _held(tr: Trace, path: str, a: int, b: int) -> str:
    """The values a count takes in ``[a, b)``, in words: "1", "3 or 4", "0 to 2"."""
    lo, hi = tr.values(path, a, b)
    return f"{lo}" if lo == hi else f"{lo} or {hi}" if hi == lo + 1 else f"{lo} to {hi}"


# The generated blocks of docs/reading-traces.md, by name (benchmarks/doc_figures.py).
SECTIONS = {
    "trace-fill": line_buffer_fill,
    "trace-rows": sva_row_delay,
    "trace-stall": fifo_stall,
    "trace-stages": sva_stages,
}


def block(name: str) -> list[str]:
    """The lines of the generated block ``name``."""
    return SECTIONS[name]().lines


def pictures() -> list[Picture]:
    """Every picture of the page, in its order."""
    return [pic for section in SECTIONS.values() for pic in section().pictures]


def main() -> int:
    for name in SECTIONS:
        print(f"<!-- {name} -->\n" + "\n".join(block(name)) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
