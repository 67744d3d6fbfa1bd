"""Freed memory kept for the next frame: glibc's heap thresholds, raised once a process.

A 720p frame makes about 14 MiB of fresh arrays (descriptors, output words, disparities, the
SVA's buffers). The kernel maps each 4 KiB page on its first touch, a fault of a few
microseconds on the machines measured (docs/performance.md: about 3,600 faults, several ms, a
functional 720p frame). glibc gives large blocks back to the kernel when they are freed -- a
block above its mmap threshold is unmapped, and the heap's top is trimmed above its trim
threshold -- so a process that runs frame after frame faults the same memory in again every
frame. :func:`keep_freed_memory` raises both thresholds (``mallopt``): blocks up to
:data:`MMAP_THRESHOLD` come from the heap, and up to :data:`TRIM_THRESHOLD` of free heap is
kept, so the next frame's arrays reuse the last frame's pages.

It changes the whole process's allocator (a program that embeds stereosim keeps up to
TRIM_THRESHOLD of freed heap too), once, when :mod:`sim.api` is imported; with the environment
variable ``STEREOSIM_KEEP_HEAP=0`` it does nothing. Only glibc has ``mallopt``: elsewhere
nothing changes. The peak memory of a frame is not raised (``benchmarks/memory_cycle.py``).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import os
import sys

# mallopt's parameter numbers (glibc's malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: blocks up to this many bytes come from the heap (glibc's largest allowed value on 64 bits)
MMAP_THRESHOLD = 32 << 20
#: free heap kept before glibc gives its top back to the kernel
TRIM_THRESHOLD = 128 << 20
#: the environment variable that turns :func:`keep_freed_memory` off ("0")
ENV = "STEREOSIM_KEEP_HEAP"

@functools.cache
def keep_freed_memory() -> bool:
    """Raise glibc's mmap and trim thresholds, once a process (a later call returns the first
    answer); True when both took, False on another C library, with ``STEREOSIM_KEEP_HEAP=0``,
    or when glibc refused a value."""
    if os.environ.get(ENV, "1") == "0" or not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(ctypes.util.find_library("c")).mallopt
    except (OSError, AttributeError, TypeError):
        return False  # not glibc (musl has no mallopt), or no C library found
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(
        mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
