"""The paper's argument in numbers: binary descriptors against float32 feature maps between the
NNA and the SVA, if they went through DRAM -- traffic, bandwidth, energy per frame and power.

    python benchmarks/descriptor_dram_study.py [--write]

The chip as simulated passes 32-bit descriptors from the NNA to the SVA through on-chip FIFOs.
A design without them would spill the NNA's output to DRAM and read it back: 32 bits a pixel
per camera as binary descriptors (the paper's 3.6 MB per 720p frame), or 32 float32 channels,
1,024 bits a pixel (118 MB). This script runs the default 720p chip on the cycle model for its
energy per frame (``report["energy"]``, stereosim's 45 nm table), adds the spill's DRAM bits
(written once and read once) at the table's DRAM energy, and gives the bandwidth at 30 fps
against one LPDDR4 x32 channel (17 GB/s peak). With ``--write`` it puts the table and two plots
in docs/energy.md and docs/img/. What it does not give: the stall cycles such traffic would
cost, which need the DRAM channel model (not built yet).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from sim.api import run
from sim.cycle.energy import energy_table
from sim.sweep import synthetic_pair
from markers import write_between

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "energy.md"
IMG = ROOT / "docs" / "img"
BEGIN, END = "<!-- spill-study:begin -->", "<!-- spill-study:end -->"
LPDDR4_X32_GBPS = 17.0  # 4266 MT/s x 32 bits (docs/energy.md, REFERENCE)
FPS = 30.0


def measure() -> tuple[list[str], dict]:
    left, right = synthetic_pair(720, 1280)
    rep = run(left, right, mode="cycle").report
    table = energy_table()
    e = rep["energy"]["per_frame_uj"]
    n = 1280 * 720
    cases = {"on-chip FIFOs (as built)": 0, "binary descriptors via DRAM": 32,
             "float32 feature maps via DRAM": 32 * 32}
    rows = ["| NNA -> SVA | spilled per frame (MB) | DRAM bandwidth at 30 fps (GB/s) | "
            "of one LPDDR4 x32 channel | energy per frame (mJ) | of which DRAM (mJ) | "
            "power at 30 fps (mW) |",
            "|---|---|---|---|---|---|---|"]
    data = {}
    base_dram = e["by_block"]["dram"]
    for name, bits in cases.items():
        spill_bits = 2 * 2 * n * bits  # both cameras, written and read back
        extra_uj = spill_bits * table.dram_pj_per_bit / 1e6
        total_uj = e["total"] + extra_uj
        # frame traffic on the channel: the views read, the words written, and the spill
        frame_bytes = 2 * n + n * 9 / 8 + spill_bits / 8
        gbps = frame_bytes * FPS / 1e9
        spilled_mb = 2 * n * bits / 8 / 1e6  # one direction, both cameras
        data[name] = {"energy_mj": total_uj / 1e3, "dram_mj": (base_dram + extra_uj) / 1e3,
                      "gbps": gbps}
        rows.append(f"| {name} | {spilled_mb:.1f} | {gbps:.2f} | "
                    f"{100 * gbps / LPDDR4_X32_GBPS:.1f} % | {total_uj / 1e3:.2f} | "
                    f"{(base_dram + extra_uj) / 1e3:.2f} | {total_uj * 1e-6 * FPS * 1e3:.0f} |")
    return rows, data


def plots(data: dict) -> list[str]:
    names = list(data)
    short = ["on-chip", "descriptors\nvia DRAM", "float32 maps\nvia DRAM"]
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    ax[0].bar(short, [data[k]["gbps"] for k in names], color=["#4c72b0", "#55a868", "#c44e52"])
    ax[0].axhline(LPDDR4_X32_GBPS, color="k", ls="--", lw=1)
    ax[0].text(0.02, LPDDR4_X32_GBPS * 1.03, "one LPDDR4 x32 channel, 17 GB/s", fontsize=8,
               transform=ax[0].get_yaxis_transform())
    ax[0].set_ylabel("DRAM bandwidth at 30 fps (GB/s)")
    ax[0].set_title("traffic")
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
