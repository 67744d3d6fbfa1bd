"""Every choice of docs/tuning.md, made by the protocol and written into the page.

    python benchmarks/tuning_report.py [--data DIR] [--write docs/tuning.md] [--folds 5]

Runs the studies below in order with ``tune_defaults.sweep`` (tuning scenes only: 2005 without
Art and 2006, criterion ``2 bad2 + invalid``, cross-validated) and scores each choice on the
held-out sets afterwards. A study starts from the choices of the earlier studies of its
descriptor (coordinate descent, one pass; the penalties and the box are searched jointly, as
the best penalties depend on the box), so the block is the whole chain of decisions, and the
page states whether the shipped defaults are what the chain chose. The criterion averages
clean, sigma-8 noisy, exposure-changed and blurred pairs (CONDITIONS); about 16 minutes on 2
cores (``--jobs``).
Four explorations, printed and never written (the page holds the one-pass chain under the
protocol's criterion): ``--descriptor`` runs one descriptor's studies, ``--weights FILE`` (with
``--descriptor cnn``) runs the CNN's for another int8 network (its own back end, as a preset
gives it), ``--condition`` averages other conditions, ``--passes N`` repeats the chain from its
own choices (does one pass of coordinate descent settle?).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from markers import write_between
from robustness import CONDITIONS as CONDITION_CHOICES
from tune_defaults import Study, criterion, heldout_scores, sweep, tuning_root, tuning_scenes

from stereosim.core.config import DESCRIPTOR_DEFAULTS, load_config
from stereosim.core.errors import UserError

BEGIN, END = "<!-- protocol-results:begin -->", "<!-- protocol-results:end -->"

#: (descriptor, what is chosen, grid); each study starts from the earlier ones' choices.
STUDIES = (
    ("census", "penalties, adaptive P2 (slope 0 = off) and box",
     {"sva.p1": "64,128,256,384", "sva.p2": "1024,2048,3072",
      "sva.p2_slope": "0,256,512,1024", "sva.box_size": "5,7"}),
    ("census", "box, LR threshold, median",
     {"sva.box_size": "3,5,7", "sva.lr_max_diff": "1,2,3", "sva.median": "0,3,5"}),
    ("census", "window", {"nna.census.window": "[11,3]|[3,11]"}),
    ("cnn", "penalties, adaptive P2 (slope 0 = off) and box",
     {"sva.p1": "96,160,256,384", "sva.p2": "1024,1792,3072",
      "sva.p2_slope": "0,256,512,1024", "sva.box_size": "5,7"}),
    ("cnn", "box, LR threshold, median",
     {"sva.box_size": "3,5,7", "sva.lr_max_diff": "1,2,3", "sva.median": "0,3,5"}),
    ("cnn", "SGM paths", {"sva.paths": "2,4"}),
)
#: Cost, path and sum registers wide enough that no point of a grid saturates (a 7x7 box of
#: 32-bit costs stays below 1568 < 2^12, a path cost below 1568 + P2 < 2^13, four of them below
#: 2^15): the choice is made on the SGM itself, and the shipped widths are then the narrowest
#: that never saturate at the chosen box and P2 (core.config.sgm_widths).
WIDE = {"sva.cost_bits": "12", "sva.path_bits": "13", "sva.sum_bits": "15"}
#: Where the chain starts for the keys a study has not chosen yet, whatever the shipped defaults
#: are (so the block does not depend on them): the back end before the protocol's choices.
START = {"sva.box_size": "5", "sva.lr_max_diff": "2", "sva.median": "3", "sva.paths": "4"}
FIXED = {d: {"nna.descriptor": d, **START, **WIDE} for d in ("census", "cnn")}
#: Settings a grid key needs to mean what it says, and the value that needs none: the adaptive
#: P2 switched on (slope 0 is the plain P2), a line buffer tall enough for a 3x11 window. They
#: carry into later studies only when the choice is not that value.
NEEDS = {"sva.p2_slope": ("0", {"sva.p2_adaptive": "true"}),
         "nna.census.window": ("[11,3]", {"nna.line_buffer_rows": "14"})}
SHOWN = 5  # points listed per study
#: The conditions the criterion averages over, each on all the tuning scenes: the four the
#: robustness issue names -- clean pairs, Gaussian noise of sigma 8 on both views, the right
#: view's exposure changed (gain 0.8, offset +12) and the right view blurred (sigma 1)
#: (benchmarks/robustness.py's draws). ``--condition`` replaces them for an exploration.
CONDITIONS = ("clean", "noise 8", "exposure", "blur")


def carried(point: dict, grid: dict) -> dict:
    """What a later study of the same descriptor starts from: the chosen point without the
    settings its grid only needed for points that were not chosen."""
    out = dict(point)
    for key in grid:
        off, extras = NEEDS.get(key, (None, {}))
        if point[key] == off:
            for extra in extras:
                out.pop(extra, None)
    return out


def grid_of(spec: dict) -> dict:
    return {k: v.split("|" if "|" in v else ",") for k, v in spec.items()}


def _value(cfg, key: str) -> str:
    """``key`` of ``cfg`` as the grids spell it."""
    value = cfg
    for part in key.split("."):
        value = getattr(value, part)
    if isinstance(value, (tuple, list)):
        return "[" + ",".join(str(v) for v in value) + "]"
    return str(value).lower() if isinstance(value, bool) else str(value)


def shipped(descriptor: str, key: str) -> str:
    """The shipped default of ``key`` for ``descriptor``, as the grids spell it (a key whose
    NEEDS the defaults do not meet is at its 'off' value, e.g. slope 0 for the plain P2)."""
    cfg = load_config(overrides={"nna.descriptor": descriptor})
    off, extras = NEEDS.get(key, (None, {}))
    if any(_value(cfg, k) != v for k, v in extras.items()):
        return off
    return _value(cfg, key)


def row(m: dict) -> str:
    return " / ".join(f"{m[k]:.3f}" for k in ("bad2", "invalid", "totbad"))


def point_text(point: dict, grid: dict) -> str:
    return ", ".join(f"{k.rpartition('.')[2]} {point[k]}" for k in grid)


def study_lines(n: int, descriptor: str, what: str, grid: dict, study: Study,
                held: dict) -> list[str]:
    chosen = study.points[study.chosen]
    defaults = {k: shipped(descriptor, k) for k in grid}
    same = all(chosen[k] == defaults[k] for k in grid)
    verdict = ("the shipped default" if same else
               f"**not** the shipped default ({point_text(defaults, grid)})")
    lines = [f"**{n}. {descriptor}: {what}** -- {len(study.points)} points; chosen "
             f"**{point_text(chosen, grid)}**, {verdict}.", "",
             "| point | bad2 / invalid / totbad | 2b2+inv |", "|---|---|---|"]
    for i in study.order()[:SHOWN]:
        mark = " (chosen)" if i == study.chosen else ""
        m = study.mean(i)
        lines.append(f"| {point_text(study.points[i], grid)}{mark} | {row(m)} | "
                     f"{criterion(m):.3f} |")
    picks = sorted({point_text(study.points[p], grid) for _, p in study.cv_picks})
    lines += ["", f"Cross-validated 2b2+inv of the choice: {criterion(study.cv):.3f} (folds "
              f"chose: {'; '.join(picks)}). Held out, after the choice: "
              + "; ".join(f"{label} bad2 {m['bad2']:.2f}, totbad {m['totbad']:.2f}"
                          for label, m in held.items()) + ".", ""]
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="worker processes (default: one per CPU; the block is the same)")
    ap.add_argument("--write", metavar="DOC", help="put the block into DOC between its markers")
    ap.add_argument("--descriptor", choices=sorted(FIXED),
                    help="only this descriptor's studies (printed; not with --write)")
    ap.add_argument("--weights", metavar="FILE",
                    help="the CNN's studies for this int8 network (nna.cnn.weights; with "
                         "--descriptor cnn: printed, not with --write): its own back end")
    ap.add_argument("--condition", action="append", choices=CONDITION_CHOICES,
                    help="average these conditions instead of the protocol's "
                         "(repeatable; printed; not with --write)")
    ap.add_argument("--passes", type=int, default=1, choices=range(1, 5), metavar="N",
                    help="run the chain N times, each pass starting from the last one's "
                         "choices (1-4; printed; not with --write)")
    args = ap.parse_args(argv)
    if (args.descriptor or args.condition or args.passes > 1 or args.weights) and args.write:
        raise UserError("--descriptor, --condition, --passes and --weights explore; the page "
                        "holds the whole chain under the protocol's criterion: drop them to "
                        "--write")
    if args.weights and args.descriptor != "cnn":
        raise UserError("--weights names a CNN: give --descriptor cnn too")
    conditions = tuple(args.condition or CONDITIONS)
    root = tuning_root(args.data)
    scenes = tuning_scenes(root, conditions)
    chosen = {d: dict(FIXED[d]) for d in FIXED}
    if args.weights:
        chosen["cnn"]["nna.cnn.weights"] = args.weights
    body, summary = [], []
    plan = [(d, what + (f" (pass {p})" if p > 1 else ""), spec)
            for p in range(1, args.passes + 1) for d, what, spec in STUDIES
            if args.descriptor in (None, d)]
    for n, (descriptor, what, spec) in enumerate(plan, 1):
        grid = grid_of(spec)
        base = dict(chosen[descriptor])
        for key in grid:
            base.update(NEEDS.get(key, (None, {}))[1])
        study = sweep(scenes, base, grid, args.folds, f"study {n}/{len(plan)}", args.jobs)
        point = study.points[study.chosen]
        held = {f"{label}, {c}": m for c in conditions
                for label, m in heldout_scores(root, point, c).items()}
        body += study_lines(n, descriptor, what, grid, study, held)
        chosen[descriptor] = carried(point, grid)
        summary.append((descriptor, what, study, held))
    n_scenes = len(scenes) // len(conditions)
    held_labels = list(summary[0][3]) if summary else []
    lines = ["**Results under the protocol**, generated by `python benchmarks/tuning_report.py "
             "--write docs/tuning.md` (functional model; tuning figures: mean over the "
             f"{n_scenes} tuning scenes under each of {len(conditions)} conditions "
             f"({', '.join(conditions)}; nonocc, third-size pixels, D = 96); held-out figures "
             "in each set's own pixels, D from each 2014 scene's calib.txt, 64 on 2003).",
             "", "| descriptor | after study | tuning: bad2 / invalid / totbad | 2b2+inv | "
             "cross-validated | " + " | ".join(f"{h} (held out): bad2 / totbad"
                                               for h in held_labels) + " |",
             "|---|---|---|---|---|" + "---|" * len(held_labels)]
    for descriptor, what, study, held in summary:
        m = study.mean(study.chosen)
        lines.append(f"| {descriptor} | {what} | {row(m)} | {criterion(m):.3f} | "
                     f"{criterion(study.cv):.3f} | "
                     + " | ".join(f"{h['bad2']:.2f} / {h['totbad']:.2f}" for h in held.values())
                     + " |")
    lines += ["", *body]
    studied = {d: list(dict.fromkeys(k for desc, _, spec in STUDIES if desc == d for k in spec))
               for d in FIXED}
    final = "; ".join(f"{d}: " + ", ".join(f"{k} {chosen[d][k]}" for k in studied[d])
                      for d in FIXED if args.descriptor in (None, d))
    lines.append(f"Chosen by the chain: {final}. Shipped penalties: "
                 + ", ".join(f"{d} {v['p1']} / {v['p2']}" for d, v in DESCRIPTOR_DEFAULTS.items())
                 + ".")
    if args.write:
        return write_between(Path(args.write), BEGIN, END, lines)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except UserError as err:  # a missing or wrong data folder: one line
        print(f"tuning_report: {err}", file=sys.stderr)
        sys.exit(2)
