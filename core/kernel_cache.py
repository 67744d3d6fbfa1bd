"""numba's on-disk cache of the kernels, kept in step with the whole package's source.

numba keys a cached kernel on its own file's content only. A kernel that calls or inlines
kernels of other modules (the fused SVA stream inlines sva/sgm/sgm.py's,
sva/hamming/cost.py's, ...; the compiled engine's kernels call each other across
sim/cycle/compiled/), or freezes a constant of another module, holds their code too: after an
edit of sva/sgm/sgm.py numba served the fused stream of sva/pipeline/pipeline.py from its cache
as it was before the edit -- stale machine code, with nothing to say so.

:class:`PackageLocator` finds the same cache folder as numba's own locators but stamps every
kernel of a file under the package's folder with (numba's stamp of its file, :func:`source_digest`
of the package's modules): an edit of any module recompiles every kernel, once, and the
compile notice says so. Importing this module registers it; ``njit`` is re-exported so that a
kernel module gets it from here (tests/core/test_kernel_cache.py checks that every cached kernel
uses the locator). numba's ``NUMBA_CACHE_LOCATOR_CLASSES``, when set, replaces the chain.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from numba import njit
from numba.core import caching

__all__ = ["PackageLocator", "njit", "njit_borrowing", "source_digest"]

def njit_borrowing(**options):
    """``njit(**options)`` with numba's reference counting off, for a kernel that only reads and
    writes the arrays it is given: it makes no array and returns none, and its caller keeps
    every array alive. numba otherwise counts an array up and down, with atomic instructions,
    each time the kernel takes one out of a tuple (the compiled engine's ``Net``): 0.35 us of a
    call of 0.4 us when the call moves nothing, which the stream loop makes some 60,000 times a
    720p frame. numba refuses to compile such a kernel that needs the counts (an array made
    inside it). ``_nrt`` is numba's own option for this (numba.core.options)."""
    return njit(_nrt=False, **options)


# the class that holds numba's chain of locators (_CacheImpl in older numba)
_IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl

# the package's root: stereosim/ (the checkout in an editable install)
ROOT = Path(__file__).resolve().parents[1]
# the folders whose modules kernels are built from (the package's sub-packages)
SOURCE_FOLDERS = ("core", "sim", "nna", "sva", "quant", "traces")


def source_files(root: Path | None = None) -> list[Path]:
    """The package's modules (under ``root``, default :data:`ROOT`): the root's own and every
    ``.py`` under :data:`SOURCE_FOLDERS`, in a fixed order."""
    root = ROOT if root is None else root
    files = sorted(root.glob("*.py"))
    for folder in SOURCE_FOLDERS:
        files += sorted((root / folder).rglob("*.py"))
    return files


def digest_of(files: list[Path], root: Path) -> str:
    """SHA-256 over the files' paths (relative to ``root``) and contents."""
    h = hashlib.sha256()
    for f in files:
        h.update(f.relative_to(root).as_posix().encode() + b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """:func:`digest_of` the package's modules, once a process."""
    return digest_of(source_files(ROOT), ROOT)


def _under_root(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(ROOT)
    except (OSError, ValueError):
        return False


class PackageLocator(caching._CacheLocator):
    """The locator numba's own chain picks for a kernel (its cache folder, its disambiguator),
    with :func:`source_digest` added to the source stamp, for files under the package's folder
    (the checkout's benchmarks and tests too: their kernels call the package's)."""

    def __init__(self, inner: caching._CacheLocator):
        self.inner = inner
        # numba's warning that a kernel cannot be cached names the locator's file
        self._py_file = getattr(inner, "_py_file", None)

    def ensure_cache_path(self):
        self.inner.ensure_cache_path()

    def get_cache_path(self):
        return self.inner.get_cache_path()

    def get_source_stamp(self):
        return (self.inner.get_source_stamp(), source_digest())

    def get_disambiguator(self):
        return self.inner.get_disambiguator()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _under_root(py_file):
            return None
        for other in _IMPL._locator_classes:
            if other is cls:
                continue
            inner = other.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner)
        return None


def install() -> None:
    """Put :class:`PackageLocator` first in numba's chain of locators (once)."""
    chain = _IMPL._locator_classes
    if PackageLocator not in chain:
        chain.insert(0, PackageLocator)


install()
