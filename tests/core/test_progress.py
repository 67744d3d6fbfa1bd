"""Feedback on long work (core.progress): when bars show, the readable kernel's bar, and the
notice while numba compiles (before the first kernel compiles, and how long it took)."""

import importlib.util
import io
import math
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from tqdm import tqdm

from stereosim.core import progress
from stereosim.core.config import load_config
from stereosim.core.progress import (
    COMPILE_MESSAGE,
    compile_notice,
    poller,
    progress_bar,
    show_progress,
)
from stereosim.quant.quantizer import FloatModel, QuantizerConfig, quantize
from stereosim.sim.cycle.readable import kernel


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_bars_show_only_on_a_terminal_and_not_when_quiet(monkeypatch):
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    assert show_progress(stream=_Terminal())
    assert not show_progress(stream=io.StringIO())  # a pipe, a file, captured output
    assert not show_progress(quiet=True, stream=_Terminal())
    monkeypatch.setenv("TQDM_DISABLE", "1")
    assert not show_progress(stream=_Terminal())
    closed = _Terminal()
    closed.close()
    assert not show_progress(stream=closed)
    # under pytest stderr is captured: no bar, and nothing written
    bar = progress_bar(10, "x", "step")
    assert bar.disable
    bar.close()


def test_a_poller_moves_the_bar_to_the_count():
    assert poller(tqdm(total=5, disable=True), lambda: 3) is None
    out = _Terminal()
    bar = tqdm(total=10, file=out, disable=False, mininterval=0)
    count = [0]
    poll = poller(bar, lambda: count[0])
    for count[0] in (2, 2, 7, 10):
        poll()
    assert bar.n == 10
    bar.close()
    assert "10/10" in out.getvalue()


def _pair(h, w, shift=3):
    base = np.random.default_rng(1).integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, :w].copy(), base[:, shift:].copy()


def test_the_readable_kernel_reports_rows_without_changing_the_run(monkeypatch, capsys,
                                                                  run_cycle):
    left, right = _pair(9, 35)
    cfg = load_config(overrides={"sva.disparities": 16, "nna.descriptor": "census"})
    words, report, chip = run_cycle(left, right, cfg)
    assert capsys.readouterr().err == ""  # not a terminal: no bar
    calls = []
    monkeypatch.setattr(kernel, "PROGRESS_STEPS", 50)
    monkeypatch.setattr(progress, "show_progress", lambda quiet=False, stream=None: True)
    original = kernel.Simulator.run

    def counting_run(self, until, **kw):
        inner = kw["on_progress"]

        def spy():
            calls.append(self.steps)
            inner()

        return original(self, until, **{**kw, "on_progress": spy})

    monkeypatch.setattr(kernel.Simulator, "run", counting_run)
    words_b, report_b, chip_b = run_cycle(left, right, cfg)
    np.testing.assert_array_equal(words_b, words)
    assert report_b == report and chip_b.sim.stats() == chip.sim.stats()
    steps = chip.sim.steps
    # every 50 steps, then once at the end
    assert calls == [*range(50, steps + 1, 50), steps]
    err = capsys.readouterr().err
    assert "readable engine" in err and "9/9" in err and "row" in err


def test_the_compiled_timing_pass_reports_frames_without_changing_the_stream():
    """A stream's timing pass on the compiled engine says, between the returns of its event
    loop (each time the walkers are due), how many frames the sink has taken whole: never
    backwards, within the stream, and more than once on a stream longer than the rings."""
    from stereosim.sim.api import run_stream

    left, right = _pair(120, 200)
    pairs = [(left, right)] * 6
    over = {"sva.disparities": 32}
    heard = []
    with_progress = run_stream(pairs, overrides=over, progress=heard.append)
    plain = run_stream(pairs, overrides=over)
    assert with_progress.report == plain.report
    assert heard == sorted(heard) and 0 <= heard[0] and heard[-1] <= len(pairs)
    assert len(set(heard)) >= 3  # it moved while the pass ran, not only at its end


def test_quantize_counts_every_channel_search(monkeypatch, capsys):
    """Two layers of 3 and 2 channels: 3 + 2 scale searches and 3 (m, h) searches."""
    rng = np.random.default_rng(0)
    model = FloatModel(weights=(rng.normal(size=(3, 1, 3, 3)), rng.normal(size=(2, 3, 3, 3))),
                       biases=(np.zeros(3), np.zeros(2)), input_offset=128,
                       input_scale=1 / 64)
    image = rng.integers(0, 256, (12, 14), dtype=np.uint8)
    cfg = QuantizerConfig(n_samples=50)
    quiet = quantize(model, [image], cfg, progress=False)
    monkeypatch.setattr(progress, "show_progress", lambda quiet=False, stream=None: not quiet)
    shown = quantize(model, [image], cfg)
    for field in ("weights", "biases", "mult", "shift"):  # the bar changes nothing
        for a, b in zip(getattr(shown, field), getattr(quiet, field)):
            np.testing.assert_array_equal(a, b)
    err = capsys.readouterr().err
    assert "quantize" in err and "8/8" in err and "9/8" not in err
    quantize(model, [image], cfg, progress=False)
    assert capsys.readouterr().err == ""


# ---- the compile notice: real numba kernels in a module of a temporary folder ------------------

SOURCE = """
from numba import njit


@njit(cache=True)
def add_one(x):
    return x + 1


@njit(cache=True)
def add_two(x):
    return add_one(add_one(x))


@njit(cache=True)
def never_called(x):
    return x - 1
"""
DONE = re.compile(r"stereosim: compiling took \d+\.\d s \((\d+) numba kernels\)")


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class _Log(io.StringIO):
    """A stream that notes, at every line, whether ``kernel`` was compiled yet."""

    def __init__(self, kernel=None):
        super().__init__()
        self.kernel = kernel
        self.compiled_at_line: list[bool] = []

    def write(self, text):
        if text.endswith("\n") and self.kernel is not None:
            self.compiled_at_line.append(bool(self.kernel.signatures))
        return super().write(text)


def test_the_notice_comes_before_the_first_compile_and_says_how_long_it_took(tmp_path):
    src = tmp_path / "h4_kernels.py"
    src.write_text(SOURCE)
    first = _load(src, "h4_kernels")
    out = _Log(first.add_two)
    with compile_notice(stream=out, delay_s=0) as watch:
        assert out.getvalue() == ""  # nothing compiled yet, nothing said
        assert first.add_two(1) == 3  # compiles add_two and, inside it, add_one
    lines = out.getvalue().splitlines()
    assert lines[0] == COMPILE_MESSAGE
    assert out.compiled_at_line == [False, True]  # the notice came before the compile
    assert int(DONE.fullmatch(lines[1]).group(1)) == 2 == len(watch.kernels)
    assert 0 < watch.seconds
    # loaded in this process now: nothing compiles, nothing is said
    out = io.StringIO()
    with compile_notice(stream=out, delay_s=0):
        first.add_two(5)
    assert out.getvalue() == ""
    # a new process (a fresh module object) loads the kernels from numba's cache: silent
    again = _load(src, "h4_kernels")
    assert not again.add_two.signatures
    with compile_notice(stream=out, delay_s=0):
        assert again.add_two(1) == 3
    assert out.getvalue() == ""
    # an edit (numba's cache is keyed by the source's content) compiles again, and says so
    src.write_text(SOURCE + "\n# edited\n")
    edited = _load(src, "h4_kernels")
    with compile_notice(stream=out, delay_s=0):
        edited.add_one(1)
    lines = out.getvalue().splitlines()
    assert lines[0] == COMPILE_MESSAGE and DONE.fullmatch(lines[1]).group(1) == "1"


def test_a_notice_inside_another_reports_once_and_works_as_a_decorator(tmp_path):
    src = tmp_path / "h4_nested.py"
    src.write_text(SOURCE)
    module = _load(src, "h4_nested")
    out = io.StringIO()

    @compile_notice(stream=out, delay_s=0)
    def work():
        with compile_notice(stream=io.StringIO()):  # inner: reports through the outer one
            module.add_one(1)
        module.never_called(1)  # compiled after the inner block ended: still this notice's

    work()
    lines = out.getvalue().splitlines()
    assert lines[0] == COMPILE_MESSAGE and len(lines) == 2
    assert DONE.fullmatch(lines[1]).group(1) == "2"


@pytest.mark.parametrize("env", ["", "1"])
def test_the_notice_goes_to_stderr_only(tmp_path, capsys, monkeypatch, env):
    monkeypatch.setenv("TQDM_DISABLE", env)  # bars off or on: the notice is not a bar
    src = tmp_path / f"h4_stderr{env}.py"
    src.write_text(SOURCE)
    module = _load(src, src.stem)
    with compile_notice(delay_s=0):
        module.add_one(1)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 2
    assert captured.err.startswith("stereosim: compiling")


def test_compiling_briefly_is_not_announced_and_a_long_compile_is_while_it_runs(tmp_path):
    src = tmp_path / "h4_delay.py"
    src.write_text(SOURCE)
    module = _load(src, "h4_delay")
    out = io.StringIO()
    with compile_notice(stream=out, delay_s=60) as watch:  # a kernel compiles in far less
        module.add_one(1)
    assert out.getvalue() == "" and len(watch.kernels) == 1 and not watch.announced
    # a compile that takes longer than the delay is announced by the timer, while it runs
    out = _Log(module.add_two)
    slow = progress.CompileWatch.on_start

    def slow_start(self, ev):
        slow(self, ev)
        time.sleep(0.2)  # (the compile itself, made longer than the delay)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(progress.CompileWatch, "on_start", slow_start)
        with compile_notice(stream=out, delay_s=0.05) as watch:
            module.add_two(1)
    lines = out.getvalue().splitlines()
    assert lines[0] == COMPILE_MESSAGE and DONE.fullmatch(lines[1])
    assert out.compiled_at_line == [False, True] and watch.seconds > 0.2


def test_a_silent_watch_counts_without_a_timer(tmp_path):
    """The prewarm helper's watch (delay infinite) counts the kernels and starts no timer
    (threading.Timer cannot wait forever: it raised in a thread at every compile)."""
    src = tmp_path / "h4_silent.py"
    src.write_text(SOURCE)
    module = _load(src, "h4_silent")
    raised = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threading, "excepthook", raised.append)  # any thread's uncaught exception
        with compile_notice(stream=io.StringIO(), delay_s=math.inf) as watch:
            assert module.add_two(1) == 3
        time.sleep(0.2)  # (a timer thread, had one started, has run by now)
    assert raised == [] and watch._timer is None
    assert len(watch.kernels) == 2 and not watch.announced


def test_a_traced_run_announces_the_trace_writers_compile(tmp_path):
    """The VCD writer's kernels (traces/vcd.py), which the notice of a hand-kept module list
    missed, in a process whose numba cache is an empty folder: the notice and the time (the
    writers' own notice reports through the enclosing one)."""
    code = ("from stereosim.core.progress import compile_notice; "
            "from stereosim.sim.tracing import TraceRequest, trace_files; "
            "from stereosim.sim.synthetic_trace import synthetic_log; "
            "log = synthetic_log(50)\n"
            "with compile_notice(delay_s=0):  # (however fast this machine compiles)\n"
            f"    trace_files(log, TraceRequest(vcd={str(tmp_path / 't.vcd')!r}))")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, check=False,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert lines[0] == COMPILE_MESSAGE and len(lines) == 2
    assert int(DONE.fullmatch(lines[1]).group(1)) >= 4  # _merge, _format_size, _format, ...
    # which is why the notice may not promise that all compiling happens in the first run
    assert "by the first command that needs it" in COMPILE_MESSAGE
