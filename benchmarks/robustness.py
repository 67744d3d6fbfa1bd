"""How the descriptors hold up when the images are not clean: noise, exposure and blur.

Every condition is applied to the held-out test sets only -- MiddEval3 trainingQ (15 scenes) and
the 2003 scenes (teddy, cones) -- which are never used for a choice (docs/tuning.md). Three
matchers run on the same degraded pairs and are scored by the same code (sim.metrics, nonocc
mask, thresholds in the GT's pixels; mean over the scenes of a set):

* ``cnn``: the shipped int8 ``single9x9`` descriptor at its defaults (the functional model,
  bit-exact with the chip);
* ``census``: the 32-bit census at its defaults;
* ``opencv``: OpenCV's StereoSGBM with the parameters of benchmarks/accuracy_vs_opencv.py.

Conditions (each seeded from ``np.random.default_rng([seed, scene index, view])``):

* ``clean``;
* ``noise s``: Gaussian noise N(0, s^2) on both views, rounded and clipped to 0..255
  (s = 4, 8, 12);
* ``exposure``: the right view x 0.8 + 12 (gain and offset), rounded and clipped;
* ``blur``: the right view through a Gaussian blur of sigma 1 pixel.

    python benchmarks/robustness.py [--data DIR] [--seed S] [--write docs/ablation.md]

D is each 2014 scene's ``calib.txt`` ndisp rounded up to the chip's legal range, 64 for the 2003
quarter-size scenes (their disparities stay below 64).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from accuracy_vs_opencv import opencv_sgbm
from markers import write_between

from stereosim.core.config import parse_set_options
from stereosim.core.datasets import find_scenes, legal_disparities, load_scene, shared_data_dir
from stereosim.core.io import to_grey
from stereosim.core.progress import progress_bar
from stereosim.sim.api import run
from stereosim.sim.metrics import evaluate, mean_metrics

SETS = (("MiddEval3 trainingQ", "middlebury2014_trainingQ"), ("2003", "middlebury2003_quarter"))
METHODS = ("cnn", "census", "opencv")
CONDITIONS = ("clean", "noise 4", "noise 8", "noise 12", "exposure", "blur")
D_2003 = 64
BEGIN, END = "<!-- robustness:begin -->", "<!-- robustness:end -->"


def degrade(left: np.ndarray, right: np.ndarray, condition: str, seed: int, scene: int):
    """The pair under ``condition`` (grey uint8 in, grey uint8 out)."""
    if condition == "clean":
        return left, right
    if condition.startswith("noise"):
        sigma = float(condition.split()[1])
        out = []
        for view, img in enumerate((left, right)):
            rng = np.random.default_rng([seed, scene, view])
            noisy = img.astype(np.float64) + rng.normal(0.0, sigma, img.shape)
            out.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8))
        return tuple(out)
    if condition == "exposure":
        changed = np.clip(np.rint(right.astype(np.float64) * 0.8 + 12.0), 0, 255)
        return left, changed.astype(np.uint8)
    if condition == "blur":
        return left, cv2.GaussianBlur(right, (0, 0), 1.0)
    raise ValueError(condition)


def score(method: str, left, right, d: int, gt, masks, cnn: dict, config=None) -> dict:
    """The metrics of ``method`` on a pair; the cnn column runs ``config`` (a preset: built
    for the pair's own size) when one is given, with the ``cnn`` overrides."""
    if method == "opencv":
        return evaluate(opencv_sgbm(left, right, d), gt, masks)
    if method == "cnn" and config is not None:
        over = {"sva.disparities": d, "source.camera_width": 0, "source.camera_height": 0,
                **cnn}
        return run(left, right, mode="functional", gt=gt, masks=masks, config=config,
                   overrides=over).report["metrics"]
    over = {"sva.disparities": d, "nna.descriptor": method, **(cnn if method == "cnn" else {})}
    return run(left, right, mode="functional", gt=gt, masks=masks,
               overrides=over).report["metrics"]


def measure(root: Path, seed: int, cnn: dict, config=None, conditions=CONDITIONS) -> dict:
    """{set: {condition: {method: mean nonocc metrics}}} and the scene counts."""
    jobs = []
    for label, folder in SETS:
        for index, scene in enumerate(find_scenes(root / folder)):
            jobs.append((label, index, scene))
    results: dict = {}
    counts: dict = {}
    with progress_bar(len(jobs) * len(conditions) * len(METHODS), "robustness", "run") as bar:
        for label, index, scene in jobs:
            data = load_scene(scene)
            left, right = to_grey(data["left"]), to_grey(data["right"])
            d = legal_disparities(data["ndisp"]) if data["ndisp"] else D_2003
            counts[label] = counts.get(label, 0) + 1
            for condition in conditions:
                pair = degrade(left, right, condition, seed, index)
                for method in METHODS:
                    m = score(method, *pair, d, data["gt"], data["masks"], cnn, config)
                    results.setdefault(label, {}).setdefault(condition, {}) \
                        .setdefault(method, []).append(m)
                    bar.update(1)
    means = {label: {c: {m: mean_metrics(v)["nonocc"] for m, v in per.items()}
                     for c, per in conds.items()} for label, conds in results.items()}
    return {"means": means, "counts": counts}


def table(result: dict, seed: int, seconds: float, cnn: dict, config=None,
          conditions=CONDITIONS) -> list[str]:
    lines = []
    for label, _ in SETS:
        means = result["means"].get(label)
        if not means:
            continue
        n = result["counts"][label]
        lines += [f"**{label}** ({n} scenes, nonocc mean): totbad (bad2)", "",
                  "| condition | " + " | ".join(METHODS) + " |",
                  "|---|" + "---|" * len(METHODS)]
        for condition in conditions:
            cells = []
            best = min(means[condition][m]["totbad"] for m in METHODS)
            for m in METHODS:
                v = means[condition][m]
                cell = f"{v['totbad']:.2f} ({v['bad2']:.2f})"
                cells.append(f"**{cell}**" if v["totbad"] == best else cell)
            lines.append(f"| {condition} | " + " | ".join(cells) + " |")
        lines.append("")
    lines.append(f"(`python benchmarks/robustness.py --seed {seed} --write docs/ablation.md`, "
                 f"{seconds:.0f} s; bold: the lowest totbad of the row"
                 + (f"; the cnn column: {config}" if config else "")
                 + (f"; cnn with {cnn}" if cnn else "") + ".)")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--write", metavar="DOC", help="put the table into DOC between its markers")
    ap.add_argument("--cnn", action="append", default=[], metavar="KEY=VALUE",
                    help="overrides for the cnn column only, e.g. nna.cnn.weights=w.npz "
                    "(a candidate; the defaults otherwise)")
    ap.add_argument("--config", metavar="FILE",
                    help="the cnn column runs this configuration (a preset, such as "
                    "configs/hybrid-720p.toml), built for each pair's own size")
    ap.add_argument("--condition", action="append", choices=CONDITIONS,
                    help="only these conditions (default: all six)")
    args = ap.parse_args(argv)
    root = Path(args.data) if args.data else shared_data_dir()
    if root is None or not (root / SETS[0][1]).is_dir():
        print("robustness: no data: pass --data pointing at the shared data folder",
              file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    cnn = parse_set_options(args.cnn)
    conditions = tuple(args.condition or CONDITIONS)
    result = measure(root, args.seed, cnn, args.config, conditions)
    lines = table(result, args.seed, time.perf_counter() - t0, cnn, args.config, conditions)
    print("\n".join(lines))
    return write_between(Path(args.write), BEGIN, END, lines) if args.write else 0


if __name__ == "__main__":
    sys.exit(main())
