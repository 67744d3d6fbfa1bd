"""The machine a benchmark ran on, in one line: speed ratios move with the CPU, so every figure
names it (the CPU's model from /proc/cpuinfo where there is one, the core count, and the widest
SIMD level LLVM -- numba's back end -- finds on the host).

A script's ``--write-result`` keeps what it prints in a dated, machine-named result file,
``benchmarks/results/<script>-<YYYY-MM-DD>-<cpu>.md`` (:func:`result_file`): the docs link those
files instead of quoting one machine's log."""

from __future__ import annotations

import contextlib
import io
import os
import platform
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import llvmlite.binding as llvm

RESULTS = Path(__file__).resolve().parent / "results"
ROOT = RESULTS.parents[1]

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


def cpu_slug() -> str:
    """The CPU for a file name: the model and LLVM's name for it, e.g. ``amd-epyc-znver4``."""
    words = cpu_model().lower()
    host = llvm.get_host_cpu_name().lower()
    if host and host not in words:
        words += f" {host}"
    return re.sub(r"[^a-z0-9]+", "-", words).strip("-") or "unknown-cpu"


def result_path(script: str, when: datetime) -> Path:
    """``benchmarks/results/<script>-<YYYY-MM-DD>-<cpu>.md``: one file a script, day and CPU."""
    return RESULTS / f"{script}-{when:%Y-%m-%d}-{cpu_slug()}.md"


def _code_version() -> str:
    """The commit the run measured, and whether the working tree differed from it."""
    def git(*args: str) -> str:
        done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                              check=False)
        return done.stdout.strip() if done.returncode == 0 else ""

    head = git("rev-parse", "--short", "HEAD")
    if not head:
        return "not a git checkout"
    dirty = git("status", "--porcelain", "--untracked-files=no")
    return head + (" with uncommitted changes" if dirty else "")


class _Tee(io.TextIOBase):
    """Writes go to the terminal's stdout and to a buffer."""

    def __init__(self, out, copy: io.StringIO):
        self.out, self.copy = out, copy

    def write(self, text: str) -> int:
        self.copy.write(text)
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()


@contextlib.contextmanager
def result_file(script: str, write: bool) -> Iterator[None]:
    """What the block prints, also appended to :func:`result_path` when ``write`` is set (a
    block that raises writes nothing): one section a run, headed by its time, its command, the
    machine, the load average before and after, the code and the library versions."""
    if not write:
        yield
        return
    from stereosim.sim.api import version_text

    start, load = datetime.now(UTC), os.getloadavg()
    copy = io.StringIO()
    with contextlib.redirect_stdout(_Tee(sys.stdout, copy)):
        yield
    path = result_path(script, start)
    command = shlex.join(["python", f"benchmarks/{script}.py", *sys.argv[1:]])
    head = [] if path.exists() else [f"# {script}, {start:%Y-%m-%d}, {cpu_model()}", ""]
    section = [*head, f"## {start:%H:%M} UTC: `{command}`", "",
               f"- machine: {describe()}",
               f"- load average (1 min): {load[0]:.1f} before, {os.getloadavg()[0]:.1f} after",
               f"- code: {_code_version()}; {version_text()}", "",
               "```text", copy.getvalue().rstrip("\n"), "```", ""]
    RESULTS.mkdir(exist_ok=True)
    with path.open("a") as f:
        f.write("\n".join(section) + "\n")
    print(f"result appended to {path.relative_to(ROOT)}")
