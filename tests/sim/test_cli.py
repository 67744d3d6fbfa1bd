"""The command line: outputs, one-line errors with exit status 2, nothing half-written."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stereosim.core.datasets import shared_data_dir
from stereosim.core.io import encode_png, read_pfm
from stereosim.sim.cli import main

DATA = shared_data_dir()


def _write_pair(tmp_path, h=21, w=57, shift=4):
    rng = np.random.default_rng(1)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    left, right = tmp_path / "l.png", tmp_path / "r.png"
    left.write_bytes(encode_png(base[:, :w].copy()))
    right.write_bytes(encode_png(base[:, shift:].copy()))
    return left, right


def _run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_run_writes_the_three_outputs(tmp_path, capsys):
    left, right = _write_pair(tmp_path)
    out = tmp_path / "out"
    code, stdout, _ = _run(["run", "--left", str(left), "--right", str(right), "--disparities",
                            "16", "--out", str(out), "--json"], capsys)
    assert code == 0
    report = json.loads(stdout)
    assert report == json.loads((out / "report.json").read_text())
    disp = read_pfm(out / "disparity.pfm")
    assert disp.shape == (21, 57)
    assert report["output"]["valid_pixels"] == int(np.isfinite(disp).sum())
    assert (out / "disparity.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_is_byte_for_byte_deterministic(tmp_path, capsys):
    left, right = _write_pair(tmp_path)
    outs = []
    for name in ("a", "b"):
        code, _, _ = _run(["run", "--left", str(left), "--right", str(right), "--disparities",
                           "16", "--out", str(tmp_path / name)], capsys)
        assert code == 0
        outs.append({f: (tmp_path / name / f).read_bytes()
                     for f in ("disparity.pfm", "disparity.png", "report.json")})
    assert outs[0] == outs[1]


def _bad_cases(tmp_path):
    left, right = _write_pair(tmp_path)
    small = tmp_path / "small.png"
    small.write_bytes(encode_png(np.zeros((21, 30), np.uint8)))
    corrupt = tmp_path / "corrupt.png"
    corrupt.write_bytes(b"\x89PNG\r\n\x1a\n this is not an image")
    one = tmp_path / "one.png"
    one.write_bytes(encode_png(np.zeros((1, 1), np.uint8)))
    empty_cfg = tmp_path / "bad.toml"
    empty_cfg.write_text("[sva]\nbogus = 1\n")
    lr = ["--left", str(left), "--right", str(right)]
    return {
        "mismatched sizes": ["run", "--left", str(left), "--right", str(small)],
        "1-pixel images": ["run", "--left", str(one), "--right", str(one)],
        "D >= width": ["run", "--left", str(small), "--right", str(small), "--disparities", "32"],
        "missing file": ["run", "--left", str(tmp_path / "nope.png"), "--right", str(right)],
        "corrupt file": ["run", "--left", str(corrupt), "--right", str(right)],
        "unknown key": ["run", *lr, "--set", "sva.bogus=1"],
        "unknown key in file": ["run", *lr, "--config", str(empty_cfg)],
        "bad value": ["run", *lr, "--disparities", "17"],
        "one view only": ["run", "--left", str(left)],
        "bad flag": ["run", "--frobnicate"],
        "missing gt": ["run", *lr, "--gt", str(tmp_path / "gt.pfm")],
        "png gt without scale": ["run", *lr, "--gt", str(left)],
        "missing dataset": ["eval", str(tmp_path / "nowhere")],
    }


@pytest.mark.parametrize("case", [
    "mismatched sizes", "1-pixel images", "D >= width", "missing file", "corrupt file",
    "unknown key", "unknown key in file", "bad value", "one view only", "bad flag",
    "missing gt", "png gt without scale", "missing dataset"])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(case, tmp_path, capsys):
    args = _bad_cases(tmp_path)[case]
    out = tmp_path / "out"
    if args[0] == "run":
        args = [*args, "--out", str(out)]
    code, stdout, stderr = _run(args, capsys)
    assert code == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("stereosim: error: "), stderr
    assert "Traceback" not in stderr
    assert not out.exists()


def test_console_script_has_no_traceback(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "stereosim.sim.cli", "run", "--left", str(tmp_path / "x.png"),
         "--right", str(tmp_path / "y.png")],
        capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("stereosim: error: image file")
    assert "Traceback" not in proc.stderr


def test_config_show_prints_loadable_toml(tmp_path, capsys):
    code, stdout, _ = _run(["config", "show", "--set", "sva.p1=3"], capsys)
    assert code == 0
    path = tmp_path / "c.toml"
    path.write_text(stdout)
    code, stdout, _ = _run(["config", "show", "--config", str(path), "--plain"], capsys)
    assert code == 0 and "p1 = 3\n" in stdout


def test_config_diff(tmp_path, capsys):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text("[sva]\np1 = 3\n")
    b.write_text("[sva]\np1 = 4\npaths = 2\n")
    code, stdout, _ = _run(["config", "diff", str(a), str(b)], capsys)
    assert code == 0
    # the sum register left unset follows the paths: 2 x (2^12 - 1) needs 13 bits, 4 x it 14
    assert stdout.splitlines() == ["sva.p1: 3 -> 4", "sva.paths: 4 -> 2", "sva.sum_bits: 14 -> 13"]


def test_config_diff_takes_preset_names_as_run_does(tmp_path, capsys):
    """``config diff paper-720p 1080p60`` reads the presets of configs/, like ``--config``; an
    unknown name lists the presets in one line."""
    code, stdout, _ = _run(["config", "diff", "paper-720p", "1080p60"], capsys)
    assert code == 0
    assert "nna.stereo_submodules: 2 -> 6" in stdout.splitlines()
    code, _, err = _run(["config", "diff", "paper-720p", "no-such-preset"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "'no-such-preset'" in err and "paper-720p" in err


@pytest.mark.skipif(DATA is None, reason="../shared/data (Middlebury scenes) is not present")
def test_run_on_a_2014_scene_folder_takes_d_from_calib(tmp_path, capsys):
    scene = DATA / "middlebury2014_trainingQ" / "ArtL"
    code, stdout, _ = _run(["run", str(scene), "--out", str(tmp_path), "--json"], capsys)
    assert code == 0
    report = json.loads(stdout)
    assert report["config"]["sva"]["disparities"] == 64  # ndisp 64 in calib.txt
    assert set(report["metrics"]) == {"nonocc", "all"}
    code, stdout, _ = _run(["run", str(scene), "--out", str(tmp_path), "--json",
                            "--disparities", "80"], capsys)
    assert json.loads(stdout)["config"]["sva"]["disparities"] == 80


@pytest.mark.skipif(DATA is None, reason="../shared/data (Middlebury scenes) is not present")
def test_eval_on_the_2003_layout(capsys):
    code, stdout, _ = _run(["eval", str(DATA / "middlebury2003_quarter"), "--json",
                            "--disparities", "64"], capsys)
    assert code == 0
    out = json.loads(stdout)
    assert sorted(out["scenes"]) == ["cones", "teddy"]
    for mask in ("nonocc", "all"):
        per_scene = [out["scenes"][s]["metrics"][mask]["bad2"] for s in ("cones", "teddy")]
        assert out["mean"][mask]["bad2"] == pytest.approx(sum(per_scene) / 2)
    # a working matcher on real data: far better than chance on these easy scenes
    assert out["mean"]["nonocc"]["bad2"] < 20


def test_rtl_synth_prints_the_cached_table_and_judges_the_clock(capsys):
    """``stereosim rtl synth``: the RTL twin's table from sva/synth_table.json (no Yosys
    run), the stages' rows and the compare_levels verdict at the clock asked for."""
    code, stdout, _ = _run(["rtl", "synth", "--mhz", "200"], capsys)
    assert code == 0
    assert "hamming" in stdout and "compare_levels = 8 at 200 MHz" in stdout
    for bad in (["rtl", "synth", "--mhz", "-3"], ["rtl", "synth", "--mhz", "nan"], ["rtl"]):
        code, _, stderr = _run(bad, capsys)
        lines = stderr.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith("stereosim: error: "), stderr


# ---- the chip's area (sim/cycle/area.py) in estimate, run and report.json ----------------------


def _words(text: str) -> str:
    return " ".join(text.split())


def _area_of(config: str | None, overrides: dict, shape=None) -> dict:
    from stereosim.core.config import load_config
    from stereosim.sim.cycle.area import chip_area
    from stereosim.sim.cycle.plan import build_plan, frame_size

    cfg = load_config(config, overrides)
    return chip_area(build_plan(cfg, shape or frame_size(cfg)), cfg.power.node)


def test_estimate_prints_the_chips_area_at_its_node(capsys):
    from stereosim.sim.cycle.area import area_lines

    code, stdout, _ = _run(["estimate", "--config", "1080p60"], capsys)
    assert code == 0
    area = _area_of(str(Path(__file__).resolve().parents[2] / "configs" / "1080p60.toml"), {})
    t = area["totals"]
    lines = area_lines(area)
    assert [ln for ln in stdout.splitlines() if ln.startswith("area")] == lines
    assert lines[0].startswith(f"area at 45nm, chip: {t['chip_mm2']:.4f} mm2: logic "
                               f"{t['logic_mm2']:.4f} mm2")
    assert f"SRAM {t['sram_mm2']:.4f} mm2" in lines[0]
    assert f"leakage {t['leakage_mw']:,.2f} mW" in lines[0]
    stereo = [b for b in area["blocks"] if b.get("use") == "stereo"]
    assert lines[1].startswith(f"area, NNA submodules, stereo: {len(stereo)}: "
                               f"{sum(b['area_mm2'] for b in stereo):.4f} mm2")
    code, stdout, _ = _run(["estimate", "--config", "1080p60", "--json"], capsys)
    assert json.loads(stdout)["area"] == json.loads(json.dumps(area))


def test_a_cycle_run_prints_its_area_and_reports_it(tmp_path, capsys):
    from stereosim.sim.cycle.area import area_rows

    left, right = _write_pair(tmp_path)
    out = tmp_path / "out"
    code, stdout, _ = _run(["run", "--left", str(left), "--right", str(right), "--disparities",
                            "16", "--mode", "cycle", "--out", str(out)], capsys)
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    area = _area_of(None, {"sva.disparities": 16}, (21, 57))
    assert report["area"] == json.loads(json.dumps(area))
    assert "area (45nm;" in stdout
    for what, figs in area_rows(area):
        assert _words(f"{what} {figs}") in _words(stdout)
    assert _words(f"chip {area['totals']['chip_mm2']:.4f} mm2: logic") in _words(stdout)


def test_at_7nm_the_sram_area_is_not_available(tmp_path, capsys):
    left, right = _write_pair(tmp_path)
    code, stdout, _ = _run(["run", "--left", str(left), "--right", str(right), "--disparities",
                            "16", "--mode", "cycle", "--set", "power.node=7nm", "--out",
                            str(tmp_path / "out")], capsys)
    assert code == 0
    area = _area_of(None, {"sva.disparities": 16, "power.node": "7nm"}, (21, 57))
    t = area["totals"]
    assert t["sram_mm2"] is None and t["chip_mm2"] is None
    text = _words(stdout)
    assert "area (7nm;" in stdout
    assert _words(f"chip n/a: logic {t['logic_mm2']:.4f} mm2") in text
    assert _words(f"SRAM not available ({t['sram_reason']})") in text
    code, stdout, _ = _run(["estimate", "--set", "power.node=7nm"], capsys)
    assert code == 0
    assert "SRAM not available (no cited SRAM macro table for 7nm" in stdout
