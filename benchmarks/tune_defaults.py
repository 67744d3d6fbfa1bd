"""Choose the back end's parameters on the tuning scenes only, with cross-validation.

The protocol (docs/tuning.md), enforced here:

* **Tuning scenes**: Middlebury 2005 (without Art, which is MiddEval3's ArtL) and 2006,
  third size -- the scenes the descriptor is trained on (``nna.train.training_scene_dirs``).
  ``--data`` names the shared data folder; the script reads nothing else for a choice.
* **Held out**: MiddEval3 trainingQ and the 2003 scenes. They are never used for a choice:
  ``--heldout`` scores the chosen point on them *after* the choice, and prints them as a
  report.
* **Criterion**, fixed before any run: the mean over the tuning scenes (nonocc) of
  ``bad2 + totbad`` = ``2 bad2 + invalid`` -- a wrong disparity counts twice an invalid one,
  since a later stage can fill a hole but not spot a wrong match. Ties go to the earlier
  point of the grid.
* **Cross-validation**: the scenes are split into ``--folds`` folds (scene i in fold
  i mod k, names sorted). For each fold the point best on the other folds is scored on the
  fold; the mean of those scores estimates how the *choice* does on scenes it did not see,
  beside the chosen point's own (optimistic) score on all the scenes.

    python benchmarks/tune_defaults.py [--data DIR] --grid sva.p1=48,64,80 --grid sva.p2=512,640
                                       [--base KEY=VALUE ...] [--folds 5] [--heldout]

D is 96 on the tuning scenes (their third-size disparities stay below 86), each 2014 scene's
calib.txt ndisp rounded up on MiddEval3, and 64 on the 2003 quarter-size scenes.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

import numpy as np

from nna.train import training_scene_dirs
from sim.api import run
from sim.datasets import find_scene, find_scenes, legal_disparities, load_scene, shared_data_dir
from sim.errors import UserError
from sim.progress import progress_bar

KEYS = ("bad2", "invalid", "totbad", "avgerr")
D_TUNING, D_2003 = 96, 64
HELDOUT = (("MiddEval3 trainingQ", "middlebury2014_trainingQ"), ("2003", "middlebury2003_quarter"))


def criterion(m: dict) -> float:
    """What the choice minimises (module docstring)."""
    return m["bad2"] + m["totbad"]


def load(scenes, d_default: int) -> list:
    out = []
    for sc in scenes:
        data = load_scene(sc)
        d = legal_disparities(data["ndisp"]) if data["ndisp"] else d_default
        out.append((sc.name, data, d))
    return out


def scene_scores(scenes, overrides: dict) -> np.ndarray:
    """(scenes, KEYS) nonocc metrics of one point on every scene (functional model)."""
    rows = []
    for _, data, d in scenes:
        over = {"sva.disparities": d, **overrides}
        m = run(data["left"], data["right"], mode="functional", overrides=over, gt=data["gt"],
                masks=data["masks"]).report["metrics"]["nonocc"]
        rows.append([m[k] for k in KEYS])
    return np.array(rows)


def mean_of(rows: np.ndarray) -> dict:
    return dict(zip(KEYS, rows.mean(axis=0).tolist(), strict=True))


def best(points: list, table: list, index: np.ndarray) -> int:
    """The point with the lowest criterion over the scenes ``index`` (first on ties)."""
    values = [criterion(mean_of(rows[index])) for rows in table]
    return int(np.argmin(values))


def parse_grid(items: list[str]) -> dict:
    grid = {}
    for item in items:
        key, _, values = item.partition("=")
        grid[key] = values.split("|" if "|" in values else ",")
    return grid


def fmt(m: dict) -> str:
    return " ".join(f"{m[k]:7.3f}" for k in KEYS) + f" {criterion(m):8.3f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--base", action="append", default=[], metavar="KEY=VALUE",
                    help="fixed overrides for every point (e.g. nna.descriptor=census)")
    ap.add_argument("--grid", action="append", required=True, metavar="KEY=V1,V2,...",
                    help="sweep these values (repeatable; separate with | when values "
                    "contain commas, e.g. [9,7]|[13,5])")
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--heldout", action="store_true",
                    help="after the choice, report it on MiddEval3 trainingQ and 2003")
    args = ap.parse_args(argv)
    root = Path(args.data) if args.data else shared_data_dir()
    if root is None:
        print("tune_defaults: no data: pass --data, the shared data folder", file=sys.stderr)
        return 2
    if any(part in {h[1] for h in HELDOUT} for part in root.resolve().parts):
        print(f"tune_defaults: {root} is a held-out test set: tune on the shared data folder "
              "(its 2005/2006 scenes)", file=sys.stderr)
        return 2
    scenes = load([find_scene(p) for p in sorted(training_scene_dirs(root))], D_TUNING)
    names = [name for name, _, _ in scenes]
    base = dict(kv.split("=", 1) for kv in args.base)
    grid = parse_grid(args.grid)
    points = [{**base, **dict(zip(grid, values, strict=True))}
              for values in itertools.product(*grid.values())]
    points = [p for p in points
              if not ("sva.p1" in p and "sva.p2" in p and int(p["sva.p2"]) <= int(p["sva.p1"]))]
    t0 = time.perf_counter()
    table = []
    with progress_bar(len(points), "points", "point") as bar:
        for point in points:
            table.append(scene_scores(scenes, point))
            bar.update(1)
    every = np.arange(len(scenes))
    chosen = best(points, table, every)
    print(f"{len(points)} points x {len(scenes)} tuning scenes (2005 without Art, 2006; "
          f"nonocc) in {time.perf_counter() - t0:.0f} s")
    print(f"{'bad2':>7} {'invalid':>7} {'totbad':>7} {'avgerr':>7} {'2b2+inv':>8}  point")
    order = sorted(range(len(points)), key=lambda i: (criterion(mean_of(table[i])), i))
    for i in order[: args.top]:
        print(f"{fmt(mean_of(table[i]))}  {points[i]}")
    # cross-validation of the choice
    folds = np.arange(len(scenes)) % args.folds
    cv_rows = []
    print(f"\ncross-validation, {args.folds} folds:")
    for k in range(args.folds):
        pick = best(points, table, every[folds != k])
        held = mean_of(table[pick][folds == k])
        cv_rows.append(table[pick][folds == k])
        fold_names = ", ".join(n for n, f in zip(names, folds, strict=True) if f == k)
        print(f"  fold {k} ({fold_names}): chose {points[pick]} -> {fmt(held)}")
    cv = mean_of(np.concatenate(cv_rows))
    print(f"cross-validated score of the choice: {fmt(cv)}")
    print(f"chosen on all tuning scenes:          {fmt(mean_of(table[chosen]))}  "
          f"{points[chosen]}")
    if args.heldout:
        print("\nheld-out test sets (reported, never used for the choice):")
        for label, folder in HELDOUT:
            held = load(find_scenes(root / folder), D_2003)
            print(f"  {label:<20} {fmt(mean_of(scene_scores(held, points[chosen])))}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except UserError as err:  # a missing or wrong data folder, a bad override: one line
        print(f"tune_defaults: {err}", file=sys.stderr)
        sys.exit(2)
