"""The what-if of the hybrid descriptor: accuracy and hardware cost of the CNN alone, the census
alone and the hybrid, on one 720p chip, under the four conditions -- measured once, on the
held-out sets, after every choice was made (benchmarks/hybrid_tuning.py).

    python benchmarks/hybrid_whatif.py [--data DIR] [--write]

Three configurations:

* ``cnn``: configs/robust-720p.toml (the robust network alone, at the back end its file
  carries);
* ``census``: the same chip with configs/census-baseline.toml layered on it (the 11x3 census
  alone, at the census's tuned back end);
* ``hybrid``: configs/hybrid-720p.toml (the network's bits beside the census's, the weights
  chosen per frame).

Hardware (``stereosim estimate --config NAME`` at 1280x720): the NNA's work bound and the fps
delivered from the preset's 720p60 cameras, the chip's SRAM, the energy of a frame and the
power. Accuracy: MiddEval3 trainingQ (15 scenes) and the 2003 scenes (teddy, cones), nonocc
totbad (bad2), mean over the scenes, clean and under sigma-8 noise, the exposure change and
blur (benchmarks/robustness.py's draws, seed 0), the functional model (bit-exact with the
chip), each preset built for the pair's own size.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from markers import write_between
from robustness import D_2003, SETS, degrade

from stereosim.core.config import load_config
from stereosim.core.datasets import find_scenes, legal_disparities, load_scene, shared_data_dir
from stereosim.core.io import to_grey
from stereosim.core.progress import progress_bar
from stereosim.nna.descriptor import descriptor_parts
from stereosim.nna.geometry import macs_per_descriptor
from stereosim.sim.api import run
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.metrics import mean_metrics

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
PRESETS = {"cnn": [CONFIGS / "robust-720p.toml"],
           "census": [CONFIGS / "robust-720p.toml", CONFIGS / "census-baseline.toml"],
           "hybrid": [CONFIGS / "hybrid-720p.toml"]}
CONDITIONS = ("clean", "noise 8", "exposure", "blur")
#: the pages the tables go into (``--write``), each between markers of its own block name
PAGES = {"hybrid-whatif": "docs/hybrid.md", "hybrid-hardware": "docs/hardware-study.md",
         "hybrid-accuracy": "docs/learned-descriptor.md"}
ROOT = Path(__file__).resolve().parents[1]


def hardware(cfg) -> dict:
    est = estimate(cfg, (720, 1280))
    thr, sram = est["throughput"], est["chip_sram"]["total"]
    parts = " + ".join(f"{b} {k}" for k, b in descriptor_parts(cfg.nna))
    return {"parts": parts, "macs": macs_per_descriptor(cfg.nna),
            "bound": thr["fps_bound"], "delivered": thr.get("fps_delivered", thr["fps_bound"]),
            "sram": sram, "uj": est["energy"]["per_frame_uj"]["total"],
            "mw": est["energy"]["power_mw"]}


def accuracy(root: Path, cfgs: dict, seed: int = 0) -> dict:
    """{set: {condition: {name: mean nonocc metrics}}}."""
    jobs = [(label, i, s) for label, folder in SETS
            for i, s in enumerate(find_scenes(root / folder))]
    out: dict = {}
    with progress_bar(len(jobs) * len(CONDITIONS) * len(cfgs), "what-if", "run") as bar:
        for label, index, scene in jobs:
            data = load_scene(scene)
            left, right = to_grey(data["left"]), to_grey(data["right"])
            d = legal_disparities(data["ndisp"]) if data["ndisp"] else D_2003
            over = {"sva.disparities": d, "source.camera_width": 0, "source.camera_height": 0}
            for condition in CONDITIONS:
                pair = degrade(left, right, condition, seed, index)
                for name, cfg in cfgs.items():
                    m = run(*pair, mode="functional", config=cfg_for(cfg, over),
                            gt=data["gt"], masks=data["masks"]).report["metrics"]
                    out.setdefault(label, {}).setdefault(condition, {}) \
                        .setdefault(name, []).append(m)
                    bar.update(1)
    return {label: {c: {n: mean_metrics(v)["nonocc"] for n, v in per.items()}
                    for c, per in conds.items()} for label, conds in out.items()}


def cfg_for(paths: list, over: dict):
    return load_config(paths, over)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="the shared data folder (default: ../shared/data)")
    ap.add_argument("--write", action="store_true",
                    help="put the tables into docs/hybrid.md, hardware-study.md and "
                    "learned-descriptor.md, each between its markers")
    args = ap.parse_args(argv)
    root = Path(args.data) if args.data else shared_data_dir()
    if root is None or not (root / SETS[0][1]).is_dir():
        print("hybrid_whatif: no data: pass --data pointing at the shared data folder",
              file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    hw = {name: hardware(load_config(paths)) for name, paths in PRESETS.items()}
    lines = ["| 720p chip | descriptor bits | MACs / pixel | NNA work bound fps | fps from the "
             "720p60 cameras | chip SRAM (bits) | energy a frame (uJ) | power (mW) |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for name, h in hw.items():
        lines.append(f"| {name} | {h['parts']} | {h['macs']:,} | {h['bound']:.3f} | "
                     f"{h['delivered']:.3f} | {h['sram']:,} | {h['uj']:,.1f} | {h['mw']:.1f} |")
    lines.append("")
    acc = accuracy(root, PRESETS)
    for label, _ in SETS:
        lines += [f"**{label}**, nonocc mean totbad (bad2):", "",
                  "| condition | " + " | ".join(PRESETS) + " |",
                  "|---|" + "---|" * len(PRESETS)]
        for c in CONDITIONS:
            best = min(acc[label][c][n]["totbad"] for n in PRESETS)
            cells = []
            for n in PRESETS:
                v = acc[label][c][n]
                cell = f"{v['totbad']:.2f} ({v['bad2']:.2f})"
                cells.append(f"**{cell}**" if v["totbad"] == best else cell)
            lines.append(f"| {c} | " + " | ".join(cells) + " |")
        lines.append("")
    lines.append(f"(`python benchmarks/hybrid_whatif.py --write`, "
                 f"{time.perf_counter() - t0:.0f} s; bold: the lowest totbad of the row.)")
    print("\n".join(lines))
    if not args.write:
        return 0
    return max(write_between(ROOT / doc, f"<!-- {name}:begin -->", f"<!-- {name}:end -->", lines)
               for name, doc in PAGES.items())


if __name__ == "__main__":
    sys.exit(main())
