"""Regenerate the chip-plan pictures and listing of docs/architecture.md from the plan object.

    python docs/make_plan_pictures.py

Each picture is one `stereosim config plan --png`, printed as it runs; the default chip's listing
replaces the block between the `plan:begin` and `plan:end` markers of docs/architecture.md
(tests/sim/test_diagram.py checks that it is current).
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
IMG = os.path.join(HERE, "img")
DOC = os.path.join(HERE, "architecture.md")

PICTURES = [
    ("chip_plan.png", []),
    ("chip_plan_split_camera.png", ["--set", "nna.stereo_submodules=4", "--set",
                                    "source.kind=camera"]),
]


def main() -> None:
    listing = ""
    for name, options in PICTURES:
        cmd = [sys.executable, "-m", "stereosim.sim.cli", "config", "plan", *options,
               "--png", os.path.join(IMG, name)]
        print("$", shlex.join(["stereosim", *cmd[3:]]))
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        if not options:  # the plan's listing (sim.diagram.plan_text), without the energy line
            listing = "".join(line for line in out.splitlines(True)
                              if not line.startswith("energy:"))
    text = open(DOC, encoding="utf-8").read()
    block = f"<!-- plan:begin -->\n```\n{listing}```\n<!-- plan:end -->"
    new = re.sub(r"<!-- plan:begin -->.*?<!-- plan:end -->", lambda _: block, text, flags=re.S)
    with open(DOC, "w", encoding="utf-8") as f:
        f.write(new)


if __name__ == "__main__":
    main()
