"""A cold first run compiles on two cores: the stream loop here, everything else in a helper.

On an empty numba cache a cycle run spends nearly all its time compiling, one kernel after
another: the stream loop (:func:`.schedule.advance_streams`, with every block's advance linked
into it) is about 45 % of it, the walkers and the data kernels (the NNA's descriptors, the
SVA's stream) most of the rest. They do not depend on each other, so :func:`prewarm` compiles
them at the same time: a helper process (``python -m`` this module) compiles the walkers, the
pass a stopped run makes (``note_source_wait``), the SVA's data kernels of the run's
configuration and the trace sampler (:func:`.sampler.record_window`, which a traced run --
``--vcd``, ``--timeline`` -- calls after its pass; the first traced run after an install
compiled it alone in the run's process) into numba's on-disk cache, while this
process compiles the stream loop and the NNA's data kernels; then this process waits for the
helper, and the run finds every kernel compiled (its own in memory, the helper's in the
cache). Nothing changes in what runs:
the kernels are the same functions with the same types, whichever process compiled them.

- The helper compiles by *running* the kernels on stand-ins of the run's types: the walkers
  and the trace sampler on the event net of a small frame of the same configuration before
  any event (the walkers find nothing to do, the sampler records a few idle clock edges), the
  data kernels on a small random pair (the SVA's on random descriptors of the run's type).
  The trace writers' kernels (``traces/vcd.py``) stay with the run: they belong to a layer
  above the cycle model.
- The stream loop is compiled for the net's types without running
  (``Dispatcher.compile``); the net's numba type is the same for every configuration.
- Only when the stream loop is not in the cache (a fresh install or an edit) is a helper
  started; otherwise nothing happens here. A helper that fails or is slow costs nothing but
  its time: whatever it did not compile, the run compiles itself as before. It is killed when
  this process leaves :func:`prewarm` in any way (an interrupt included), and it exits when
  its input closes (this process gone).
- The compile notice (:func:`core.progress.compile_notice`) counts the helper's kernels and
  says how long this process waited for it (:meth:`~core.progress.CompileWatch.add_helper`).
- ``STEREOSIM_PREWARM=0`` in the environment switches it off (one process compiles all).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import os
import pickle
import subprocess
import sys
import threading
import time

import numpy as np
from numba import typeof

from stereosim.core.errors import UserError
from stereosim.core.progress import compile_notice, current_watch
from stereosim.nna.descriptor import compute_descriptor
from stereosim.quant.intconv import descriptor_dtype
from stereosim.sim.cycle.compiled.layout import TraceData, serialise
from stereosim.sim.cycle.compiled.ring import cursors_at
from stereosim.sim.cycle.compiled.sampler import WindowLog, next_instant, record_window, sample
from stereosim.sim.cycle.compiled.schedule import advance_streams, walk_all
from stereosim.sim.cycle.compiled.source import note_source_wait
from stereosim.sim.cycle.plan import ChipPlan, build_plan
from stereosim.sva.pipeline.pipeline import sva_stream

#: the longest this process waits for the helper before it goes on alone (a safety net:
#: whatever the helper has not compiled then, the run compiles itself)
WAIT_S = 300.0
SMALL_ROWS = 24  # the stand-in frame of the helper's walkers: enough rows for every window


def _stand_in_plan(plan: ChipPlan) -> ChipPlan:
    """A plan of the same configuration on a few rows (the same kernels and types, a small
    net; a chip built for its camera's frame size is built for these rows instead, which
    changes no type); the plan itself where the configuration needs more rows."""
    h, w = plan.shape
    if h <= SMALL_ROWS:
        return plan
    cfg = plan.cfg
    any_size = dataclasses.replace(cfg, source=dataclasses.replace(
        cfg.source, camera_width=0, camera_height=0))
    try:
        return build_plan(any_size, (SMALL_ROWS, w))
    except UserError:
        return plan


def _loop_signature(plan: ChipPlan) -> tuple:
    net, _ = serialise(_stand_in_plan(plan))
    walked = np.zeros(net.streams.shape[0], np.int64)
    return (typeof(net), typeof(walked))


def _cached(dispatcher, sig: tuple) -> bool:
    """Whether numba's on-disk cache holds ``dispatcher`` for ``sig``: its index has the key
    (True when it cannot tell: then the run compiles in one process, as without a helper)."""
    try:
        cache = dispatcher._cache
        key = cache._index_key(sig, dispatcher.targetctx.codegen())
        return cache._cache_file._load_index().get(key) is not None
    except Exception:  # noqa: BLE001 -- numba's internals: when in doubt, no helper
        return True


@contextlib.contextmanager
def prewarm(plan: ChipPlan, *, always: bool = False):
    """Within the block, the run of ``plan`` finds its kernels compiled (see the module's
    docstring); on a warm cache this does nothing but look it up. Yields the helper process
    (None when none was started); ``always`` starts one even on a warm cache (tests)."""
    if os.environ.get("STEREOSIM_PREWARM", "1").strip() == "0":
        yield None
        return
    try:
        sig = _loop_signature(plan) if always or not advance_streams.overloads else None
    except Exception:  # noqa: BLE001 -- a stand-in the plan refuses: no helper, the run as ever
        sig = None
    if sig is None or not always and _cached(advance_streams, sig):
        yield None  # loaded in this process already, or in the cache
        return
    helper = _start_helper(plan)
    try:
        advance_streams.compile(sig)
        _compile_descriptors(plan)
        _wait(helper)
        yield helper
    finally:
        helper.kill()
        helper.wait()
        for pipe in (helper.stdin, helper.stdout):
            with contextlib.suppress(OSError):
                pipe.close()


def _start_helper(plan: ChipPlan) -> subprocess.Popen:
    """The helper process, with its job (the configuration and frame size) on its stdin; it
    inherits this process's environment, so it fills the same numba cache."""
    helper = subprocess.Popen(
        [sys.executable, "-m", __name__], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL)
    job = pickle.dumps((plan.cfg, plan.shape))
    helper.stdin.write(len(job).to_bytes(8, "little") + job)
    helper.stdin.flush()  # stdin stays open: the helper exits when it closes
    return helper


def _wait(helper: subprocess.Popen) -> None:
    """Wait for the helper's report (at most :data:`WAIT_S`) and hand it to the compile
    notice; a helper that fails or says nothing is ignored."""
    box: list = []
    reader = threading.Thread(target=lambda: box.append(helper.stdout.readline()), daemon=True)
    t0 = time.perf_counter()
    reader.start()
    reader.join(WAIT_S)
    waited = time.perf_counter() - t0
    try:
        report = json.loads(box[0]) if box and box[0] else None
    except ValueError:
        report = None
    watch = current_watch()
    if watch is not None and report is not None:
        watch.add_helper({tuple(k) for k in report["kernels"]}, waited)


# ---- the helper process ------------------------------------------------------------------------


def _compile_walkers(plan: ChipPlan) -> None:
    net, _ = serialise(_stand_in_plan(plan))
    walk_all(net, False)  # before any event: every walker runs and finds nothing to do
    # and the pass a run makes when it stops (a run may stop before any event), which would
    # otherwise compile in the run's own process, the longer of the two
    note_source_wait(net)


def _compile_sampler(plan: ChipPlan) -> None:
    """The trace sampler's kernels, which a traced run (``--vcd``, ``--timeline``) compiles
    after its pass (:func:`.run._trace`): run as it runs them, on the stand-in's event net
    before any event, over its first few clock edges, with stand-in data of the run's types
    (:class:`.layout.TraceData`)."""
    stand_in = _stand_in_plan(plan)
    net, _ = serialise(stand_in)
    h, w = stand_in.shape
    data = TraceData(np.zeros((1, 2, h, w), np.uint64), np.zeros((1, h, w), np.int32),
                     np.int64((1 << stand_in.word_bits) - 1), np.int64(0))
    periods = np.array([d.period_fs for d in stand_in.domains.values()], np.int64)
    n_sig = len(stand_in.signals)
    scratch = np.zeros(n_sig, np.uint64)
    done = np.full((len(stand_in.blocks) + len(stand_in.fifos), 2), -1)
    start = int(periods.max())
    cursors_at(net, start - 1, True)
    sample(net, data, start - 1, scratch, done)
    size = max(1 << 10, 4 * n_sig)
    ctl = np.array([0, next_instant(periods, start - 1)], np.int64)
    record_window(net, data, periods, 3 * start, WindowLog(
        ctl, scratch.copy(), np.zeros(size, np.int64), np.zeros(size, np.int32),
        np.zeros(size, np.uint64), scratch.copy(), done))


def _stand_in_view(plan: ChipPlan, rng) -> np.ndarray:
    """A small random grey view, a little wider than the disparity range."""
    w = min(plan.shape[1], plan.cfg.sva.disparities + 32)
    return rng.integers(0, 256, (SMALL_ROWS, w), dtype=np.uint8)


def _compile_descriptors(plan: ChipPlan) -> None:
    """The NNA's data kernels, on a small random view (in this process, while the helper
    compiles the rest). A stand-in the descriptor refuses (a window taller than it, say) only
    leaves the kernels to the run."""
    view = _stand_in_view(plan, np.random.default_rng(0))
    with contextlib.suppress(UserError, ValueError):
        compute_descriptor(view, plan.spec.nna)


def _compile_sva_stream(plan: ChipPlan) -> None:
    """The SVA's data kernels, on random descriptors of the run's type."""
    rng = np.random.default_rng(0)
    left = _stand_in_view(plan, rng)
    dtype = descriptor_dtype(plan.descriptor_bits)
    top = 1 << plan.descriptor_bits
    desc_l, desc_r = (rng.integers(0, top, left.shape, dtype=np.uint64).astype(dtype)
                      for _ in range(2))
    sva_stream(desc_l, desc_r, left, plan.spec.sva, plan.part_bits)


def _helper_main() -> None:
    size = int.from_bytes(sys.stdin.buffer.read(8), "little")
    cfg, shape = pickle.loads(sys.stdin.buffer.read(size))

    def orphaned() -> None:  # the parent gone (its end of the pipe closed): stop at once
        sys.stdin.buffer.read()
        os._exit(0)

    threading.Thread(target=orphaned, daemon=True).start()
    # the run's own notice, silent here: it collects what this process compiles
    with compile_notice(stream=io.StringIO(), delay_s=math.inf) as watch:
        plan = build_plan(cfg, shape)
        _compile_walkers(plan)
        _compile_sva_stream(plan)
        _compile_sampler(plan)
    sys.stdout.write(json.dumps({"kernels": sorted(watch.kernels)}) + "\n")
    sys.stdout.flush()
    os._exit(0)  # not a normal shutdown: the watcher thread is blocked reading stdin


if __name__ == "__main__":
    _helper_main()
