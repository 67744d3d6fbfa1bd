"""Regenerate the pictures and figures of docs/reading-traces.md with the project's own commands.

    python docs/make_trace_pictures.py

The windows are not typed in: ``benchmarks/reading_traces.py`` runs the chip on the embedded
default scene (Middlebury 2014 Motorcycle, 741x500), finds the instants each section is about
(the line buffer full, the first ready row, the first stall of a shallow FIFO, the first output
word) and gives each picture its ``stereosim run --trace-window`` and ``stereosim wave
--window``. Each picture is then one ``stereosim run ... --vcd`` (shared by the pictures of one
run) followed by one ``stereosim wave``; the commands are printed as they run, so any of them
can be repeated by hand. The VCDs go to a temporary folder, the PNGs to docs/img/. Last, the
figures the page quotes are written into its generated blocks
(``python benchmarks/doc_figures.py --write trace-...``, measured on the same runs).
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
IMG = os.path.join(HERE, "img")
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "benchmarks"))

import doc_figures  # noqa: E402  (benchmarks/ is a folder of scripts, not a package)
import reading_traces  # noqa: E402


def sh(args: list[str]) -> None:
    print("$ " + " ".join(shlex.quote(a) for a in args), flush=True)
    subprocess.run(args, check=True)


def main() -> int:
    os.makedirs(IMG, exist_ok=True)
    exe = [sys.executable, "-m", "stereosim.sim.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        dumps = {}  # (chip, run window) -> its VCD: one run for the pictures that share it
        for pic in reading_traces.pictures():
            key = (pic.overrides, pic.run_window)
            if key not in dumps:
                dumps[key] = os.path.join(tmp, f"run{len(dumps)}.vcd")
                sh([*exe, "run", "--out", os.path.join(tmp, "out"), "--vcd", dumps[key],
                    *reading_traces.set_options(pic.overrides),
                    "--trace-window", pic.run_window])
            wave = [*exe, "wave", dumps[key], "--signals", pic.signals,
                    "--png", os.path.join(IMG, pic.png), "--title", pic.title]
            if pic.wave_window:
                wave += ["--window", pic.wave_window]
            sh(wave)
    return doc_figures.main([*reading_traces.SECTIONS, "--write"])


if __name__ == "__main__":
    raise SystemExit(main())
