"""The tuning protocol (docs/tuning.md) is enforced by the tuning script: it refuses to tune on
a held-out test set, whatever the folder is called above it."""

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "tune_defaults.py"


@pytest.mark.parametrize("held_out", ["middlebury2014_trainingQ", "middlebury2003_quarter"])
def test_tuning_on_a_held_out_set_is_refused(tmp_path, held_out):
    folder = tmp_path / "data" / held_out
    folder.mkdir(parents=True)
    done = subprocess.run([sys.executable, str(SCRIPT), "--data", str(folder), "--grid",
                           "sva.p1=48"], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == (f"tune_defaults: {folder} is a held-out test set: tune on "
                                   "the shared data folder (its 2005/2006 scenes)")


def test_the_shared_folder_tunes_on_2005_and_2006_only(tmp_path):
    """A shared folder with only held-out sets has no tuning scene: the script stops with the
    training-scene loader's one-line message before scoring anything."""
    (tmp_path / "middlebury2014_trainingQ").mkdir()
    done = subprocess.run([sys.executable, str(SCRIPT), "--data", str(tmp_path), "--grid",
                           "sva.p1=48"], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert done.stderr.startswith("tune_defaults: ") and "holds no training scenes" in done.stderr


@pytest.mark.parametrize("explore", [["--descriptor", "cnn"], ["--condition", "blur"],
                                     ["--passes", "2"], ["--descriptor", "cnn", "--weights",
                                                         "n.int8.npz"]])
def test_a_partial_chain_is_never_written_into_the_page(tmp_path, explore):
    """``tuning_report.py`` may explore one descriptor or other conditions, but the page holds
    the whole chain under the protocol's criterion: such a run with --write is refused before
    any scene is read, and the page is left as it was."""
    page = tmp_path / "tuning.md"
    page.write_text("<!-- protocol-results:begin -->\nold\n<!-- protocol-results:end -->\n")
    before = page.read_bytes()
    done = subprocess.run([sys.executable, str(SCRIPT.with_name("tuning_report.py")), *explore,
                           "--data", str(tmp_path), "--write", str(page)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == ("tuning_report: --descriptor, --condition, --passes and "
                                   "--weights explore; the page holds the whole chain under "
                                   "the protocol's criterion: drop them to --write")
    assert page.read_bytes() == before


def test_weights_without_the_cnn_studies_are_refused(tmp_path):
    done = subprocess.run([sys.executable, str(SCRIPT.with_name("tuning_report.py")),
                           "--weights", "n.int8.npz", "--data", str(tmp_path)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == "tuning_report: --weights names a CNN: give --descriptor cnn too"


def test_cross_validating_weights_on_a_held_out_set_is_refused(tmp_path):
    """``descriptor_cv.py`` scores per-fold weights on the tuning scenes under the same rule."""
    folder = tmp_path / "data" / "middlebury2014_trainingQ"
    folder.mkdir(parents=True)
    done = subprocess.run([sys.executable, str(SCRIPT.with_name("descriptor_cv.py")), "--data",
                           str(folder), "--weights", "a.npz,b.npz"], capture_output=True,
                          text=True, timeout=120, check=False)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip() == (f"descriptor_cv: {folder} is a held-out test set: tune on "
                                   "the shared data folder (its 2005/2006 scenes)")


@pytest.mark.parametrize("held_out", ["middlebury2014_trainingQ", "middlebury2003_quarter"])
def test_the_hybrid_is_never_tuned_on_a_held_out_set(tmp_path, held_out):
    folder = tmp_path / "data" / held_out
    folder.mkdir(parents=True)
    done = subprocess.run([sys.executable, str(SCRIPT.with_name("hybrid_tuning.py")), "--data",
                           str(folder)], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.strip().startswith(f"hybrid_tuning: {folder} is a held-out test set")


def test_the_hybrid_tunings_scorer_is_the_functional_model(monkeypatch):
    """benchmarks/hybrid_tuning.py scores a point on descriptors it computed once; the metrics
    are stereosim.run's on the same pair and configuration."""
    import numpy as np

    monkeypatch.syspath_prepend(str(SCRIPT.parent))
    import hybrid_tuning

    from stereosim.sim.api import run

    rng = np.random.default_rng(3)
    left = rng.integers(0, 256, (30, 90), dtype=np.uint8)
    right = np.roll(left, -5, axis=1)
    gt = np.full((30, 90), 5.0, np.float32)
    masks = {"nonocc": np.ones((30, 90), bool)}
    data = {"gl": left, "gr": right, "gt": gt, "masks": masks}
    point = {**hybrid_tuning.START, "sva.weight_mode": "auto", "sva.noisy_weights": "[1,0]"}
    got = hybrid_tuning.hybrid_scores([("synthetic", data, 32)], point)[0]
    cfg = hybrid_tuning._config(point, 32)
    want = run(left, right, mode="functional", config=cfg, gt=gt,
               masks=masks).report["metrics"]["nonocc"]
    assert np.allclose(got, [want[k] for k in hybrid_tuning.KEYS], equal_nan=True)
