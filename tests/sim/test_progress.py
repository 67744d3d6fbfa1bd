"""Feedback on long work (sim.progress): when bars show, the readable kernel's bar, and the
one-line notice before numba compiles."""

import importlib.util
import io
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from tqdm import tqdm

from stereosim.quant.quantizer import FloatModel, QuantizerConfig, quantize
from stereosim.sim import progress
from stereosim.sim.config import load_config
from stereosim.sim.cycle import kernel
from stereosim.sim.cycle.chip import run_cycle
from stereosim.sim.cycle.simulate import COMPILE_SECONDS
from stereosim.sim.progress import (
    COMPILE_MESSAGE,
    compile_notice,
    index_file,
    kernels_need_compiling,
    poller,
    progress_bar,
    show_progress,
)


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


def test_the_readable_kernel_reports_rows_without_changing_the_run(monkeypatch, capsys):
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

PY = f"{sys.version_info[0]}{sys.version_info[1]}"
SOURCE = """
from numba import njit


@njit(cache=True)
def add_one(x):
    return x + 1


@njit(cache=True)
def never_called(x):
    return x - 1


def plain(x):
    return x
"""


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_compile_notice_prints_once_and_not_when_the_cache_is_warm(tmp_path):
    src = tmp_path / "h4_kernels.py"
    src.write_text(SOURCE)
    other = tmp_path / "h4_unused.py"
    other.write_text(SOURCE.replace("add_one", "add_two"))
    past = time.time() - 100
    for path in (src, other):
        os.utime(path, (past, past))
    first = _load(src, "h4_kernels")
    # numba's name: file stem, qualname, first line (the decorator's), Python version
    assert index_file(first.add_one).name == f"h4_kernels.add_one-5.py{PY}.nbi"
    assert not index_file(first.add_one).exists()
    out = io.StringIO()
    assert compile_notice([[first]], 40, stream=out)  # cold: nothing on disk
    assert out.getvalue() == COMPILE_MESSAGE.format(seconds=40) + "\n"
    assert first.add_one(1) == 2  # compiles and writes the cache
    assert index_file(first.add_one).is_file()
    assert not compile_notice([[first]], 40, stream=out)  # loaded in this process
    assert out.getvalue().count("\n") == 1
    # a new process (a fresh module object): the cache is warm; a module of the group that
    # has no index at all (kernels never run, or only called by other kernels) does not count
    again = _load(src, "h4_kernels")
    unused = _load(other, "h4_unused")
    assert not again.add_one.signatures
    assert not kernels_need_compiling([[again, unused]])
    assert kernels_need_compiling([[unused]])  # alone, nothing of it is cached
    # an edit (source newer than the index) makes it cold again
    future = time.time() + 100
    os.utime(src, (future, future))
    assert kernels_need_compiling([[_load(src, "h4_kernels"), unused]])
    assert compile_notice([[_load(src, "h4_kernels")]], 7, stream=out)
    assert out.getvalue().splitlines()[-1].endswith("about 7 s; cached afterwards)")


@pytest.mark.parametrize("env", ["", "1"])
def test_the_notice_goes_to_stderr_only(tmp_path, capsys, monkeypatch, env):
    monkeypatch.setenv("TQDM_DISABLE", env)  # bars off or on: the notice is not a bar
    src = tmp_path / f"h4_stderr{env}.py"
    src.write_text(SOURCE)
    module = _load(src, src.stem)
    assert compile_notice([[module]], 40)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert captured.err.startswith("stereosim: compiling")


def test_a_run_announces_the_compile_with_an_empty_cache(tmp_path):
    """The real kernel groups, in a process whose numba cache is an empty folder: the notice
    is due, on stderr only (nothing is compiled here: the check reads the cache folder)."""
    code = ("from stereosim.sim.cycle.simulate import announce_compiling as a; "
            "print(a('fast'), a('functional'))")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, check=False,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "True True\n"
    assert done.stderr.splitlines() == [
        COMPILE_MESSAGE.format(seconds=COMPILE_SECONDS["fast"]),
        COMPILE_MESSAGE.format(seconds=COMPILE_SECONDS["functional"])]
