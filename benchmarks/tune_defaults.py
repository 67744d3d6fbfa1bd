"""Sweep the functional pipeline's parameters on MiddEval3 trainingQ and rank them.

This is the documented sweep behind the default P1/P2, box size, uniqueness and LR threshold
(docs/tuning.md). Every point runs all 15 scenes (nonocc mask, D from each calib.txt) and the
ranking is by mean totbad among the points with mean bad2 <= 11.

    python benchmarks/tune_defaults.py [--data DIR] [--stage coarse|fine] [--base KEY=VALUE ...]
                                       [--grid KEY=V1,V2,... ...]
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time

import numpy as np

from sim.api import run
from sim.config import load_config
from sim.datasets import find_scenes, legal_disparities, load_scene, shared_data_dir

GRIDS = {
    # stage 1: the penalties and the box size with both checks at their loosest useful setting
    "coarse": {
        "sva.box_size": [1, 3, 5],
        "sva.p1": [16, 24, 32, 48],
        "sva.p2": [128, 256, 384, 512],
        "sva.uniqueness": [0],
        "sva.lr_max_diff": [1, 2],
    },
    # stage 2: the checks and the sub-pixel fit around the best penalties of stage 1
    "fine": {
        "sva.uniqueness": [0, 2, 5],
        "sva.lr_max_diff": [1, 2, 3],
        "sva.subpixel": ["parabola", "equiangular"],
        "sva.median": [0, 3],
    },
}


def load_all(data_dir):
    scenes = []
    for sc in find_scenes(data_dir):
        d = load_scene(sc)
        scenes.append((sc.name, d, legal_disparities(d["ndisp"])))
    return scenes


def score(scenes, overrides):
    rows = []
    for _, d, ndisp in scenes:
        over = dict(overrides)
        over.setdefault("sva.disparities", ndisp)
        res = run(d["left"], d["right"], config=load_config(None, over), gt=d["gt"], masks=d["masks"])
        rows.append(res.report["metrics"]["nonocc"])
    return {k: float(np.mean([r[k] for r in rows])) for k in ("bad2", "invalid", "totbad", "avgerr")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="MiddEval3 trainingQ folder")
    ap.add_argument("--stage", choices=tuple(GRIDS), default="coarse")
    ap.add_argument("--base", action="append", default=[], metavar="KEY=VALUE",
                    help="fixed overrides for every point (e.g. the stage-1 winner)")
    ap.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2,...",
                    help="sweep these values instead of the stage's grid (repeatable; "
                         "separate with | when values contain commas, e.g. [9,7]|[13,5])")
    ap.add_argument("--top", type=int, default=15)
    args = ap.parse_args(argv)
    data = args.data or (shared_data_dir() / "middlebury2014_trainingQ" if shared_data_dir() else None)
    if data is None:
        sys.exit("no data: pass --data pointing at MiddEval3 trainingQ")
    scenes = load_all(data)
    base = dict(kv.split("=", 1) for kv in args.base)
    grid = GRIDS[args.stage]
    if args.grid:
        grid = {}
        for item in args.grid:
            key, _, values = item.partition("=")
            grid[key] = values.split("|" if "|" in values else ",")
    keys = list(grid)
    results = []
    t0 = time.perf_counter()
    for values in itertools.product(*grid.values()):
        over = dict(base)
        over.update(dict(zip(keys, values)))
        if "sva.p1" in over and "sva.p2" in over and int(over["sva.p2"]) <= int(over["sva.p1"]):
            continue
        results.append((over, score(scenes, over)))
    ok = [r for r in results if r[1]["bad2"] <= 11.0]
    ok.sort(key=lambda r: r[1]["totbad"])
    print(f"{len(results)} points x {len(scenes)} scenes in {time.perf_counter() - t0:.0f} s; "
          f"ranked by mean totbad (nonocc) among bad2 <= 11:")
    print(f"{'bad2':>7} {'invalid':>8} {'totbad':>7} {'avgerr':>7}  overrides")
    for over, m in ok[: args.top]:
        sets = " ".join(f"{k}={v}" for k, v in over.items())
        print(f"{m['bad2']:7.3f} {m['invalid']:8.3f} {m['totbad']:7.3f} {m['avgerr']:7.3f}  {sets}")


if __name__ == "__main__":
    main()
