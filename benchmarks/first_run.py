"""The first `stereosim run` after an install: its wall time on an empty numba cache.

    python benchmarks/first_run.py [--repeat 3] [--alone] [--write-result] [-- RUN ARGS ...]

Each repetition runs ``stereosim run --out TMP [RUN ARGS]`` (the embedded default scene unless
the arguments name a pair) in a fresh process whose ``NUMBA_CACHE_DIR`` is a new empty folder,
so every kernel compiles as in a fresh clone; it prints the wall time and the run's own compile
line from stderr. ``--alone`` also runs each repetition with ``STEREOSIM_PREWARM=0`` (one process
compiles everything, as before sim/cycle/compiled/prewarm.py), alternating with the default
run so that both see the same machine. The load average is printed with each figure: a busy
machine compiles slower, and on 2 cores the helper process competes with any other work.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

from machine import describe, result_file

NOTICE = re.compile(r"stereosim: compiling took .*")


def one(args: list[str], prewarm: bool) -> tuple[float, str]:
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "STEREOSIM_PREWARM": "1" if prewarm else "0"}
        t0 = time.perf_counter()
        done = subprocess.run(["stereosim", "run", "--out", out, *args], env=env,
                              capture_output=True, text=True, check=False)
        wall = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"first_run: stereosim run failed: {done.stderr.strip()[-400:]}")
    notice = NOTICE.search(done.stderr)
    return wall, notice.group(0) if notice else "(no compile notice)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--alone", action="store_true",
                    help="also run each repetition without the helper process (in turn)")
    ap.add_argument("--write-result", action="store_true",
                    help="also append the output to benchmarks/results/<script>-<date>-<cpu>.md")
    ap.add_argument("run_args", nargs="*", help="after --: arguments of stereosim run")
    args = ap.parse_args(argv)
    with result_file("first_run", args.write_result):
        measure(args)
    return 0


def measure(args) -> None:
    print(f"machine: {describe()}")
    kinds = [True, False] if args.alone else [True]
    walls: dict[bool, list[float]] = {k: [] for k in kinds}
    for i in range(args.repeat):
        for prewarm in kinds:
            load = os.getloadavg()[0]
            wall, notice = one(args.run_args, prewarm)
            walls[prewarm].append(wall)
            label = "two processes" if prewarm else "one process "
            print(f"run {i + 1} {label}: {wall:6.1f} s wall (load {load:.1f} before) -- {notice}",
                  flush=True)
    for prewarm, w in walls.items():
        label = "two processes (default)" if prewarm else "one process (STEREOSIM_PREWARM=0)"
        print(f"{label}: " + ", ".join(f"{x:.1f}" for x in w) + " s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
