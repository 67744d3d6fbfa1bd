"""Two runs into one --out at the same time: each trial leaves a complete set from one run
(the report's SHA-256 manifest matches the disparity files beside it)."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys

import numpy as np

from stereosim.core.io import encode_png

TRIALS = 6


def _consistent_set(out):
    report = json.loads((out / "report.json").read_text())
    for name in ("disparity.pfm", "disparity.png"):
        digest = hashlib.sha256((out / name).read_bytes()).hexdigest()
        assert report["files"][name] == digest, f"{name} is not from the run of report.json"
    assert sorted(p.name for p in out.iterdir()) == ["disparity.pfm", "disparity.png",
                                                     "report.json"]
    return report["config"]["sva"]["disparities"]


def test_two_concurrent_runs_into_one_out_leave_a_whole_set(tmp_path):
    rng = np.random.default_rng(5)
    base = rng.integers(0, 256, (24, 72), dtype=np.uint8)
    (tmp_path / "l.png").write_bytes(encode_png(base[:, 4:].copy()))
    (tmp_path / "r.png").write_bytes(encode_png(base[:, :-4].copy()))
    out = tmp_path / "out"
    winners = []
    for _trial in range(TRIALS):
        procs = [
            subprocess.Popen(
                [sys.executable, "-m", "stereosim.sim.cli", "run", "--mode", "functional", "--left",
                 str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"), "--disparities",
                 str(d), "--out", str(out)],
                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
            for d in (16, 32)
        ]
        for p in procs:
            _, err = p.communicate(timeout=120)
            assert p.returncode == 0, err.decode()
        winners.append(_consistent_set(out))
    assert set(winners) <= {16, 32}
