"""Peak resident memory of one cycle-model frame (CNN descriptor, D = 128) at 1280x720,
1920x1080 and 3840x2160, each in a fresh process, with the sizes of what it must hold.

    python benchmarks/memory_cycle.py [--sizes 1280x720,1920x1080,3840x2160] [--write-result]

The frame is the default scene resized. What the run keeps besides the two images, their
descriptors and the output: the compiled engine's event rings (a few rows of every stream,
not the frame), the SVA's streaming buffers (W x D), the report. The baseline is the same
process after importing stereosim and compiling nothing new (numba, numpy, OpenCV loaded).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys

import cv2
from machine import describe, result_file

from stereosim.core.config import load_config
from stereosim.core.datasets import default_scene
from stereosim.core.io import to_grey
from stereosim.sim.api import run
from stereosim.sim.cycle.compiled.layout import ring_capacity
from stereosim.sim.cycle.plan import build_plan

CONFIG = {"nna.descriptor": "cnn", "sva.disparities": 128}


def child(size: str) -> None:
    w, h = (int(v) for v in size.split("x"))
    scene = default_scene()
    left = cv2.resize(to_grey(scene["left"]), (w, h), interpolation=cv2.INTER_LINEAR)
    right = cv2.resize(to_grey(scene["right"]), (w, h), interpolation=cv2.INTER_LINEAR)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    res = run(left, right, mode="cycle", overrides=CONFIG)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    plan = build_plan(load_config(overrides=CONFIG), (h, w))
    print(json.dumps({"size": size, "peak_mib": peak, "before_run_mib": base,
                      "pixels": h * w, "ring_events": ring_capacity(plan),
                      "engine": res.report["engine"],
                      "frame_ms": res.report["latency"]["frame_ms"]}))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1280x720,1920x1080,3840x2160")
    ap.add_argument("--write-result", action="store_true",
                    help="also append the output to benchmarks/results/<script>-<date>-<cpu>.md")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child)
        return
    with result_file("memory_cycle", args.write_result):
        measure(args)


def measure(args) -> None:
    print(f"machine: {describe()}")
    print("peak RSS of one cycle-model frame (CNN, D=128), each in a fresh process:")
    for size in args.sizes.split(","):
        out = subprocess.run([sys.executable, __file__, "--child", size], capture_output=True,
                             text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        extra = (r["peak_mib"] - r["before_run_mib"]) * 2**20 / r["pixels"]
        print(f"  {size:>10}: peak {r['peak_mib']:.0f} MiB ({r['before_run_mib']:.0f} MiB before "
              f"the run: images loaded, packages imported), {extra:.1f} bytes per pixel for the "
              f"run; rings of {r['ring_events']} events; engine {r['engine']}")


if __name__ == "__main__":
    main()
