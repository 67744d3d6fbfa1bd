"""Regenerate the pictures of docs/reading-traces.md with the project's own commands.

    python docs/make_trace_pictures.py

Each picture is one `stereosim run ... --vcd` on the embedded default scene (Middlebury 2014
Motorcycle, 741x500) followed by one `stereosim wave`; the commands are printed as they run, so
any of them can be repeated by hand. The VCDs go to a temporary folder, the PNGs to docs/img/.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
IMG = os.path.join(HERE, "img")

# (picture, run options, wave signals, wave window)
PICTURES = [
    (
        "trace_line_buffer_fill.png",
        ["--set", "nna.descriptor=cnn", "--trace-window", "rows:0:1"],
        "top.memory_left.status,top.fifo.src_left_to_nna.occupancy,"
        "top.nna.left.sub0.line_buffer.*,top.nna.left.sub0.status,top.nna.left.sub0.mac.row,"
        "top.nna.left.sub0.out.valid,top.sva.status",
        "0:40us",
    ),
    (
        "trace_sva_row_delay.png",
        ["--set", "nna.descriptor=cnn", "--trace-window", "rows:0:3"],
        "top.sva.input.row,top.sva.input.rows_ready,top.sva.status,top.sva.output.row,"
        "top.sva.output.valid,top.sva.lr_check.reject,top.sink.count",
        "",
    ),
    (
        "trace_stall.png",
        ["--descriptor", "census", "--set", "fifo.nna_to_sva_depth=4", "--trace-window",
         "sva:31152:31192"],
        "clocks.*,top.nna.left.sub0.status,top.nna.left.sub0.out.valid,"
        "top.fifo.nna_left_to_sva.*,top.sva.status,top.sva.output.valid",
        "",
    ),
    (
        "trace_sva_stages.png",
        ["--descriptor", "census", "--trace-window", "sva:4750:4790"],
        "top.sva.pipeline.*,top.sva.stage.*.words,top.sva.stage.sgm.status,"
        "top.sva.output.valid",
        "",
    ),
]


def sh(args: list[str]) -> None:
    print("$ " + " ".join(shlex.quote(a) for a in args), flush=True)
    subprocess.run(args, check=True)


def main() -> int:
    os.makedirs(IMG, exist_ok=True)
    exe = [sys.executable, "-m", "stereosim.sim.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        for png, run_opts, signals, window in PICTURES:
            vcd = os.path.join(tmp, png.replace(".png", ".vcd"))
            sh([*exe, "run", "--out", os.path.join(tmp, "out"), "--vcd", vcd, *run_opts])
            wave = [*exe, "wave", vcd, "--signals", signals, "--png", os.path.join(IMG, png)]
            if window:
                wave += ["--window", window]
            sh(wave)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
