"""numba's cache follows every module a kernel is built from (core/kernel_cache.py)."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba.core import caching
from numba.core.dispatcher import Dispatcher
from numba.core.errors import TypingError

from stereosim.core import kernel_cache
from stereosim.core.kernel_cache import ROOT, PackageLocator, digest_of, source_files
from stereosim.sim.api import run
from stereosim.sim.cycle.compiled import fifo, schedule


def _cached_kernel_modules():
    """The package's modules that define a kernel numba caches on disk, and their text."""
    for path in source_files():
        text = path.read_text()
        if "cache=True" in text:
            rel = path.relative_to(ROOT).with_suffix("")
            yield "stereosim." + ".".join(rel.parts), text


def test_every_cached_kernel_of_the_package_uses_the_package_locator():
    """A module that decorated its kernels before the locator was in would keep numba's stamp
    of its own file alone: each takes ``njit`` from core.kernel_cache, which installs it."""
    seen = 0
    for name, text in _cached_kernel_modules():
        assert "from stereosim.core.kernel_cache import njit" in text, name
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            cache = getattr(value, "_cache", None)
            if isinstance(value, Dispatcher) and not isinstance(cache, caching.NullCache):
                assert isinstance(cache._impl.locator, PackageLocator), f"{name}.{attr}"
                seen += 1
    assert seen > 100, seen  # the package has well over a hundred cached kernels


def test_the_stamp_is_the_files_and_the_packages_digest():
    from stereosim.sva.pipeline import pipeline

    locator = pipeline.stream_rows._cache._impl.locator
    inner = locator.inner
    assert not isinstance(inner, PackageLocator)
    assert locator.get_source_stamp() == (inner.get_source_stamp(), kernel_cache.source_digest())
    assert locator.get_cache_path() == inner.get_cache_path()


def test_the_locator_names_the_kernels_file_as_numba_does():
    """numba's warning that a compiled kernel cannot be cached (dynamic globals, lifted code)
    names ``locator._py_file``; the package's locator keeps the file numba's own one found, so
    that warning is a warning and not an AttributeError (seen with NUMBA_OPT=0)."""
    from stereosim.sva.pipeline import pipeline

    locator = pipeline.stream_rows._cache._impl.locator
    assert isinstance(locator, PackageLocator)
    assert locator._py_file == locator.inner._py_file
    assert locator._py_file.endswith("pipeline.py")


def test_the_digest_changes_with_any_module(tmp_path):
    for name, text in (("a.py", "x = 1\n"), ("b.py", "y = 2\n")):
        (tmp_path / name).write_text(text)
    files = sorted(tmp_path.glob("*.py"))
    before = digest_of(files, tmp_path)
    assert digest_of(files, tmp_path) == before
    (tmp_path / "b.py").write_text("y = 3\n")  # same size
    assert digest_of(files, tmp_path) != before


DEPENDENCY = """
from numba import njit


@njit(cache=True, inline="always")
def value():
    return {value}
"""
USER = """
from numba import njit

from dependency import value


@njit(cache=True)
def twice():
    return 2 * value()
"""
RUN = """
import sys
from pathlib import Path

if sys.argv[2] == "package":
    from stereosim.core import kernel_cache

    kernel_cache.ROOT = Path(sys.argv[1])  # this folder plays the package
sys.path.insert(0, sys.argv[1])
import user

print(user.twice())
"""


def _twice_after_an_edit(folder, locator):
    """``user.twice()`` (2 x the inlined ``dependency.value()``) with value() = 1, then again
    in a new process after value() became 2."""
    folder.mkdir()
    (folder / "user.py").write_text(USER)
    results = []
    for value in (1, 2):
        (folder / "dependency.py").write_text(DEPENDENCY.format(value=value))
        out = subprocess.run([sys.executable, "-c", RUN, str(folder), locator],
                             capture_output=True, text=True, timeout=120, cwd=folder)
        assert out.returncode == 0, out.stderr
        results.append(int(out.stdout))
    return results


def test_an_edit_of_an_inlined_kernel_recompiles_its_callers(tmp_path):
    """numba alone serves the caller from its cache after an edit of the kernel it inlines
    (the value before the edit); with the package's locator the caller is compiled again."""
    assert _twice_after_an_edit(tmp_path / "plain", "numba") == [2, 2]  # stale
    assert _twice_after_an_edit(tmp_path / "package", "package") == [2, 4]


def test_a_borrowing_kernel_works_on_given_arrays_and_cannot_make_one():
    """``njit_borrowing``: numba's reference counts off. A kernel that reads and writes the
    arrays it is given runs as the plain one does; one that makes an array is refused at
    compile time (a typing error), not run without the counts it needs."""
    def fill(a, b):
        for i in range(a.shape[0]):
            b[i] = 2 * a[i] + 1

    def make(n):
        return np.zeros(n).sum()

    a = np.arange(7)
    plain, borrowed = np.zeros(7, np.int64), np.zeros(7, np.int64)
    kernel_cache.njit()(fill)(a, plain)
    kernel_cache.njit_borrowing()(fill)(a, borrowed)
    assert borrowed.tolist() == plain.tolist() == (2 * a + 1).tolist()
    assert kernel_cache.njit()(make)(3) == 0.0
    with pytest.raises(TypingError):
        kernel_cache.njit_borrowing()(make)(3)


# numba's reference counts: its runtime's functions, named in the machine code of a kernel that
# counts (the increment may be inlined, the decrement stays a call)
COUNTS = (b"NRT_incref", b"NRT_decref")
TWINS = """
from numba import njit

from stereosim.core.kernel_cache import njit_borrowing


def _copy(pair):
    a, b = pair  # an array taken out of a tuple: numba counts it up and down
    for i in range(a.shape[0]):
        b[i] = a[i]


counted = njit(cache=True)(_copy)


@njit_borrowing(cache=True)
def borrowing(pair):
    a, b = pair
    for i in range(a.shape[0]):
        b[i] = a[i]
"""


def _machine_code(kernel, sig) -> bytes:
    """The code numba built for ``kernel`` at ``sig``, as its on-disk cache holds it (numba
    links the kernels it calls into it; code loaded from the cache cannot be inspected)."""
    cache = kernel._cache
    name = cache._cache_file._load_index().get(cache._index_key(sig, kernel.targetctx.codegen()))
    assert name is not None, f"{kernel.py_func.__name__}{sig} is not in numba's cache"
    return (Path(cache._cache_path) / name).read_bytes()


def test_the_search_for_reference_counts_finds_them(tmp_path, monkeypatch):
    """What the next test looks for is there in the code of a kernel that counts (a plain
    ``njit`` one taking arrays out of a tuple) and not in its borrowing twin's."""
    (tmp_path / "nrt_twins.py").write_text(TWINS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "nrt_twins", raising=False)
    twins = importlib.import_module("nrt_twins")
    pair = (np.arange(5), np.zeros(5, np.int64))
    for kernel in (twins.counted, twins.borrowing):
        kernel(pair)
    (counted,), (borrowing,) = twins.counted.signatures, twins.borrowing.signatures
    assert any(name in _machine_code(twins.counted, counted) for name in COUNTS)
    assert not any(name in _machine_code(twins.borrowing, borrowing) for name in COUNTS)
    monkeypatch.delitem(sys.modules, "nrt_twins")


def test_the_stream_loop_runs_without_reference_counts():
    """The code a cycle run runs for the compiled engine's stream loop (every block's advance
    linked into it) and its FIFO walkers counts no array up or down: the 0.35 us of atomic
    counts a call are gone (docs/performance.md)."""
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (24, 64), dtype=np.uint8)
    result = run(img, img, mode="cycle", overrides={"sim.engine": "fast", "sva.disparities": 16})
    assert result.report["engine"] == "fast"
    linked = {schedule.advance_streams: (b"advance_whole_side", b"advance_sva_and_sink",
                                         b"advance_sva_pops"),
              fifo.walk_fifos: (b"walk_fifo",)}
    for kernel, callees in linked.items():
        assert kernel.signatures, kernel.py_func.__name__  # the run called it
        for sig in kernel.signatures:
            code = _machine_code(kernel, sig)
            assert all(callee in code for callee in callees), kernel.py_func.__name__
            assert not any(name in code for name in COUNTS), kernel.py_func.__name__
