"""The cold-cache helper process of the compiled engine (sim/cycle/compiled/prewarm.py): the
run is the same with it, the helper never outlives the block, and the compile notice counts
what it compiled. (A real cold compile takes half a minute of CPU: benchmarks/first_run.py
measures it; here the suite's cache is warm, so a forced helper compiles nothing.)"""

from __future__ import annotations

import io
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba import typeof

from stereosim.core.config import load_config
from stereosim.core.progress import COMPILE_MESSAGE, COMPILED_WITH_HELPER, compile_notice
from stereosim.sim.cycle.compiled import prewarm as pw
from stereosim.sim.cycle.compiled.layout import serialise
from stereosim.sim.cycle.compiled.sampler import record_window, sample
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.simulate import simulate

HELPER_DONE = re.compile(re.escape(COMPILED_WITH_HELPER).replace(r"\{seconds:\.1f\}", r"[0-9.]+")
                         .replace(r"\{kernels\}", "([0-9]+)").replace(r"\{helper\}", "([0-9]+)"))


@pytest.fixture(scope="module")
def plan():
    cfg = load_config(overrides={"sva.disparities": 16})
    return build_plan(cfg, (20, 48))


def _pair(seed=0):
    rng = np.random.default_rng(seed)
    return rng.integers(0, 256, (2, 20, 48), dtype=np.uint8)


def test_a_forced_helper_leaves_the_run_unchanged_and_is_gone_after_it(plan):
    left, right = _pair()
    alone = simulate(plan, left, right)
    out = io.StringIO()
    with compile_notice(stream=out, delay_s=1e9) as watch:
        with pw.prewarm(plan, always=True) as helper:
            assert helper is not None
            helped = simulate(plan, left, right)
    assert helper.returncode is not None  # waited for and reaped
    assert np.array_equal(alone.words, helped.words) and alone.report == helped.report
    # the warm cache: the helper loaded every kernel and compiled none, and said so
    assert watch.helper_kernels == set() and out.getvalue() == ""


def test_the_helper_is_killed_when_the_block_raises(plan):
    with pytest.raises(KeyboardInterrupt), pw.prewarm(plan, always=True) as helper:
        raise KeyboardInterrupt
    assert helper.returncode is not None


def test_the_helper_exits_when_its_parent_is_gone(plan):
    helper = pw._start_helper(plan)
    helper.stdin.close()  # what the parent's death does to the pipe
    assert helper.wait(timeout=120) == 0
    assert helper.stdout.read() == b""  # stopped before its report
    helper.stdout.close()


def test_a_failing_helper_costs_nothing_but_its_time(plan, monkeypatch):
    def broken(_plan):
        return subprocess.Popen([sys.executable, "-c", "import sys; sys.exit(3)"],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE)

    monkeypatch.setattr(pw, "_start_helper", broken)
    left, right = _pair(1)
    with compile_notice(stream=io.StringIO(), delay_s=1e9) as watch:
        with pw.prewarm(plan, always=True) as helper:
            words = simulate(plan, left, right).words
    assert helper.returncode == 3 and watch.helper_kernels == set()
    assert np.array_equal(words, simulate(plan, left, right).words)


def test_switched_off_or_warm_starts_no_helper(plan, monkeypatch):
    with pw.prewarm(plan) as helper:  # the suite's cache holds the stream loop
        assert helper is None
    monkeypatch.setenv("STEREOSIM_PREWARM", "0")
    with pw.prewarm(plan, always=True) as helper:
        assert helper is None


def test_the_notice_counts_the_helpers_kernels_and_the_wait():
    out = io.StringIO()
    kernels = {("m", "f", "(int64,)"), ("m", "g", "(float64,)")}
    with compile_notice(stream=out, delay_s=0.5) as watch:
        watch.add_helper(kernels, 2.0)  # waited 2 s: announced then
        assert out.getvalue().splitlines() == [COMPILE_MESSAGE]
    done = HELPER_DONE.fullmatch(out.getvalue().splitlines()[1])
    assert done and done.group(1) == "2" == done.group(2)
    assert watch.seconds == pytest.approx(2.0)


def test_the_helpers_report_names_what_it_compiled(plan, tmp_path, monkeypatch):
    """On an empty cache of its own, the helper's report lists the walkers, the SVA's stream
    and the trace sampler among its kernels (the stand-in frame is small: a few seconds of
    compiling the walkers, the SVA's and the sampler's kernels)."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))  # the helper inherits it
    # and compiles without LLVM's optimisation passes: the report names the kernels it
    # compiled, whatever the optimisation (about a quarter of the helper's time saved)
    monkeypatch.setenv("NUMBA_OPT", "0")
    helper = pw._start_helper(plan)
    line = helper.stdout.readline()
    helper.stdin.close()
    assert helper.wait(timeout=600) == 0
    helper.stdout.close()
    names = {k[1] for k in json.loads(line)["kernels"]}
    assert {"walk_nna", "walk_sva", "walk_fifos", "stream_rows"} <= names
    # and the trace sampler's, which a traced run (--vcd) compiled after the helper had gone:
    # for the very types a traced run calls them with (this process loads them, warm)
    assert {"record_window", "sample", "next_instant", "cursors_at", "sample_sva"} <= names
    reported = {(k[1], k[2]) for k in json.loads(line)["kernels"]}
    left, right = _pair()
    simulate(plan, left, right, window=(10**6, 10**8))  # (a start > 0 samples it first)
    for kernel in (record_window, sample):
        assert kernel.signatures
        for sig in kernel.signatures:
            assert (kernel.py_func.__qualname__, str(sig)) in reported
    assert "advance_streams" not in names  # the parent's part


@pytest.mark.parametrize("preset", ["paper-720p", "1080p60", "census-baseline", "robust-720p"])
@pytest.mark.parametrize("over", [{}, {"sva.pairs": 2, "source.kind": "camera",
                                       "source.frame_buffers": 2}])
def test_the_stand_in_net_has_the_run_s_numba_type(preset, over):
    """The stream loop compiled for the stand-in's types is the one the run calls: the event
    net of a 24-row frame has the numba type of the real frame's, streams of frames included,
    for every preset (whole frames, column tiles, cameras, frame buffers, several layers; here
    on 320 x 96 frames, so without the preset's camera size)."""
    cfg = load_config(Path(__file__).resolve().parents[4] / "configs" / f"{preset}.toml",
                      overrides={**over, "source.camera_width": 0, "source.camera_height": 0})
    real = build_plan(cfg, (96, 320), frames=3)
    stand_in = pw._stand_in_plan(real)
    assert stand_in.shape[0] == pw.SMALL_ROWS
    assert pw._loop_signature(real) == (typeof(serialise(real)[0]),
                                        typeof(np.zeros(len(serialise(real)[0].streams),
                                                        np.int64)))


@pytest.mark.parametrize("preset", ["paper-720p", "1080p60"])
def test_a_chip_built_for_its_cameras_size_gets_a_small_stand_in(preset):
    """A preset carries its camera's frame size, which refuses other frames; the helper's
    stand-in is built for a few rows all the same (the size changes no numba type)."""
    cfg = load_config(Path(__file__).resolve().parents[4] / "configs" / f"{preset}.toml")
    real = build_plan(cfg, (cfg.source.camera_height, cfg.source.camera_width))
    assert pw._stand_in_plan(real).shape == (pw.SMALL_ROWS, cfg.source.camera_width)
