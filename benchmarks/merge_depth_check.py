"""Is the estimate's merge FIFO depth (``throughput.merge_depth_needed``) the least at which column
tiles reach the work bound? A bisection on the cycle model for each configuration below.

For each configuration the cycle model runs a stream of three frames (a synthetic pair repeated)
at a merge FIFO depth and compares its sustained rate (``stream.sustained_fps``) with the work
bound (``throughput.fps_bound``; equal within 1e-4, as it is measured between SVA edges); the
least depth that reaches it is found by bisection between 1 and the frame's width, and printed
beside the estimate's figure. Frames from memory: the estimate is exact, every line should say
"same". A camera streaming into the NNA: the estimate is an upper bound (docs/whatif.md).
About a minute in all (the 1080p and 720p rows take most of it).

    PYTHONPATH=. python benchmarks/merge_depth_check.py [--quick]

(``--quick``: the small frames only.)
"""

from __future__ import annotations

import argparse

from stereosim.core.config import load_config
from stereosim.sim.api import run_stream
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.sweep import synthetic_pair

AT_BOUND = 1 - 1e-4

SMALL = [
    # equal and unequal tiles, 2-5 per camera, at the NNA's bound
    *[((40, w), {"nna.stereo_submodules": k}) for w, k in
      ((300, 4), (302, 4), (305, 4), (300, 6), (302, 6), (384, 6), (400, 6), (500, 6),
       (300, 8), (303, 8), (306, 8), (401, 8), (410, 8), (960, 8))],
    ((50, 777), {"nna.stereo_submodules": 10, "nna.macs": 144}),
    # other MAC arrays and clocks
    *[((40, 300), {"nna.stereo_submodules": 6, "nna.macs": m}) for m in (324, 259)],
    *[((40, 303), {"nna.stereo_submodules": 8, "nna.macs": m}) for m in (259, 162, 81)],
    ((50, 600), {"nna.stereo_submodules": 6, "nna.macs": 400, "clocks.nna_mhz": 600.0}),
    ((40, 384), {"nna.stereo_submodules": 6, "clocks.nna_mhz": 300.0}),
    # FIFO latency
    ((40, 300), {"nna.stereo_submodules": 6, "fifo.latency_cycles": 2}),
    *[((40, 303), {"nna.stereo_submodules": 8, "nna.macs": 162, "fifo.latency_cycles": lat})
      for lat in (2, 4)],
    ((50, 523), {"nna.stereo_submodules": 6, "clocks.sva_mhz": 350.0,
                 "fifo.latency_cycles": 3}),
    # the SVA's bound
    ((40, 384), {"nna.stereo_submodules": 6, "nna.macs": 576}),
    ((60, 641), {"nna.stereo_submodules": 4, "nna.macs": 576}),
    *[((40, 384), {"nna.stereo_submodules": 6, "clocks.sva_mhz": f}) for f in (250.0, 300.0)],
    ((40, 384), {"nna.stereo_submodules": 4, "nna.descriptor": "census"}),
    # the memory source's bound
    *[((40, 384), {"nna.stereo_submodules": 6, "source.memory_gbps": g})
      for g in (0.1, 0.12, 0.15)],
    # a camera streaming into the NNA (an upper bound)
    *[((40, 384), {"nna.stereo_submodules": 6, "source.kind": "camera",
                   "clocks.camera_mhz": f, "source.camera_hblank": 50}) for f in (100.0, 150.0)],
]
LARGE = [
    ((720, 1280), {"nna.stereo_submodules": 6}),
    ((1080, 1920), {"nna.stereo_submodules": 6}),
    ((720, 1280), {"nna.stereo_submodules": 4, "source.kind": "camera"}),
]


def reaches_bound(pair, over: dict, depth: int) -> bool:
    cfg = load_config(overrides={**over, "fifo.nna_to_merge_depth": depth})
    try:
        rep = run_stream([pair] * 3, config=cfg).report
    except Exception as exc:  # noqa: BLE001 -- a camera overflows when the tiles fall behind
        if "overflow" in str(exc):
            return False
        raise
    return rep["stream"]["sustained_fps"] >= AT_BOUND * rep["throughput"]["fps_bound"]


def least_depth(shape, over: dict) -> int | None:
    pair = synthetic_pair(*shape)
    lo, hi = 1, shape[1]
    if not reaches_bound(pair, over, hi):
        return None
    while lo < hi:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if reaches_bound(pair, over, mid) else (mid + 1, hi)
    return lo


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the small frames only")
    args = parser.parse_args()
    same = 0
    cases = SMALL + ([] if args.quick else LARGE)
    for shape, over in cases:
        over = {"nna.descriptor": "cnn", **over}
        need = estimate(load_config(overrides=over), shape)["throughput"]["merge_depth_needed"]
        least = least_depth(shape, over)
        verdict = "same" if least == need else f"estimate {need - least:+d}"
        same += least == need
        print(f"{shape[1]}x{shape[0]} {over}: estimate {need}, cycle model {least} -- {verdict}",
              flush=True)
    print(f"{same} of {len(cases)} the same")


if __name__ == "__main__":
    main()
