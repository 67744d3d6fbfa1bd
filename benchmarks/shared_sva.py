"""Camera pairs sharing one chip: two 720p 60 fps camera pairs, frame by frame.

    python benchmarks/shared_sva.py [--frames 30] [--write]

Each case streams ``--frames`` frames per pair of the embedded scene resized to 1280x720 from
CEA-861 720p60 cameras (74.25 MHz, 1650 x 750 raster) into two DRAM frame buffers per pair,
through the DRAM channel at its defaults, dropping the frames that find no free buffer; the
second pair runs half a frame period after the first (``sva.pairs = 2``). It prints per case
and per pair the measured sustained fps, drops and latency, and the work bound with its
bottleneck; a lone pair of the same chip gives what sharing costs in latency, and the last
case lends the other four NNA submodules to the example network configs/lent/backbone224.toml
(a recognition backbone at 30 fps; docs/lent.md), whose DRAM traffic takes a slot of each round.
``--write`` puts the table into docs/streams.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
from markers import write_between

import stereosim
from stereosim.core.datasets import default_scene

DOC = Path(__file__).resolve().parent.parent / "docs" / "streams.md"
LENT = Path(__file__).resolve().parent.parent / "configs" / "lent" / "backbone224.toml"
BEGIN, END = "<!-- shared-sva:begin -->", "<!-- shared-sva:end -->"
CAMERAS = {"source.kind": "camera", "source.frame_buffers": 2,
           "source.on_overflow": "drop_frame", "dram.model": "tdm"}
CNN4 = {"nna.descriptor": "cnn", "nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 1024}
CNN6 = {"nna.descriptor": "cnn", "nna.stereo_submodules": 6, "fifo.nna_to_merge_depth": 1024}
CASES = [
    ("census, one pair", {"nna.descriptor": "census"}, 1),
    ("census, two pairs", {"nna.descriptor": "census"}, 2),
    ("CNN, 4 submodules, one pair", CNN4, 1),
    ("CNN, 4 submodules, two pairs", CNN4, 2),
    ("CNN, 6 submodules, two pairs", CNN6, 2),
    ("CNN, 6 submodules, two pairs, 4 lent to backbone224 at 30 fps",
     {**CNN6, "nna.lent_submodules": 4, "nna.lent_network": str(LENT)}, 2),
]


def run_case(left, right, frames: int, over: dict, pairs: int) -> dict:
    t0 = time.perf_counter()
    stream = stereosim.run_stream([(left, right)] * frames,
                            overrides={**CAMERAS, **over, "sva.pairs": pairs})
    rep = stream.report
    return {"stream": rep["stream"], "bound": rep["throughput"]["fps_bound"],
            "bottleneck": rep["throughput"]["bottleneck"],
            "wall_s": time.perf_counter() - t0}


def _pair_rows(st: dict) -> list[dict]:
    return st.get("pairs") or [{"pair": 0, **st}]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30, help="frames per pair (default 30)")
    ap.add_argument("--write", action="store_true", help="write the table into docs/streams.md")
    args = ap.parse_args()
    scene = default_scene()
    left = cv2.resize(scene["left"], (1280, 720), interpolation=cv2.INTER_AREA)
    right = cv2.resize(scene["right"], (1280, 720), interpolation=cv2.INTER_AREA)
    rows = [f"{args.frames} frames per pair (`python benchmarks/shared_sva.py --frames "
            f"{args.frames}`):", "",
            "| chip | pair | frames taken | dropped | sustained fps | latency median / max ms "
            "| chip's work bound (bottleneck) |", "|---|---|---|---|---|---|---|"]
    for name, over, pairs in CASES:
        r = run_case(left, right, args.frames, over, pairs)
        for p in _pair_rows(r["stream"]):
            lat = p.get("latency_ms", {})
            fps = p["sustained_fps"]
            row = (f"| {name} | {p['pair']} | {p['frames_completed']} of {p['frames']} | "
                   f"{p['frames_dropped']} | {fps:.3f} | {lat.get('median', 0):.2f} / "
                   f"{lat.get('max', 0):.2f} | {r['bound']:.1f} ({r['bottleneck']}) |")
            rows.append(row)
            print(row, flush=True)
        print(f"  ({r['wall_s']:.1f} s wall; the whole stream sustains "
              f"{r['stream']['sustained_fps']} fps)", flush=True)
    if args.write:
        return write_between(DOC, BEGIN, END, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
