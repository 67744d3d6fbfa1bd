"""The NNA's single9x9 layer on a 720p view by its two paths, same run: the float32 lanes
(``STEREOSIM_VNNI=0``, quant/intconv.py's band kernels) and the AVX512-VNNI byte dot products
(:func:`quant.vnni.vnni_signs`, what ``int_signs`` takes on a CPU that has them); the
descriptors must be equal bit for bit.

    python benchmarks/vnni_probe.py [--repeat 7] [--write-result]

A CPU without AVX512-VNNI gets one line and exit 2.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import cv2
import numpy as np
from machine import describe, result_file

from stereosim.core.config import load_config
from stereosim.core.datasets import default_scene
from stereosim.core.io import to_grey
from stereosim.nna.descriptor import compute_descriptor
from stereosim.quant import vnni


def _best(repeat: int, vnni: bool, img, cfg) -> tuple[float, np.ndarray]:
    os.environ["STEREOSIM_VNNI"] = "1" if vnni else "0"
    out = compute_descriptor(img, cfg)  # compiled, and the result
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        compute_descriptor(img, cfg)
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--write-result", action="store_true",
                    help="also append the output to benchmarks/results/<script>-<date>-<cpu>.md")
    args = ap.parse_args(argv)
    if not vnni.HAS_VNNI:
        print("vnni_probe: this CPU has no AVX512-VNNI; the probe needs it (AMD Zen 4, Intel Ice "
              "Lake and later have it)", file=sys.stderr)
        return 2
    with result_file("vnni_probe", args.write_result):
        return measure(args)


def measure(args) -> int:
    print(f"machine: {describe()}")
    cfg = load_config(overrides={"nna.descriptor": "cnn"}).nna
    scene = default_scene()
    img = cv2.resize(to_grey(scene["left"]), (1280, 720), interpolation=cv2.INTER_LINEAR)
    lanes, by_lanes = _best(args.repeat, False, img, cfg)
    dots, by_dots = _best(args.repeat, True, img, cfg)
    if not np.array_equal(by_lanes, by_dots):
        print("vnni_probe: the two paths' descriptors differ", file=sys.stderr)
        return 1
    macs = img.size * 9 * 9 * 32
    print(f"single9x9 on a 1280x720 view, best of {args.repeat}:")
    print(f"  float32 lanes    : {lanes:.4f} s ({macs / lanes / 1e9:.1f} G multiply-adds/s)")
    print(f"  VNNI dot products: {dots:.4f} s ({macs / dots / 1e9:.1f} G multiply-adds/s)")
    print(f"  descriptors equal bit for bit; {lanes / dots:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
