"""benchmarks/hardware_study.py (docs/hardware-study.md): the page holds what the plan, the hand
formulas and the ablation's cached JSON give today; the hand formulas agree with the cycle model
on a small frame; the cached JSON is what the ablation computes (with the shared data)."""

import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "hardware_study.py"
sys.path.insert(0, str(SCRIPT.parent))

import ablation  # noqa: E402  (benchmarks/ is a folder of scripts, not a package)
import hardware_study  # noqa: E402

from stereosim.core.config import load_config  # noqa: E402
from stereosim.core.datasets import find_scenes, load_scene, shared_data_dir  # noqa: E402
from stereosim.nna.training.floatmodel import load_float_model  # noqa: E402
from stereosim.quant.artifact import load_quantized  # noqa: E402


def test_the_page_holds_the_plan_formula_and_accuracy_figures_of_today():
    """``--check`` recomputes every cell but the cycle model's (the plan, nna/geometry.py, the
    formulas, the cached ablation JSON) and compares them with the page; a stale page fails
    with the diff."""
    done = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True,
                          text=True, timeout=300, check=False, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr


def test_check_fails_on_a_changed_cell(monkeypatch):
    """The comparison is not blind: a page whose MACs per pixel differ by one is reported."""
    page = hardware_study.current()
    row = next(i for i, line in enumerate(page) if line.startswith("| mccnn4 |"))
    page[row] = page[row].replace("27,936", "27,937", 1)
    monkeypatch.setattr(hardware_study, "current", lambda: page)
    assert hardware_study.main(["--check"]) == 1


@pytest.mark.parametrize("variant", hardware_study.NETWORKS)
def test_the_hand_formulas_are_what_the_cycle_model_measures(variant):
    """On a 200 x 30 frame: the first output of every layer by the formula is the report's (and
    the last the trace's ``out.valid``), and the stream's sustained rate is the formula's
    f / (max_l II_l W H), which the plan's work bound also gives. The stream's rate is timed
    between the frames' last output words, on SVA clock edges: it may differ from the formula
    by one SVA period over the span of STREAM_FRAMES - 1 frames (and by its rounding to 3
    decimals)."""
    shape = (30, 200)
    p = hardware_study.plan_figures(variant, shape)
    c = hardware_study.cycle_figures(variant, p["first_formula"][-1], shape)
    assert c["per_layer_first"] == p["first_formula"]
    assert c["first_cycle"] == p["first_formula"][-1]
    assert c["bottleneck"] == "nna_left"
    fps = p["fps_formula"]
    sva_period_s = 1 / (load_config().clocks.sva_mhz * 1e6)
    edge = fps * sva_period_s * fps / (hardware_study.STREAM_FRAMES - 1)
    assert c["sustained_fps"] == pytest.approx(fps, abs=edge + 5e-4)
    assert p["fps_plan"] == pytest.approx(p["fps_formula"], abs=5e-4)


def test_the_first_output_formula_on_a_known_case():
    """One 9x9 layer, 9 cycles a pixel: (h + 1) W + c = 5 x 1280 + 9 (docs/architecture.md);
    two 3x3 layers of 10 cycles: layer 0 starts once input row 1 is in (2 W + 1), its row 0
    takes W x 10 cycles, its row 1 follows, and layer 1 starts after it."""
    assert hardware_study.first_outputs_formula((4,), (9,), (720, 1280)) == [6409]
    w = 1280
    first0 = 2 * w + 10
    row1_end = 2 * w + 2 * 10 * w
    assert hardware_study.first_outputs_formula((1, 1), (10, 10), (720, w)) == [
        first0, row1_end + 10]


@pytest.mark.skipif(shared_data_dir() is None,
                    reason="needs the shared Middlebury data (../shared/data) to re-score a "
                           "scene of the ablation's cached JSON")
@pytest.mark.parametrize("condition", list(hardware_study.ACCURACY))
def test_the_cached_accuracy_is_what_the_ablation_computes(condition):
    """The JSON the page's accuracy columns come from holds what benchmarks/ablation.py computes
    today: its first scene re-scored for the census and single9x9 rows."""
    path, _ = hardware_study.ACCURACY[condition]
    cached = json.loads(path.read_text())
    scene = find_scenes(shared_data_dir() / "middlebury2014_trainingQ")[0]
    assert cached["scenes"][0] == scene.name
    fpath, qpath = ablation.model_paths(ablation.MODELS, "single9x9")
    models = {"single9x9": (load_float_model(fpath)[0], load_quantized(qpath))}
    args = SimpleNamespace(noise=cached["noise"], seed=cached["seed"])
    rows, _ = ablation.evaluate_scene(load_scene(scene), 0, args, models)
    for key, metrics in rows.items():
        name = key if isinstance(key, str) else " / ".join(key)
        assert cached["per_scene"][0][name] == metrics, name


def test_the_ablation_scores_the_networks_whose_files_are_there(tmp_path):
    """Its default (the documented command) takes the variants with both files and skips the
    ones trained elsewhere or not kept; single9x9 takes the shipped artifact for its int8."""
    for name in ("mccnn4.float.npz", "mccnn4.int8.npz", "mixed5x5.float.npz",
                 "single9x9.float.npz", "mixed5x5-rf11.int8.npz"):
        (tmp_path / name).write_bytes(b"")
    assert ablation.variants_with_files(tmp_path) == ["mccnn4", "single9x9"]
    shipped = ablation.variants_with_files(ROOT / "benchmarks" / "models")
    assert "mixed5x5-wide" in shipped and "mixed5x5-40" not in shipped
