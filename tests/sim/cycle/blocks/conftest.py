"""The bench of the block-level tests: one plan run on both cycle engines (the readable kernel,
sim/cycle/readable, and the compiled engine, sim/cycle/compiled), and one block's own results
held equal -- not only the whole report.

A block's results (:meth:`Bench.results`) are what the engines give for that block alone: its
statistics entry (``stats["blocks"][name]``: busy, starved, blocked, idle cycles) and its
report entry, the statistics of every FIFO it pushes into or pops from (pushes, pops,
occupancy histogram, cycles full and empty, ...), its row buffers' peaks
(``report["buffers"][name]``), an NNA submodule's per-layer statistics, the SVA's per-stage
ones, and every traced signal it or its FIFOs own (``plan.signals``' owner), as the sequence
of value changes a waveform viewer shows. A stopped run's results are the block's and its
FIFOs' state on the exception. The block files (one per compiled block:
sim/cycle/compiled/{source,nna,merge,sva,sink,fifo}.py) choose the configurations that stress
their block."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import UserError
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable

WHOLE_RUN = (0, 1 << 60)  # a trace window that holds every run here


def frames_of(h, w, frames=1, seed=0, shift=3):
    """A textured stereo pair (right = left shifted by ``shift``) of ``frames`` frames: (H, W)
    images for one frame, (N, H, W) stacks for a stream."""
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (frames, h, w + shift), dtype=np.uint8)
    left, right = base[:, :, :w].copy(), base[:, :, shift:].copy()
    return (left[0], right[0]) if frames == 1 else (left, right)


def waveform(trace, path):
    """A signal's value entering the window and its changes ``[(time_fs, value)]`` as a viewer
    shows them (traces/log.py: the last change at an instant wins, a change to the value held
    is none)."""
    i = [s.path for s in trace.signals].index(path)
    mask = trace.ids == i
    times, values = trace.times_fs[mask], trace.values[mask]
    start = int(trace.initial[i])
    held, changes = start, []
    for k in range(times.size):
        if k + 1 < times.size and times[k + 1] == times[k]:
            continue
        if int(values[k]) != held:
            held = int(values[k])
            changes.append((int(times[k]), held))
    return start, changes


class Bench:
    """Runs on both engines and the block-by-block comparison (see the module docstring)."""

    waveform = staticmethod(waveform)

    @staticmethod
    def plan(over, shape, frames=1):
        return build_plan(load_config(overrides=over), shape, frames)

    def run(self, over, shape, *, frames=1, sink_stall=None, seed=0):
        """Both engines on one plan of ``over`` at ``shape`` (H, W), the whole run traced:
        ``(plan, readable result, compiled result)``; either stopping is a test failure."""
        plan = self.plan(over, shape, frames)
        left, right = frames_of(*shape, frames, seed)
        slow = run_readable(plan, left, right, sink_stall=sink_stall, window=WHOLE_RUN)
        fast = run_compiled(plan, left, right, sink_stall=sink_stall, window=WHOLE_RUN)
        return plan, slow, fast

    def stop(self, over, shape, *, frames=1, sink_stall=None, seed=0):
        """Both engines on one plan that must stop: ``(plan, readable stop, compiled stop)``,
        the same exception type on both, each with the trace up to the stop."""
        plan = self.plan(over, shape, frames)
        left, right = frames_of(*shape, frames, seed)
        got = []
        for engine in (run_readable, run_compiled):
            with pytest.raises(UserError) as info:
                engine(plan, left, right, sink_stall=sink_stall, window=WHOLE_RUN)
            got.append(info.value)
        assert type(got[0]) is type(got[1]), got
        assert got[0].trace is not None and got[1].trace is not None
        return plan, got[0], got[1]

    @staticmethod
    def fifos(plan, name):
        """The FIFOs block ``name`` pushes into or pops from, in the plan's order."""
        return [f.name for f in plan.fifos if name in (f.producer, f.consumer)]

    def results(self, plan, result, name):
        """Block ``name``'s own results in a finished run (a :class:`FrameResult`)."""
        fifos = self.fifos(plan, name)
        owners = {name, *fifos}
        out = {
            "stats": result.stats["blocks"][name],
            "report": result.report["blocks"][name],
            "buffers": result.report["buffers"].get(name),
            "layers": result.stats.get("nna_layers", {}).get(name),
        }
        for f in fifos:
            out[f"fifo {f} stats"] = result.stats["fifos"][f]
            out[f"fifo {f} report"] = result.report["fifos"][f]
        if plan.block(name).kind == "sva":
            out["stages"] = result.stats["stages"]["sva"]
            out["stage report"] = result.report["sva_stages"]
        for s in plan.signals:
            if s.owner in owners:
                out[f"signal {s.path}"] = waveform(result.trace, s.path)
        return out

    def stopped(self, plan, stop, name):
        """Block ``name``'s own results in a stopped run (a :class:`RunStopped`)."""
        out = {"state": stop.blocks[name], "time_fs": stop.time_fs}
        for f in self.fifos(plan, name):
            out[f"fifo {f}"] = stop.fifos[f]
        owners = {name, *self.fifos(plan, name)}
        for s in plan.signals:
            if s.owner in owners:
                out[f"signal {s.path}"] = waveform(stop.trace, s.path)
        return out

    @staticmethod
    def fifo_results(plan, result, fifo):
        """FIFO ``fifo``'s own results: its statistics, its report entry and the signals it
        owns (occupancy, push, pop, full, empty) in a finished run, or its state on the
        exception of a stopped one and its signals up to the stop."""
        if isinstance(result, UserError):
            out = {"state": result.fifos[fifo], "time_fs": result.time_fs}
        else:
            out = {"stats": result.stats["fifos"][fifo], "report": result.report["fifos"][fifo]}
        for s in plan.signals:
            if s.owner == fifo:
                out[f"signal {s.path}"] = waveform(result.trace, s.path)
        return out

    def fifo_agree(self, plan, slow, fast, fifo):
        """Assert the engines give FIFO ``fifo`` the same results; returns the readable
        kernel's."""
        a, b = self.fifo_results(plan, slow, fifo), self.fifo_results(plan, fast, fifo)
        diff = self.differences(a, b)
        assert not diff, {k: (a.get(k), b.get(k)) for k in diff}
        return a

    @staticmethod
    def differences(a, b):
        """The keys of two blocks' results that differ."""
        return [k for k in a if a[k] != b.get(k)] + [k for k in b if k not in a]

    def agree(self, plan, slow, fast, name):
        """Assert the engines give block ``name`` the same results (a finished run's or a
        stopped one's); returns the readable kernel's."""
        if isinstance(slow, UserError):
            assert str(slow) == str(fast)
            a, b = self.stopped(plan, slow, name), self.stopped(plan, fast, name)
        else:
            a, b = self.results(plan, slow, name), self.results(plan, fast, name)
        diff = self.differences(a, b)
        assert not diff, {k: (a.get(k), b.get(k)) for k in diff}
        return a


@pytest.fixture(scope="session")
def bench():
    """:class:`Bench`: both engines on a plan, one block's results held equal."""
    return Bench()
