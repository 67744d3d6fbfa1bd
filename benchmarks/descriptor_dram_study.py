"""The paper's argument in numbers: binary descriptors against float32 feature maps between the
NNA and the SVA, if they went through DRAM -- traffic, stall cycles, energy per frame and power.

    python benchmarks/descriptor_dram_study.py [--write]

The chip as built passes 32-bit descriptors from the NNA to the SVA through on-chip FIFOs. A
design without them would spill the NNA's output to DRAM and read it back: the binary beats
(the 32-bit descriptor -- the paper's 3.6 MB per 720p frame and camera -- and the 8-bit pixel the
default adaptive P2 reads: 40 bits a pixel per camera), or 32 float32 channels, 1,024 bits a
pixel (118 MB). This script simulates a 720p stream of three frames on the cycle model
with the DRAM channel on (``dram.model = "tdm"``: one LPDDR4 x32 channel, 17 GB/s, its slots
shared by the stereo read, the write-back and ``dram.spill``), and reports per case the channel
traffic at 30 fps, the cycles the memory sources waited on the channel per frame, the
sustained frame rate the chip then reaches, energy per frame (stereosim's 45 nm table, the
spill priced per DRAM bit) and power at 30 fps. With ``--write`` it puts the table and two
plots in docs/energy.md and docs/img/.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from markers import write_between

from stereosim.sim.api import run_stream
from stereosim.sim.sweep import synthetic_pair

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "energy.md"
IMG = ROOT / "docs" / "img"
BEGIN, END = "<!-- spill-study:begin -->", "<!-- spill-study:end -->"
FPS = 30.0
FRAMES = 3


def measure() -> tuple[list[str], dict]:
    left, right = synthetic_pair(720, 1280)
    cases = {"on-chip FIFOs (as built)": "none", "binary descriptors via DRAM": "descriptors",
             "float32 feature maps via DRAM": "float32"}
    rows = ["| NNA -> SVA | spilled per frame (MB) | DRAM traffic at 30 fps (GB/s) | "
            "channel slots it takes | stall cycles per frame (NNA) | sustained fps | "
            "energy per frame (mJ) | of which DRAM (mJ) | power at 30 fps (mW) |",
            "|---|---|---|---|---|---|---|---|---|"]
    data = {}
    for name, spill in cases.items():
        rep = run_stream([(left, right)] * FRAMES, overrides={
            "dram.model": "tdm", "dram.spill": spill}).report
        dram, e = rep["dram"], rep["energy"]["per_frame_uj"]
        frame_bytes = sum(c["bytes"] for c in dram["clients"].values()) / FRAMES
        gbps = frame_bytes * FPS / 1e9
        spilled_mb = dram["clients"]["spill"]["bytes"] / FRAMES / 2 / 1e6 if spill != "none" \
            else 0.0  # one direction, both cameras
        share = sum(c["slots_per_round"] for k, c in dram["clients"].items() if k == "spill")
        stalls = dram["stall_cycles"]["memory_left"] / FRAMES
        fps = rep["stream"]["sustained_fps"]
        data[name] = {"energy_mj": e["total"] / 1e3, "dram_mj": e["by_block"]["dram"] / 1e3,
                      "gbps": gbps, "stalls": stalls, "fps": fps}
        rows.append(f"| {name} | {spilled_mb:.1f} | {gbps:.2f} | "
                    f"{share} of {dram['round_slots']} | {stalls:,.0f} | {fps:.1f} | "
                    f"{e['total'] / 1e3:.2f} | {e['by_block']['dram'] / 1e3:.2f} | "
                    f"{e['total'] * 1e-6 * FPS * 1e3:.0f} |")
    return rows, data


def plots(data: dict) -> list[str]:
    names = list(data)
    short = ["on-chip", "descriptors\nvia DRAM", "float32 maps\nvia DRAM"]
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    ax[0].bar(short, [data[k]["gbps"] for k in names], color=["#4c72b0", "#55a868", "#c44e52"])
    ax[0].axhline(17.0, color="k", ls="--", lw=1)
    ax[0].text(0.02, 17.0 * 1.03, "one LPDDR4 x32 channel, 17 GB/s", fontsize=8,
               transform=ax[0].get_yaxis_transform())
    ax[0].set_ylabel("DRAM traffic at 30 fps (GB/s)")
    ax[0].set_title("traffic")
    for i, k in enumerate(names):
        ax[0].text(i, data[k]["gbps"], f"{data[k]['fps']:.0f} fps", ha="center", va="bottom",
                   fontsize=8)
    other = [data[k]["energy_mj"] - data[k]["dram_mj"] for k in names]
    dram = [data[k]["dram_mj"] for k in names]
    ax[1].bar(short, other, label="on chip", color="#8c8c8c")
    ax[1].bar(short, dram, bottom=other, label="DRAM", color="#c44e52")
    ax[1].set_ylabel("energy per 720p frame (mJ)")
    ax[1].set_title("energy (45 nm table)")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    path = IMG / "spill_study.png"
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return [str(path)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="update docs/energy.md and its plot")
    args = ap.parse_args()
    rows, data = measure()
    print("\n".join(rows))
    if args.write:
        print("wrote " + ", ".join(plots(data)))
        return write_between(DOC, BEGIN, END, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
