"""Two runs into one --out at the same time: each trial leaves a complete set from one run --
the report's SHA-256 manifest matches the disparity files beside it, and those files are the
ones that run makes alone (a set mixed from both runs, even one whose manifest was made to
match, is not)."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys

import numpy as np

from stereosim.core.io import encode_png

TRIALS = 6
DISPARITIES = (16, 32)
MAPS = ("disparity.pfm", "disparity.png")


def _start(tmp_path, disparities, out):
    return subprocess.Popen(
        [sys.executable, "-m", "stereosim.sim.cli", "run", "--mode", "functional", "--left",
         str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"), "--disparities",
         str(disparities), "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _wait(procs):
    for p in procs:
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0, err.decode()


def _maps(out) -> dict[str, str]:
    return {name: hashlib.sha256((out / name).read_bytes()).hexdigest() for name in MAPS}


def _consistent_set(out) -> tuple[int, dict[str, str]]:
    """The disparities of the run whose report.json is in ``out`` and the digests of the maps
    beside it, after checking that the report's manifest names those maps and nothing else is
    left there."""
    report = json.loads((out / "report.json").read_text())
    maps = _maps(out)
    for name, digest in maps.items():
        assert report["files"][name] == digest, f"{name} is not from the run of report.json"
    assert sorted(p.name for p in out.iterdir()) == sorted((*MAPS, "report.json"))
    return report["config"]["sva"]["disparities"], maps


def test_two_concurrent_runs_into_one_out_leave_a_whole_set(tmp_path):
    rng = np.random.default_rng(5)
    base = rng.integers(0, 256, (24, 72), dtype=np.uint8)
    (tmp_path / "l.png").write_bytes(encode_png(base[:, 4:].copy()))
    (tmp_path / "r.png").write_bytes(encode_png(base[:, :-4].copy()))
    # each run alone, into a folder of its own: the set it leaves
    _wait([_start(tmp_path, d, tmp_path / f"alone{d}") for d in DISPARITIES])
    alone = {d: _maps(tmp_path / f"alone{d}") for d in DISPARITIES}
    for name in MAPS:  # else a set mixed from both runs would look whole
        assert alone[16][name] != alone[32][name], name
    out = tmp_path / "out"
    left = []
    for _trial in range(TRIALS):
        _wait([_start(tmp_path, d, out) for d in DISPARITIES])
        left.append(_consistent_set(out))
    assert [maps for _, maps in left] == [alone[d] for d, _ in left]
