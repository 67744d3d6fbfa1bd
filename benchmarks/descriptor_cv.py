"""Cross-validate a descriptor's training recipe on the tuning scenes: every scene is scored
with weights trained without it.

The shipped weights were trained on all 25 tuning scenes, so on those scenes they are scored on
their own training data, and a recipe's lead there need not carry over to scenes it never saw
(docs/learned-descriptor.md). This script scores a recipe the honest way: train it once per
fold, leaving that fold out (the tuning's own folds, ``nna.training.traindata.cv_folds``),
quantise, then

    stereosim train --variant single9x9 --seed 0 --leave-out-fold K/5 --out wK.float.npz
    stereosim quantize wK.float.npz --calib ../shared/data --out wK.npz          # K = 0..4
    python benchmarks/descriptor_cv.py --weights w0.npz,w1.npz,w2.npz,w3.npz,w4.npz \\
        [--condition clean --condition "noise 8" ...] [--jobs 2]

Fold K's scenes (and their degraded copies) are scored with ``wK`` -- the recipe's
cross-validated score -- beside, on the same scenes and at the same back end (the CNN's
defaults), the shipped weights (trained on every scene) and the census at its defaults. The
criterion is the tuning's (``2 bad2 + invalid``, benchmarks/tune_defaults.py). The
quantiser's calibration views may include fold K's scenes: they set 32 scales, not the
weights, and int8 costs 0.01 totbad (docs/ablation.md).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from robustness import CONDITIONS
from tune_defaults import KEYS, fmt, mean_of, sweep, tuning_root, tuning_scenes

from stereosim.core.errors import UserError
from stereosim.nna.training.traindata import cv_folds


def fold_held_rows(table: list, fold_of: np.ndarray) -> np.ndarray:
    """Each scene's row from the weights of its own fold: ``table[k]`` scores weights k."""
    return np.array([table[k][i] for i, k in enumerate(fold_of)])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--weights", required=True, metavar="W0,W1,...",
                    help="int8 weight files, the K-th trained with --leave-out-fold K/N")
    ap.add_argument("--condition", action="append", choices=CONDITIONS,
                    help="degrade every pair as benchmarks/robustness.py does (default clean; "
                    "repeatable)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    args = ap.parse_args(argv)
    weights = args.weights.split(",")
    if len(weights) < 2:
        raise UserError("--weights needs one file per fold (at least 2)")
    conditions = args.condition or ["clean"]
    scenes = tuning_scenes(tuning_root(args.data), conditions)
    names = [name for name, _, _ in scenes]
    fold_of = np.array(cv_folds([n.split(" (")[0] for n in names], len(weights)))
    condition_of = np.array([n.split(" (")[1][:-1] if " (" in n else "clean" for n in names])
    cnn = sweep(scenes, {"nna.descriptor": "cnn"}, {"nna.cnn.weights": [*weights, "default"]},
                len(weights), "weights", jobs=args.jobs)
    census = sweep(scenes, {}, {"nna.descriptor": ["census"]}, len(weights), "census",
                   jobs=args.jobs)
    rows = {"recipe, fold left out": fold_held_rows(cnn.table, fold_of),
            "shipped (saw every scene)": cnn.table[-1], "census": census.table[0]}
    print(f"{len(weights)} folds x {len(names)} scene-conditions "
          f"(2005 without Art, 2006; nonocc) in {cnn.seconds + census.seconds:.0f} s")
    header = " ".join(f"{k:>7}" for k in KEYS) + f" {'2b2+inv':>8}"
    for condition in [*conditions, "all"] if len(conditions) > 1 else conditions:
        pick = condition_of == condition if condition != "all" else np.ones(len(names), bool)
        print(f"\n{condition}:\n{header}  weights")
        for label, table in rows.items():
            print(f"{fmt(mean_of(table[pick]))}  {label}")
    print("\nper fold, all conditions (recipe / shipped / census):")
    for k in range(len(weights)):
        fold = fold_of == k
        scores = " / ".join(f"{fmt(mean_of(t[fold])).split()[-1]}" for t in rows.values())
        plain = sorted({n.split(" (")[0] for n, f in zip(names, fold, strict=True) if f})
        print(f"  fold {k} ({', '.join(plain)}): {scores}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except UserError as err:
        print(f"descriptor_cv: {err}", file=sys.stderr)
        sys.exit(2)
