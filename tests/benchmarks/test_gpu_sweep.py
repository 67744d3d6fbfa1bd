"""The trimmed ``train`` command of the GPU sweep (benchmarks/gpu_sweep.sh) keeps the CLI's
one-line errors and exit status."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "gpu_train.py"


def test_the_trimmed_train_command_keeps_the_one_line_errors(tmp_path):
    out = tmp_path / "m.npz"
    done = subprocess.run([sys.executable, str(SCRIPT), "train", "--data",
                           str(tmp_path / "nowhere"), "--out", str(out)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert done.stderr.startswith("stereosim: error: ") and "not found" in done.stderr
    assert not out.exists()
