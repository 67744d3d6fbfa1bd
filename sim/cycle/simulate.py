"""One frame of the cycle model on the engine ``sim.engine`` selects -- the one place that
decides which engine runs.

- ``readable``: the reference kernel (:mod:`sim.cycle.readable.chip`), edge by edge, ~1e5 cycles/s;
- ``fast``: the compiled engine (:mod:`sim.cycle.compiled`), millions of cycles/s: completing
  runs, traces and runs that stop, with the readable kernel's words, report, statistics,
  traces and messages;
- ``auto`` (the default): the compiled engine, unless the run asks for what only the readable
  kernel does -- a shuffled evaluation order, or a sink stall given as a Python function rather
  than a periodic pattern; then the readable kernel, and the report's ``engine_reason`` says
  why. ``fast`` refuses such a run with one
  line.

A run the engines cannot simulate is refused before either starts, in one line
(:func:`check_run_time`): one whose expected chip time is longer than
:data:`~sim.cycle.plan.MAX_RUN_FS`, or whose watchdog window is beyond what the engine's time
holds (the compiled engine's time is int64 femtoseconds) -- a network on the lent NNA
submodules that leaves the stereo pair a sliver of the DRAM channel does that, and so does a
stream of too many frames.

The first frame after an install or an edit compiles the numba kernels it uses; one line on
stderr says so when the first one starts, and one more how long it took
(:func:`core.progress.compile_notice`); on an empty cache the compiled engine's kernels compile
on two cores (:mod:`sim.cycle.compiled.prewarm`). The readable kernel draws a progress bar on
stderr when it is a terminal. A run that stops raises its
:class:`~sim.cycle.contract.RunStopped` with ``engine`` set (and, with ``window``, the trace up
to the stop).
"""

from __future__ import annotations

from stereosim.core.errors import ConfigError
from stereosim.core.progress import compile_notice
from stereosim.sim.cycle.compiled.layout import INF
from stereosim.sim.cycle.compiled.prewarm import prewarm
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import FrameResult, RunStopped
from stereosim.sim.cycle.plan import MAX_RUN_FS, ChipPlan
from stereosim.sim.cycle.readable.chip import run_readable

ENGINES = ("auto", "fast", "readable")


def _needs_readable(plan: ChipPlan, sink_stall, order_seed) -> str | None:
    if order_seed is not None:
        return "a shuffled evaluation order (order_seed) runs on the readable kernel"
    if callable(sink_stall):
        return ("a sink stall given as a function runs on the readable kernel (the compiled "
                "engine takes a periodic pattern (period, allowed_phase) or a script of 0/1)")
    return None


def check_run_time(plan: ChipPlan) -> None:
    """Raise :class:`ConfigError` for a run longer than the engines simulate: its budget is
    capped (:attr:`ChipPlan.budget_reason` ``time_limit``) and the run is expected to take
    longer than that (it could only stop there), or its watchdog's window -- with the DRAM
    channel's longest wait -- is beyond what the compiled engine's time holds at all
    (:data:`.compiled.layout.INF`, "never"; an instant plus the window must fit 64 bits)."""
    ways = ["simulate the stream in parts (fewer --frames)"] if plan.frames > 1 else []
    if plan.dram is not None:
        ways.append("give the stereo pair more of the DRAM channel (a lower fps in "
                    "nna.lent_network, a wider dram.gbps)")
    ways.append("faster clocks")
    remedy = ", ".join(ways[:-1]) + f" or {ways[-1]}" if len(ways) > 1 else ways[0]
    if plan.budget_reason == "time_limit" and plan.expected_run_s > MAX_RUN_FS / 1e15:
        why = (f"the run would take about {plan.expected_run_s:,.3f} s of chip time, longer "
               f"than the {MAX_RUN_FS / 1e15:,.3f} s the cycle engines simulate (their time "
               "counts femtoseconds in 64 bits)")
    elif plan.watchdog_fs >= INF:
        why = (f"its watchdog waits {plan.watchdog_fs / 1e15:,.3f} s of chip time "
               f"(sim.watchdog_cycles = {plan.cfg.sim.watchdog_cycles} periods of the slowest "
               f"clock, with the DRAM channel's longest wait), more than the {INF / 1e15:,.3f} s "
               "the compiled engine's time holds (femtoseconds in 64 bits)")
        remedy = f"lower sim.watchdog_cycles, or {remedy}"
    else:
        return
    slots = ""
    if plan.dram is not None and plan.dram.reads is not None:
        slots = (f"; the stereo pair's reads get {plan.dram.reads.count} of the DRAM channel's "
                 f"{plan.dram.round_slots:,} slots a round")
    raise ConfigError(f"{why}{slots}: {remedy}")


def simulate(plan: ChipPlan, left, right=None, *, sink_stall=None,
             window: tuple[int, int] | None = None, order_seed=None,
             on_frame=None, words: bool = True, progress=None) -> FrameResult:
    """One frame or a stream of frames of ``plan`` (``left``, ``right``: (H, W) arrays, (N, H,
    W) stacks, or a :class:`~sim.cycle.frames.FrameSupply` as ``left``): the last frame's
    words, cycle report (with ``engine``), statistics, row and frame instants and, with
    ``window`` = (start_fs, end_fs), the trace of that window; ``on_frame(f, words)`` receives
    every frame's words in order. ``sink_stall``: ``(period, allowed_phase)`` or a script of 0/1
    (:func:`~sim.cycle.rules.sink_pattern`; or, readable kernel only, a function of the cycle
    that returns True when the sink refuses to pop).
    ``words=False``: the compiled engine computes no words (``words`` is None; the readable
    kernel moves them anyway). ``progress(frames)``: the compiled engine says now and then how
    many frames the sink has taken (the readable kernel draws its own bar)."""
    check_run_time(plan)
    engine = plan.cfg.sim.engine
    reason = _needs_readable(plan, sink_stall, order_seed)
    if engine == "fast" and reason is not None:
        raise ConfigError(f"sim.engine=fast: {reason}; use sim.engine=auto or readable")
    ran = "readable" if engine == "readable" or reason is not None else "fast"
    try:
        with compile_notice():
            if ran == "readable":
                result = run_readable(plan, left, right, sink_stall=sink_stall, window=window,
                                      order_seed=order_seed, on_frame=on_frame)
            else:
                with prewarm(plan):  # a cold cache compiles on two cores
                    result = run_compiled(plan, left, right, sink_stall=sink_stall,
                                          window=window, on_frame=on_frame, words=words,
                                          progress=progress)
    except RunStopped as stop:
        stop.engine = ran
        raise
    result.report["engine"] = ran
    if ran == "readable" and engine == "auto":
        result.report["engine_reason"] = reason
    return result
