"""The hybrid descriptor's choices (census window, weights, penalties, the noise rule), made by
the protocol on the tuning scenes only, each with the figure that made it.

    python benchmarks/hybrid_tuning.py [--data DIR] [--jobs 2] [--folds 5]
                                       [--weights benchmarks/models/mixed5x5-wide-n6.int8.npz]
                                       [--write docs/hybrid.md]

The protocol of docs/tuning.md (``tune_defaults``): the 2005 (without Art) and 2006 scenes
under the four conditions (clean, sigma-8 noise, exposure, blur), criterion ``2 bad2 +
invalid`` (nonocc), cross-validated; MiddEval3 and 2003 are never read. The network is the
robust preset's, at its own box, LR threshold, median and paths; the hybrid is its 32 bits
beside a census signature, matched with w_cnn H_cnn + w_census H_census (sva.cost). The chain,
one pass of coordinate descent, each study starting from the earlier ones' choices:

1. the census window (32 bits or fewer: the word holds 64);
2. fixed weights and the penalties, jointly (the weights scale the cost, so they trade with
   P1, P2 and the adaptive P2's slope);
3. the noise rule's threshold: the statistic (sva.noise) of every tuning pair's left view,
   clean, exposure-changed and blurred pairs against sigma-8 ones: the middle of the gap
   between the largest of the first and the smallest of the second, so that every tuning pair
   is classed as it is (printed; no grid);
4. the automatic mode's weights for a noisy frame, with the clean frame's weights and the
   penalties searched again beside them (the end-to-end criterion, the rule of 3 deciding
   each frame);
5. the box, LR threshold and median (the network's own: 7, 2, 5) around that choice.

The preset takes the automatic mode if its criterion beats the fixed weights' of study 2.

Descriptors are computed once per scene (nna.descriptor.compute_descriptor's parts: the
network's bits and each census window's) and every point runs the SVA's compiled pipeline on
them (sva.pipeline.sva_stream with the frame's cost, as stereosim.run does; checked against
stereosim.run on the first scene).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from markers import write_between
from tune_defaults import KEYS, criterion, mean_of, sweep, tuning_root, tuning_scenes

from stereosim.core.config import load_config
from stereosim.core.errors import UserError
from stereosim.core.io import to_grey
from stereosim.nna.descriptor import compute_descriptor, descriptor_parts, hybrid_word
from stereosim.sim.api import run
from stereosim.sim.metrics import evaluate
from stereosim.sva.hamming.noise import band_rows, noise_statistic
from stereosim.sva.pipeline.pipeline import sva_stream
from stereosim.sva.wta.wta import to_float

ROBUST = "benchmarks/models/mixed5x5-wide-n6.int8.npz"
CONDITIONS = ("clean", "noise 8", "exposure", "blur")
#: the robust preset's back end beside the penalties (configs/robust-720p.toml)
FIXED = {"nna.descriptor": "hybrid", "sva.paths": 4, "sva.p2_adaptive": True,
         "sva.cost_bits": 15, "sva.path_bits": 14, "sva.sum_bits": 16}
START = {"sva.box_size": "7", "sva.lr_max_diff": "2", "sva.median": "5",
         "sva.cost_weights": "[3,1]", "sva.p1": "640", "sva.p2": "4096",
         "sva.p2_slope": "1024", "nna.census.window": "[11,3]", "nna.census.kind": "plain"}
#: census windows of at most 32 bits (the network's 32 beside them) and at most 9 rows (its reach)
WINDOWS = {"nna.census.window|nna.census.kind":
           "[11,3] plain|[9,3] plain|[5,5] plain|[9,7] symmetric|[13,5] symmetric"}
FIXED_GRID = {"sva.cost_weights": "[1,1]|[2,1]|[3,1]|[3,2]", "sva.p1": "480,640,800",
              "sva.p2": "3072,4096,5120,6144", "sva.p2_slope": "1024,2048,3072"}
AUTO_GRID = {"sva.noisy_weights": "[1,0]|[2,0]|[3,0]|[2,1]|[3,1]",
             "sva.cost_weights": "[2,1]|[3,1]|[3,2]", "sva.p1": "480,640,800",
             "sva.p2": "4096,5120,6144", "sva.p2_slope": "1024,2048,3072"}
#: the back end the robust preset's network brought, searched again around the choice
BACKEND_GRID = {"sva.box_size": "5,7", "sva.lr_max_diff": "1,2,3", "sva.median": "3,5"}
BEGIN, END = "<!-- hybrid-tuning:begin -->", "<!-- hybrid-tuning:end -->"

_DESC: dict = {}  # (scene name, census window, kind) -> (left words, right words, parts)
_NET: list = [ROBUST]


def _config(point: dict, d: int):
    over = {**FIXED, "nna.cnn.weights": _NET[0], "sva.disparities": d}
    for key, value in point.items():
        if "|" in key:  # a joint key of the grid: "a|b" = "va vb"
            for k, v in zip(key.split("|"), value.split(), strict=True):
                over[k] = v
        else:
            over[key] = value
    return load_config(overrides=over)


def _descriptors(name: str, data: dict, cfg) -> tuple:
    """The hybrid words of a scene's pair (the network's bits computed once per scene, the
    census's once per window)."""
    c = cfg.nna.census
    key = (name, tuple(c.window), c.kind)
    if key not in _DESC:
        net_key = (name, "cnn")
        if net_key not in _DESC:
            cnn = load_config(overrides={"nna.cnn.weights": _NET[0]}).nna
            _DESC[net_key] = tuple(compute_descriptor(data[v], cnn) for v in ("gl", "gr"))
        census = load_config(overrides={"nna.descriptor": "census",
                                        "nna.census.window": list(c.window),
                                        "nna.census.kind": c.kind}).nna
        parts = tuple(b for _, b in descriptor_parts(cfg.nna))
        words = tuple(hybrid_word(n, compute_descriptor(data[v], census), parts[0], sum(parts))
                      for n, v in zip(_DESC[net_key], ("gl", "gr"), strict=True))
        _DESC[key] = (*words, parts)
    return _DESC[key]


def hybrid_scores(scenes: list, point: dict) -> np.ndarray:
    """(scenes, KEYS) nonocc metrics of one point: the SVA on the scenes' hybrid words."""
    rows = []
    for name, data, d in scenes:
        cfg = _config(point, d)
        dl, dr, parts = _descriptors(name, data, cfg)
        q = sva_stream(dl, dr, data["gl"], cfg.sva, parts)
        m = evaluate(to_float(q, cfg.sva.subpixel_bits), data["gt"], data["masks"])["nonocc"]
        rows.append([m[k] for k in KEYS])
    return np.array(rows)


def prepared(root: Path) -> list:
    scenes = tuning_scenes(root, CONDITIONS)
    for _, data, _ in scenes:
        data["gl"], data["gr"] = to_grey(data["left"]), to_grey(data["right"])
    return scenes


def check_against_run(scenes: list, point: dict) -> None:
    """The scorer equals stereosim.run on the first scene (the same kernels, one call)."""
    name, data, d = scenes[0]
    cfg = _config(point, d)
    want = run(data["gl"], data["gr"], mode="functional", config=cfg, gt=data["gt"],
               masks=data["masks"]).report["metrics"]["nonocc"]
    got = hybrid_scores(scenes[:1], point)[0]
    assert np.allclose(got, [want[k] for k in KEYS], equal_nan=True), (got, want)


def noise_threshold(scenes: list, point: dict) -> tuple[int, list[str]]:
    """Study 3: the threshold in the middle of the tuning pairs' gap (module docstring)."""
    cfg = _config(point, 96).sva
    means: dict = {}
    for name, data, _ in scenes:
        condition = name.split(" (")[1][:-1] if " (" in name else "clean"
        s, n = noise_statistic(data["gl"], band_rows(cfg, data["gl"].shape[0]),
                               cfg.noise_gradient)
        means.setdefault(condition == "noise 8", []).append(s / n if n else 0.0)
    clean_max, noisy_min = max(means[False]), min(means[True])
    if clean_max >= noisy_min:
        raise UserError(f"the statistic does not separate the tuning pairs: clean up to "
                        f"{clean_max:.2f}, sigma 8 from {noisy_min:.2f}")
    threshold = int(round((clean_max + noisy_min) / 2))
    lines = [f"- statistic over the first {band_rows(cfg, 375)} rows of the left view, gradient "
             f"<= {cfg.noise_gradient}: clean, exposure and blur pairs up to "
             f"**{clean_max:.2f}** (median {np.median(means[False]):.2f}), sigma-8 pairs from "
             f"**{noisy_min:.2f}** (median {np.median(means[True]):.2f}); threshold "
             f"**{threshold}**, the middle of the gap"]
    return threshold, lines


def label(key: str) -> str:
    """A grid key as the record names it: its last part; a joint key's parts joined by /."""
    return "/".join(k.split(".", 2)[-1] for k in key.split("|"))


def study_lines(n: int, what: str, grid: dict, study, top: int = 4) -> list[str]:
    lines = [f"**{n}. {what}** ({len(study.points)} points, {study.seconds:.0f} s); criterion "
             "(2 bad2 + invalid, mean of the four conditions) / bad2 / invalid / totbad:", ""]
    for i in study.order()[:top]:
        m = study.mean(i)
        mark = " **chosen**" if i == study.chosen else ""
        shown = ", ".join(f"{label(k)} {study.points[i][k]}" for k in grid)
        lines.append(f"- {shown}: {criterion(m):.3f} / {m['bad2']:.3f} / {m['invalid']:.3f} / "
                     f"{m['totbad']:.3f}{mark}")
    picks = sum(1 for _, p in study.cv_picks if p == study.chosen)
    lines += ["", f"cross-validated {criterion(study.cv):.3f}; {picks} of "
              f"{len(study.cv_picks)} folds chose the same point", ""]
    return lines


def per_condition(scenes: list, point: dict) -> str:
    rows = hybrid_scores(scenes, point)
    names = [name for name, _, _ in scenes]
    out = []
    of = [n.split(" (")[1][:-1] if " (" in n else "clean" for n in names]
    for c in CONDITIONS:
        keep = np.array([x == c for x in of])
        m = mean_of(rows[keep])
        out.append(f"{c} {m['totbad']:.2f} ({m['bad2']:.2f})")
    return "; ".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--weights", default=ROBUST, help="the network's int8 weight file")
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--write", metavar="DOC", help="put the record into DOC between its markers")
    args = ap.parse_args(argv)
    if args.write and args.weights != ROBUST:
        raise UserError("--weights explores another network; the page holds the preset "
                        "network's chain: drop --write")
    _NET[0] = args.weights
    t0 = time.perf_counter()
    scenes = prepared(tuning_root(args.data))
    check_against_run(scenes, START)
    lines = [f"Tuning scenes: {len(scenes) // len(CONDITIONS)} (2005 without Art, 2006) x "
             f"{len(CONDITIONS)} conditions; network `{args.weights}`.", ""]
    # the descriptors are computed here once, before the workers fork
    for point in ({**START, "nna.census.window": wk.split()[0], "nna.census.kind": wk.split()[1]}
                  for wk in next(iter(WINDOWS.values())).split("|")):
        for name, data, d in scenes:
            _descriptors(name, data, _config(point, d))
    base = {k: v for k, v in START.items() if k not in ("nna.census.window", "nna.census.kind")}
    windows = {k: v.split("|") for k, v in WINDOWS.items()}
    s1 = sweep(scenes, base, windows, args.folds, "windows", args.jobs, hybrid_scores)
    lines += study_lines(1, "census window (fixed weights 3, 1; P1/P2 640/4096, slope 1024)",
                         windows, s1)
    chosen = s1.points[s1.chosen]
    grid = {k: v.split("|" if "|" in v else ",") for k, v in FIXED_GRID.items()}
    s2 = sweep(scenes, chosen, grid, args.folds, "fixed", args.jobs, hybrid_scores)
    lines += study_lines(2, "fixed weights and penalties", grid, s2)
    chosen = s2.points[s2.chosen]
    lines += [f"fixed weights at the choice, per condition totbad (bad2): "
              f"{per_condition(scenes, chosen)}", ""]
    threshold, text = noise_threshold(scenes, chosen)
    lines += ["**3. the noise rule**", ""] + text + [""]
    auto = {**chosen, "sva.weight_mode": "auto", "sva.noise_threshold": str(threshold)}
    grid = {k: v.split("|" if "|" in v else ",") for k, v in AUTO_GRID.items()}
    s4 = sweep(scenes, auto, grid, args.folds, "auto", args.jobs, hybrid_scores)
    lines += study_lines(4, "automatic weights: the noisy frame's, the clean frame's and the "
                         "penalties", grid, s4)
    final = s4.points[s4.chosen]
    grid = {k: v.split(",") for k, v in BACKEND_GRID.items()}
    s5 = sweep(scenes, final, grid, args.folds, "back end", args.jobs, hybrid_scores)
    lines += study_lines(5, "box, LR threshold and median around the choice", grid, s5)
    final = s5.points[s5.chosen]
    best_fixed = criterion(s2.mean(s2.chosen))
    best_auto = criterion(s5.mean(s5.chosen))
    use = final if best_auto < best_fixed else chosen
    lines += [f"automatic {best_auto:.3f} against fixed {best_fixed:.3f}: the preset uses "
              f"**{'auto' if use is final else 'fixed'}**, per condition totbad (bad2): "
              f"{per_condition(scenes, use)}", "",
              "The choice: " + ", ".join(f"`{label(k)} = {v}`" for k, v in sorted(use.items())),
              "",
              f"(`python benchmarks/hybrid_tuning.py --jobs {args.jobs}`, "
              f"{time.perf_counter() - t0:.0f} s.)"]
    print("\n".join(lines))
    return write_between(Path(args.write), BEGIN, END, lines) if args.write else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except UserError as err:
        print(f"hybrid_tuning: {err}", file=sys.stderr)
        sys.exit(2)
