"""Choose the back end's parameters on the tuning scenes only, with cross-validation.

The protocol (docs/tuning.md), enforced here:

* **Tuning scenes**: Middlebury 2005 (without Art, which is MiddEval3's ArtL) and 2006,
  third size -- the scenes the descriptor is trained on
  (``nna.training.traindata.training_scene_dirs``).
  ``--data`` names the shared data folder; the script reads nothing else for a choice.
* **Held out**: MiddEval3 trainingQ and the 2003 scenes. They are never used for a choice:
  ``--heldout`` scores the chosen point on them *after* the choice, and prints them as a
  report.
* **Criterion**: the mean over the tuning scenes (nonocc) of ``bad2 + totbad`` =
  ``2 bad2 + invalid`` -- a wrong disparity counts twice an invalid one, since a later stage
  can fill a hole but not spot a wrong match -- under every ``--condition`` given (each on all
  the scenes; benchmarks/tuning_report.py uses clean, sigma-8 noise, exposure and blur). Ties
  go to the earlier point of the grid.
* **Cross-validation**: the scenes are split into ``--folds`` folds (scene i in fold
  i mod k, names sorted). For each fold the point best on the other folds is scored on the
  fold; the mean of those scores estimates how the *choice* does on scenes it did not see,
  beside the chosen point's own (optimistic) score on all the scenes.

    python benchmarks/tune_defaults.py [--data DIR] --grid sva.p1=48,64,80 --grid sva.p2=512,640
                                       [--base KEY=VALUE ...] [--folds 5] [--heldout]
                                       [--condition "noise 8"]

``--condition`` degrades every pair as benchmarks/robustness.py does (noise, exposure, blur);
given several times, the criterion is the mean over the conditions (the shipped defaults are
chosen on clean, sigma-8, exposure-changed and blurred pairs: benchmarks/tuning_report.py,
docs/tuning.md).

D is 96 on the tuning scenes (their third-size disparities stay below 86), each 2014 scene's
calib.txt ndisp rounded up on MiddEval3, and 64 on the 2003 quarter-size scenes.
"""

from __future__ import annotations

import argparse
import itertools
import multiprocessing as mp
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from robustness import CONDITIONS, degrade

from stereosim.core.datasets import (
    find_scene,
    find_scenes,
    legal_disparities,
    load_scene,
    shared_data_dir,
)
from stereosim.core.errors import UserError
from stereosim.core.io import to_grey
from stereosim.core.progress import progress_bar
from stereosim.nna.training.traindata import cv_folds, training_scene_dirs
from stereosim.sim.api import run

KEYS = ("bad2", "invalid", "totbad", "avgerr")
D_TUNING, D_2003 = 96, 64
HELDOUT = (("MiddEval3 trainingQ", "middlebury2014_trainingQ"), ("2003", "middlebury2003_quarter"))


def criterion(m: dict) -> float:
    """What the choice minimises (module docstring)."""
    return m["bad2"] + m["totbad"]


def load(scenes, d_default: int, condition: str = "clean", seed: int = 0) -> list:
    """(name, scene data, D) of each scene, its pair degraded by ``condition`` (a condition of
    benchmarks/robustness.py, drawn from ``seed`` and the scene's index)."""
    out = []
    for index, sc in enumerate(scenes):
        data = load_scene(sc)
        if condition != "clean":
            data = {**data, **dict(zip(("left", "right"), degrade(
                to_grey(data["left"]), to_grey(data["right"]), condition, seed, index),
                strict=True))}
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


def tuning_root(data) -> Path:
    """The shared data folder to tune in (``--data`` or the default); a held-out test set or a
    missing folder is refused with one line."""
    root = Path(data) if data else shared_data_dir()
    if root is None:
        raise UserError("no data: pass --data, the shared data folder")
    if any(part in {h[1] for h in HELDOUT} for part in root.resolve().parts):
        raise UserError(f"{root} is a held-out test set: tune on the shared data folder "
                        "(its 2005/2006 scenes)")
    return root


def tuning_scenes(root: Path, conditions=("clean",)) -> list:
    """The 2005 (without Art) and 2006 scenes, names sorted, loaded under each condition in
    turn (a degraded copy is named ``scene (condition)``): every condition weighs the same in
    a mean over the list."""
    dirs = [find_scene(p) for p in sorted(training_scene_dirs(root))]
    out = []
    for condition in conditions:
        suffix = "" if condition == "clean" else f" ({condition})"
        out += [(name + suffix, data, d) for name, data, d in load(dirs, D_TUNING, condition)]
    return out


@dataclass
class Study:
    """One sweep on the tuning scenes: every point's per-scene scores, the choice on all the
    scenes and the cross-validated choices."""

    points: list
    table: list  # one (scenes, KEYS) array per point
    chosen: int
    cv_picks: list  # per fold: (fold scene names, index of the point chosen without them)
    cv: dict  # mean of the fold-held scores of those picks
    seconds: float

    def mean(self, i: int) -> dict:
        return mean_of(self.table[i])

    def order(self) -> list:
        return sorted(range(len(self.points)), key=lambda i: (criterion(self.mean(i)), i))


_HELD: list = []  # a worker's scenes (sweep with jobs > 1)
_SCORER: list = [scene_scores]  # how a point is scored (forked workers inherit it)


def _hold(scenes: list) -> None:
    _HELD[:] = scenes


def _score_held(point: dict) -> np.ndarray:
    return _SCORER[0](_HELD, point)


def sweep(scenes: list, base: dict, grid: dict, folds: int, bar_label: str = "points",
          jobs: int = 1, scorer=None) -> Study:
    """Score every point of ``grid`` (over ``base``) on ``scenes`` and choose by the criterion,
    on all the scenes and per cross-validation fold. ``scorer(scenes, point)`` gives the
    (scenes, KEYS) metrics of a point (default :func:`scene_scores`: the functional model)."""
    _SCORER[0] = scorer or scene_scores
    points = [{**base, **dict(zip(grid, values, strict=True))}
              for values in itertools.product(*grid.values())]
    points = [p for p in points
              if not ("sva.p1" in p and "sva.p2" in p and int(p["sva.p2"]) <= int(p["sva.p1"]))]
    t0 = time.perf_counter()
    table = []
    with progress_bar(len(points), bar_label, "point") as bar:
        if jobs > 1:  # forked workers inherit the loaded scenes; the order of points is kept
            with mp.get_context("fork").Pool(jobs, _hold, (scenes,)) as pool:
                for rows in pool.imap(_score_held, points):
                    table.append(rows)
                    bar.update(1)
        else:
            for point in points:
                table.append(_SCORER[0](scenes, point))
                bar.update(1)
    every = np.arange(len(scenes))
    names = [name for name, _, _ in scenes]
    # a scene's degraded copies fall in its fold: scene i (names sorted) in fold i mod k
    fold_of = np.array(cv_folds([name.split(" (")[0] for name in names], folds))
    picks, held_rows = [], []
    for k in range(folds):
        pick = best(points, table, every[fold_of != k])
        picks.append(([n for n, f in zip(names, fold_of, strict=True) if f == k], pick))
        held_rows.append(table[pick][fold_of == k])
    return Study(points, table, best(points, table, every), picks,
                 mean_of(np.concatenate(held_rows)), time.perf_counter() - t0)


def heldout_scores(root: Path, point: dict, condition: str = "clean") -> dict:
    """The chosen point's nonocc means on each held-out set (a report, never a choice)."""
    return {label: mean_of(scene_scores(load(find_scenes(root / folder), D_2003, condition),
                                        point))
            for label, folder in HELDOUT}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--base", action="append", default=[], metavar="KEY=VALUE",
                    help="fixed overrides for every point (e.g. nna.descriptor=census)")
    ap.add_argument("--grid", action="append", required=True, metavar="KEY=V1,V2,...",
                    help="sweep these values (repeatable; separate with | when values "
                    "contain commas, e.g. [9,7]|[13,5])")
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--heldout", action="store_true",
                    help="after the choice, report it on MiddEval3 trainingQ and 2003")
    ap.add_argument("--condition", action="append", choices=CONDITIONS,
                    help="degrade every pair as benchmarks/robustness.py does (default clean); "
                    "repeat to tune on the mean over several conditions")
    args = ap.parse_args(argv)
    root = tuning_root(args.data)
    conditions = args.condition or ["clean"]
    scenes = tuning_scenes(root, conditions)
    base = dict(kv.split("=", 1) for kv in args.base)
    study = sweep(scenes, base, parse_grid(args.grid), args.folds, jobs=args.jobs)
    print(f"{len(study.points)} points x {len(scenes)} tuning scenes (2005 without Art, 2006; "
          f"nonocc) in {study.seconds:.0f} s")
    print(f"{'bad2':>7} {'invalid':>7} {'totbad':>7} {'avgerr':>7} {'2b2+inv':>8}  point")
    for i in study.order()[: args.top]:
        print(f"{fmt(study.mean(i))}  {study.points[i]}")
    print(f"\ncross-validation, {args.folds} folds:")
    for k, (fold_names, pick) in enumerate(study.cv_picks):
        held = mean_of(study.table[pick][np.isin([n for n, _, _ in scenes], fold_names)])
        print(f"  fold {k} ({', '.join(fold_names)}): chose {study.points[pick]} -> {fmt(held)}")
    print(f"cross-validated score of the choice: {fmt(study.cv)}")
    print(f"chosen on all tuning scenes:          {fmt(study.mean(study.chosen))}  "
          f"{study.points[study.chosen]}")
    if args.heldout:
        print("\nheld-out test sets (reported, never used for the choice):")
        for condition in conditions:
            for label, m in heldout_scores(root, study.points[study.chosen],
                                           condition).items():
                print(f"  {label + ', ' + condition:<28} {fmt(m)}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except UserError as err:  # a missing or wrong data folder, a bad override: one line
        print(f"tune_defaults: {err}", file=sys.stderr)
        sys.exit(2)
