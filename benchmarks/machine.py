"""The machine a benchmark ran on, in one line: speed ratios move with the CPU, so every figure
names it (the CPU's model from /proc/cpuinfo where there is one, the core count, and the widest
SIMD level LLVM -- numba's back end -- finds on the host)."""

from __future__ import annotations

import os
import platform
from pathlib import Path

import llvmlite.binding as llvm

# the widest first: the features LLVM reports for each level
SIMD_LEVELS = (("AVX-512", ("avx512f", "avx512bw", "avx512vl")), ("AVX2", ("avx2", "fma")),
               ("AVX", ("avx",)), ("SSE4.2", ("sse4.2",)), ("NEON", ("neon",)))


def simd_level() -> str:
    """The widest level of :data:`SIMD_LEVELS` whose every feature the host CPU has."""
    features = llvm.get_host_cpu_features()
    for name, needs in SIMD_LEVELS:
        if all(features.get(f, False) for f in needs):
            return name
    return "none found"


def cpu_model() -> str:
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def describe() -> str:
    """E.g. ``AMD EPYC (LLVM: znver4), 2 cores, SIMD AVX-512``."""
    return (f"{cpu_model()} (LLVM: {llvm.get_host_cpu_name()}), {os.cpu_count()} cores, "
            f"SIMD {simd_level()}")
