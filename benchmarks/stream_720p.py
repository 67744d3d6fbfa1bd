"""A stream of 720p frames through the cycle model: per-frame cost against OpenCV StereoSGBM and
peak memory for streams of different lengths, each in a fresh process.

    python benchmarks/stream_720p.py [--frames 60 600] [--set KEY=VALUE ...] [--write-result]

For each length N a child process runs ``stereosim.run_stream`` on the embedded scene resized to
1280x720 (the pair repeated N times; cycle counts do not depend on the pixels), iterates over
every frame's disparities as the CLI does, and prints the stream's measured figures, its CPU
per frame and its peak RSS; then OpenCV StereoSGBM (MODE_SGBM, D = 128, block 5, one thread)
runs the same pair 5 times in the same child for the ratio. Targets: peak RSS of 60
and 600 frames within 10 % of each other; per-frame cost <= 1.3 x OpenCV's.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

from machine import describe, result_file


def child(frames: int, overrides: dict) -> dict:
    import cv2
    import numpy as np

    import stereosim
    from stereosim.core.datasets import default_scene

    cv2.setNumThreads(1)
    scene = default_scene()
    left = cv2.resize(scene["left"], (1280, 720), interpolation=cv2.INTER_AREA)
    right = cv2.resize(scene["right"], (1280, 720), interpolation=cv2.INTER_AREA)
    warm = stereosim.run_stream([(left[:64, :256], right[:64, :256])] * 2,
                          overrides={**overrides, "sva.disparities": 64})
    for _ in warm:  # compile the kernels before timing
        pass
    t0, c0 = time.perf_counter(), time.process_time()
    stream = stereosim.run_stream([(left, right)] * frames, overrides=overrides)
    t_timing = time.process_time() - c0
    invalid = 0.0
    for frame in stream:
        invalid = frame.invalid_percent
    cpu = time.process_time() - c0
    wall = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=128, blockSize=5,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM)
    best = []
    for _ in range(5):
        c = time.process_time()
        sgbm.compute(left, right)
        best.append(time.process_time() - c)
    st = stream.report["stream"]
    return {"frames": frames, "cpu_per_frame_s": cpu / frames, "wall_s": wall,
            "timing_cpu_per_frame_s": t_timing / frames, "peak_rss_mib": rss,
            "opencv_s": float(np.min(best)), "sustained_fps": st["sustained_fps"],
            "latency_ms": st["latency_ms"], "bound_fps": stream.report["throughput"]["fps_bound"],
            "bottleneck": stream.report["throughput"]["bottleneck"],
            "last_invalid_percent": invalid}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[60, 600])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--write-result", action="store_true",
                    help="also append the output to benchmarks/results/<script>-<date>-<cpu>.md")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    overrides = {}
    for item in args.set:
        key, _, value = item.partition("=")
        overrides[key] = json.loads(value) if value[:1] in "0123456789-[{tf" else value
    if args.child:
        print(json.dumps(child(args.child, overrides)))
        return 0
    with result_file("stream_720p", args.write_result):
        measure(args)
    return 0


def measure(args) -> None:
    print(f"machine: {describe()}")
    results = []
    for n in args.frames:
        cmd = [sys.executable, __file__, "--child", str(n)] + [f"--set={s}" for s in args.set]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        results.append(r)
        lat = r["latency_ms"]
        print(f"{n} frames of 1280x720: {r['cpu_per_frame_s']:.3f} s CPU per frame "
              f"(timing {r['timing_cpu_per_frame_s']:.3f}), OpenCV {r['opencv_s']:.3f} s: ratio "
              f"{r['cpu_per_frame_s'] / r['opencv_s']:.2f} (goal <= 1.0); peak RSS "
              f"{r['peak_rss_mib']:.0f} MiB; sustained {r['sustained_fps']} fps (bound "
              f"{r['bound_fps']}, {r['bottleneck']}), latency min/median/p99/max "
              f"{lat['min']:.2f}/{lat['median']:.2f}/{lat['p99']:.2f}/{lat['max']:.2f} ms",
              flush=True)
    if len(results) > 1:
        a, b = results[0]["peak_rss_mib"], results[-1]["peak_rss_mib"]
        print(f"peak RSS {results[-1]['frames']} vs {results[0]['frames']} frames: "
              f"{b / a:.3f}x (target within 1.10)")


if __name__ == "__main__":
    sys.exit(main())
