"""Speed of the cycle-accurate model on a 1280x720 frame against OpenCV StereoSGBM, same run.

stereosim: `stereosim.run(mode="cycle")` with the CNN int8 descriptor, D = 128, 4 SGM paths, LR
check (the issue's benchmark configuration); it prints the wall time, the simulated cycles per
second (all clock domains together) and the peak resident memory of a fresh process that runs one
frame. OpenCV: StereoSGBM MODE_SGBM, D = 128, blockSize 5, single-threaded, on the same pair,
timed in this process right after each stereosim frame (the two alternate, so a change in the
machine's load shows in both).

    python benchmarks/speed_cycle.py [--repeat 3] [--engine fast|readable] [--split]
                                     [--set KEY=VALUE ...] [--versus KEY=VALUE ...]
                                     [--write-result]

``--engine readable`` is the reference kernel (about 1e5 cycles/s: minutes per frame); ``--engine
fast`` or the default is the compiled engine (sim/cycle/engine). ``--split`` runs one more frame
in the child and prints where its CPU time goes: the compiled engine's event streams and
statistics, and the data kernels (the NNA's descriptors, the SVA's stream and median).
``--set`` changes the configuration, e.g. ``--set nna.cnn.weights=benchmarks/models/mccnn4.int8.npz
--set nna.cnn.channels=32`` for a network of four layers (docs/performance.md). ``--versus``
runs a second configuration in turn with the first, e.g. ``--versus
nna.cnn.weights=benchmarks/models/mccnn4-slim.int8.npz``, and prints its wall time over the
first's, run by run.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import cv2
from machine import describe, result_file

from stereosim.core.config import load_config
from stereosim.core.config.loader import parse_set_options
from stereosim.core.datasets import default_scene
from stereosim.core.io import to_grey
from stereosim.sim.api import run
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.plan import build_plan

CONFIG = {"nna.descriptor": "cnn", "sva.disparities": 128, "sva.paths": 4, "sva.lr_check": True}


def frame():
    scene = default_scene()
    left = cv2.resize(to_grey(scene["left"]), (1280, 720), interpolation=cv2.INTER_LINEAR)
    right = cv2.resize(to_grey(scene["right"]), (1280, 720), interpolation=cv2.INTER_LINEAR)
    return left, right


def _split_frame(left, right, over) -> dict:
    """CPU seconds of one frame: the compiled engine's event streams and statistics, and the
    data kernels (the NNA's descriptors, the SVA's stream)."""
    plan = build_plan(load_config(overrides=over), left.shape)
    acc: dict = {}
    t0 = time.process_time()
    run_compiled(plan, left, right, timings=acc)
    acc["total_s"] = time.process_time() - t0
    return acc


def one_frame_child(engine: str, split: bool, sets: list[str]) -> None:
    """Run one frame and print the wall time, cycles and peak RSS (MiB) as JSON."""
    left, right = frame()
    over = dict(CONFIG, **({"sim.engine": engine} if engine else {}))
    over.update(parse_set_options(sets))
    run(left[:48, :256], right[:48, :256], mode="cycle",
        overrides=dict(over, **{"sva.disparities": 64}))
    t0 = time.perf_counter()
    res = run(left, right, mode="cycle", overrides=over)
    wall = time.perf_counter() - t0
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    cycles = sum(res.report["cycles"]["total"].values())
    out = {"wall_s": wall, "cycles": cycles, "peak_mib": peak_mib,
           "fps": res.report["throughput"]["fps_bound"],
           "bottleneck": res.report["throughput"]["bottleneck"]}
    if split:
        out["split"] = _split_frame(left, right, over)
    print(json.dumps(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--engine", default="", help="sim.engine override (default: the config's)")
    ap.add_argument("--split", action="store_true",
                    help="also print the CPU split: event loop vs data kernels")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a configuration override (repeatable)")
    ap.add_argument("--versus", action="append", default=[], metavar="KEY=VALUE",
                    help="a second configuration (the --set ones plus these), run in turn with "
                         "the first; prints its time over the first's")
    ap.add_argument("--write-result", action="store_true",
                    help="also append the output to benchmarks/results/<script>-<date>-<cpu>.md")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        one_frame_child(args.engine, args.split, args.set)
        return
    with result_file("speed_cycle", args.write_result):
        measure(args)


def measure(args) -> None:
    left, right = frame()
    cv2.setNumThreads(1)
    sgbm = cv2.StereoSGBM_create(0, 128, 5, P1=8 * 25, P2=32 * 25, disp12MaxDiff=1,
                                 uniquenessRatio=10, mode=cv2.STEREO_SGBM_MODE_SGBM)
    sgbm.compute(left, right)
    # stereosim (a fresh process per frame) and OpenCV alternate, so both see the same machine
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    runs, cv_times, versus = [], [], []

    def child(sets: list[str]) -> dict:
        out = subprocess.run([sys.executable, __file__, "--child", "--engine", args.engine]
                             + (["--split"] if args.split else [])
                             + [f"--set={item}" for item in sets],
                             capture_output=True, text=True, check=True, env=env)
        return json.loads(out.stdout.strip().splitlines()[-1])

    for _ in range(args.repeat):
        runs.append(child(args.set))
        if args.versus:
            versus.append(child(args.set + args.versus))
        t0 = time.perf_counter()
        sgbm.compute(left, right)
        cv_times.append(time.perf_counter() - t0)
    best = min(runs, key=lambda r: r["wall_s"])
    cv_best = min(cv_times)
    print(f"machine: {describe()}")
    print(f"1280x720, CNN descriptor, D=128, 4 paths, LR check; best of {args.repeat}:")
    print(f"  stereosim cycle model : {best['wall_s']:.3f} s, {best['cycles']:,} cycles "
          f"({best['cycles'] / best['wall_s'] / 1e6:.2f} M simulated cycles/s), "
          f"peak RSS {max(r['peak_mib'] for r in runs):.0f} MiB; "
          f"chip: {best['fps']} fps, bottleneck {best['bottleneck']}")
    print(f"  OpenCV SGBM, 1 thread : {cv_best:.3f} s")
    pairs = sorted(r["wall_s"] / c for r, c in zip(runs, cv_times))
    print(f"  ratio stereosim / OpenCV: {best['wall_s'] / cv_best:.2f}  (goal <= 1.0; "
          f"run by run {pairs[0]:.2f} .. {pairs[-1]:.2f}, median {pairs[len(pairs) // 2]:.2f})")
    if args.versus:
        vs = sorted(v["wall_s"] / r["wall_s"] for v, r in zip(versus, runs))
        v_best = min(v["wall_s"] for v in versus)
        print(f"  with {' '.join(args.versus)}: {v_best:.3f} s, "
              f"{max(v['cycles'] for v in versus):,} cycles; its time over the first's, run by "
              f"run {vs[0]:.2f} .. {vs[-1]:.2f}, median {vs[len(vs) // 2]:.2f}")
    if args.split:
        sp = min((r["split"] for r in runs), key=lambda x: x["total_s"])
        kernels = sp["nna_kernels_s"] + sp["sva_kernels_s"]
        print(f"  CPU of one frame (least of {args.repeat}): {sp['total_s']:.3f} s = event "
              f"streams + statistics {sp['engine_s']:.3f} s + NNA descriptors "
              f"{sp['nna_kernels_s']:.3f} s + SVA stream {sp['sva_kernels_s']:.3f} s")
        print(f"  the data kernels alone: {kernels / cv_best:.2f} x OpenCV")


if __name__ == "__main__":
    main()
