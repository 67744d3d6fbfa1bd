"""Clean against sigma-8 accuracy on the tuning scenes: the trained networks, each alone at its
back end, beside the hybrid descriptor at each pair of weights (docs/img/hybrid_curve.png).

    python benchmarks/hybrid_plot.py [--data DIR] [--out docs/img/hybrid_curve.png]
                                     [--write docs/hybrid.md]

Every network of ``benchmarks/models`` (int8) and the shipped single layer runs alone
(``nna.descriptor = cnn``, the back end its weight file carries, else the CNN's defaults), as
does the census at its defaults; the hybrid runs the robust preset's network beside the 11x3
census at the preset's penalties (configs/hybrid-720p.toml) with fixed weights [cnn, census]
from [1, 0] to [0, 1], and once with the preset's automatic weights. Tuning scenes only (2005
without Art, 2006), nonocc mean totbad; MiddEval3 and 2003 are not read. Prints the figures
it plots; the PNG is rendered at a fixed size without metadata (the same figures, the same
bytes).
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np
from hybrid_tuning import _NET, ROBUST, hybrid_scores, prepared
from markers import write_between
from tune_defaults import mean_of, scene_scores, tuning_root

from stereosim.core.config import load_config
from stereosim.core.outputs import atomic_write_bytes

PRESET = Path(__file__).resolve().parents[1] / "configs" / "hybrid-720p.toml"
BEGIN, END = "<!-- hybrid-curve:begin -->", "<!-- hybrid-curve:end -->"
WEIGHTS = ([1, 0], [3, 1], [2, 1], [3, 2], [1, 1], [2, 3], [1, 2], [1, 3], [0, 1])


def by_condition(scenes: list, rows: np.ndarray) -> dict:
    of = [n.split(" (")[1][:-1] if " (" in n else "clean" for n, _, _ in scenes]
    return {c: mean_of(rows[np.array([x == c for x in of])])["totbad"]
            for c in ("clean", "noise 8")}


def preset_point() -> dict:
    """The hybrid preset's SVA keys, as grid values of benchmarks/hybrid_tuning.py."""
    cfg = load_config(PRESET)
    s = cfg.sva
    return {"sva.cost_weights": str(list(s.cost_weights)), "sva.noisy_weights":
            str(list(s.noisy_weights)), "sva.weight_mode": s.weight_mode,
            "sva.noise_threshold": str(s.noise_threshold), "sva.p1": str(s.p1),
            "sva.p2": str(s.p2), "sva.p2_slope": str(s.p2_slope),
            "sva.box_size": str(s.box_size), "sva.lr_max_diff": str(s.lr_max_diff),
            "sva.median": str(s.median),
            "nna.census.window": str(list(cfg.nna.census.window)),
            "nna.census.kind": cfg.nna.census.kind}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--out", default="docs/img/hybrid_curve.png")
    ap.add_argument("--write", metavar="DOC", help="put the figures into DOC between its markers")
    args = ap.parse_args(argv)
    scenes = prepared(tuning_root(args.data))
    pure = [(name, data, d) for name, data, d in scenes
            if " (" not in name or "(noise 8)" in name]
    networks = {}
    models = sorted(Path("benchmarks/models").glob("*.int8.npz"))
    for path in [Path("default")] + models:
        over = {"nna.descriptor": "cnn", "nna.cnn.weights": str(path)}
        name = "single9x9" if path.name == "default" else path.name.removesuffix(".int8.npz")
        networks[name] = by_condition(
            pure, scene_scores(pure, over))
    census = by_condition(pure, scene_scores(pure, {"nna.descriptor": "census"}))
    _NET[0] = ROBUST
    point = preset_point()
    hybrid = {}
    for w in WEIGHTS:
        fixed = {**point, "sva.weight_mode": "fixed", "sva.cost_weights": str(w)}
        hybrid[tuple(w)] = by_condition(pure, hybrid_scores(pure, fixed))
    auto = by_condition(pure, hybrid_scores(pure, point))
    lines = ["| tuning scenes, nonocc totbad | clean | sigma 8 |", "|---|---:|---:|"]
    rows = [(f"`{n}` alone", v) for n, v in networks.items()] + [("census 11x3 alone", census)]
    rows += [(f"hybrid, weights {list(w)}", v) for w, v in hybrid.items()]
    rows.append(("hybrid, automatic weights (the preset)", auto))
    lines += [f"| {n} | {v['clean']:.2f} | {v['noise 8']:.2f} |" for n, v in rows]
    lines += ["", "(`python benchmarks/hybrid_plot.py --write docs/hybrid.md`; the network "
              "alone at the back end its file carries, else the CNN's defaults; the hybrid at "
              "the preset's penalties.)"]
    print("\n".join(lines))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.5, 5.0), dpi=100)
    xs = [v["clean"] for v in networks.values()]
    ys = [v["noise 8"] for v in networks.values()]
    ax.scatter(xs, ys, color="tab:blue", label="trained networks, alone")
    for name, x, y in zip(networks, xs, ys, strict=True):
        ax.annotate(name, (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.scatter([census["clean"]], [census["noise 8"]], color="tab:gray", marker="s",
               label="census 11x3, alone")
    hx = [v["clean"] for v in hybrid.values()]
    hy = [v["noise 8"] for v in hybrid.values()]
    ax.scatter(hx, hy, color="tab:orange",
               label="hybrid, fixed weights [cnn, census] (the preset's penalties)")
    for w, x, y in zip(hybrid, hx, hy, strict=True):
        ax.annotate(str(list(w)), (x, y), fontsize=7, xytext=(3, -9),
                    textcoords="offset points", color="tab:orange")
    ax.scatter([auto["clean"]], [auto["noise 8"]], color="tab:red", marker="*", s=160,
               zorder=5, label="hybrid, automatic weights (the preset)")
    ax.set_xlabel("clean pairs: totbad % (nonocc, tuning scenes)")
    ax.set_ylabel("sigma-8 noise: totbad %")
    ax.set_title("Clean against noisy accuracy: networks alone and the hybrid")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    atomic_write_bytes(args.out, buf.getvalue())
    print(f"wrote {args.out}")
    return write_between(Path(args.write), BEGIN, END, lines) if args.write else 0


if __name__ == "__main__":
    sys.exit(main())
