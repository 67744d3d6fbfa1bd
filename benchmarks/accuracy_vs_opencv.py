"""Accuracy of the functional model against OpenCV StereoSGBM on MiddEval3 trainingQ.

Both run on the same 15 scenes in the same process, evaluated with the same code (sim.metrics,
nonocc mask, thresholds in quarter-resolution pixels). OpenCV: MODE_SGBM, blockSize 5,
P1 = 8*25, P2 = 32*25, disp12MaxDiff = 1, uniquenessRatio = 10, numDisparities = the scene's D
(calib ndisp rounded up to a multiple of 16, as for stereosim); its invalid pixels are the
negative outputs.

    python benchmarks/accuracy_vs_opencv.py [--data DIR] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import sys

import cv2
import numpy as np

from stereosim.core.config import load_config, parse_set_options
from stereosim.core.datasets import find_scenes, legal_disparities, load_scene, shared_data_dir
from stereosim.core.io import to_grey
from stereosim.sim.api import run
from stereosim.sim.metrics import evaluate, mean_metrics

KEYS = ("bad2", "invalid", "totbad", "avgerr")


def opencv_sgbm(left, right, ndisp):
    sgbm = cv2.StereoSGBM_create(
        minDisparity=0, numDisparities=ndisp, blockSize=5, P1=8 * 25, P2=32 * 25,
        disp12MaxDiff=1, uniquenessRatio=10, mode=cv2.STEREO_SGBM_MODE_SGBM,
    )
    raw = sgbm.compute(to_grey(left), to_grey(right))
    disp = raw.astype(np.float32) / 16.0
    disp[raw < 0] = np.inf
    return disp


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--mask", default="nonocc", choices=("nonocc", "all"))
    args = ap.parse_args(argv)
    root = shared_data_dir()
    data = args.data or (root / "middlebury2014_trainingQ" if root else None)
    if data is None:
        sys.exit("no data: pass --data pointing at MiddEval3 trainingQ")
    over = parse_set_options(args.set)
    ours, theirs = [], []
    print(f"mask: {args.mask}; thresholds in pixels of the GT (quarter resolution)")
    head = " ".join(f"{k:>8}" for k in KEYS)
    print(f"{'scene':<12} {'D':>4} | stereosim {head} | OpenCV SGBM {head}")
    for scene in find_scenes(data):
        d = load_scene(scene)
        ndisp = legal_disparities(d["ndisp"])
        o = dict(over)
        o.setdefault("sva.disparities", ndisp)
        res = run(d["left"], d["right"], mode="functional", config=load_config(None, o),
                  gt=d["gt"], masks=d["masks"])
        m_ours = res.report["metrics"]
        m_cv = evaluate(opencv_sgbm(d["left"], d["right"], ndisp), d["gt"], d["masks"])
        ours.append(m_ours)
        theirs.append(m_cv)
        a = " ".join(f"{m_ours[args.mask][k]:8.3f}" for k in KEYS)
        b = " ".join(f"{m_cv[args.mask][k]:8.3f}" for k in KEYS)
        print(f"{scene.name:<12} {ndisp:>4} |           {a} |             {b}")
    mo, mc = mean_metrics(ours)[args.mask], mean_metrics(theirs)[args.mask]
    a = " ".join(f"{mo[k]:8.3f}" for k in KEYS)
    b = " ".join(f"{mc[k]:8.3f}" for k in KEYS)
    print(f"{'MEAN':<12} {'':>4} |           {a} |             {b}")
    verdict = "no worse than" if mo["totbad"] <= mc["totbad"] else "WORSE than"
    print(f"stereosim totbad {mo['totbad']:.3f} is {verdict} OpenCV's {mc['totbad']:.3f}; "
          f"bad2 {mo['bad2']:.3f} (target <= 11), totbad target <= 19.5")


if __name__ == "__main__":
    main()
