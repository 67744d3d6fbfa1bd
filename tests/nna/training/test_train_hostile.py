"""Hostile inputs of ``stereosim train`` and ``stereosim quantize`` (issue 46, item 9): each is
one line on stderr and exit status 2, before any training starts, with nothing written and an
existing output left as it was."""

import json
import pickle
import subprocess
import sys
from dataclasses import asdict

import numpy as np
import pytest

from stereosim.core.errors import ConfigError
from stereosim.nna.training.floatmodel import save_float_model
from stereosim.nna.training.trainconfig import TrainConfig, box_range, max_disparities
from stereosim.nna.training.traindata import load_strip_set, training_scene_dirs
from stereosim.nna.training.trainrun import checkpoint_path, cpu_count, parse_threads
from stereosim.sim.cli import main

OLD = b"an earlier output"


def _one_line(code: int, err: str) -> str:
    assert code == 2, err
    assert err.startswith("stereosim: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    return err


@pytest.fixture(scope="module")
def data_root(tmp_path_factory, scene_writer):
    root = tmp_path_factory.mktemp("data")
    for year, name, seed in (("2005", "Books", 2), ("2006", "Aloe", 3)):
        scene_writer(root / f"middlebury{year}_third" / name, seed, 5)
    return root


def _base_model(path, record) -> str:
    """A float model file (single9x9) whose training record is ``record`` (any JSON value)."""
    rng = np.random.default_rng(0)
    save_float_model(path, {
        "weights": [rng.normal(size=(32, 1, 9, 9)).astype(np.float32)],
        "biases": [np.zeros(32, np.float32)],
        "config": asdict(TrainConfig()), "scenes": [], "loss_per_epoch": [], "samples": 0,
    })  # fmt: skip
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["training"] = np.array(json.dumps(record))
    np.savez(path, **arrays)
    return str(path)


def _config(**changes):
    return {"config": {**asdict(TrainConfig()), **changes}, "scenes": [], "samples": 0,
            "loss_per_epoch": []}


def _without_scale_end():
    record = _config()
    del record["config"]["scale_end"]
    return record


RECORDS = [
    (_config(box=999), "box must be at most 15 (sva.box_size's range), got 999"),
    (_config(disparities=10**7), "disparities must be in 2..256"),
    (_config(box=5.5), "box must be a whole number, got 5.5"),
    (_config(disparities="96"), "disparities must be a number, got '96'"),
    (_config(gain=10**400), "gain must be a finite number"),
    ({"scenes": []}, "has no settings (a 'config' object)"),
    ([1, 2], "has no settings"),
    (None, "has no settings"),
    ("config", "has no settings"),
    ({"config": [1, 2]}, "has no settings"),
    (_without_scale_end(), "lacks scale_end"),
    (_config(scale_end="big"), "scale_end must be a number, got 'big'"),
    (_config(variant=["single9x9"]), "variant must be text, got ['single9x9']"),
    (_config(box=10**4000 + 1), "box must be at most 15 (sva.box_size's range), got 1000000"),
    (_config(offset=1e300), "offset, noise_max and shot_noise must be at most 255 grey levels"),
    (_config(gamma=1e300), "gain and gamma at most 1"),
    (_config(blur_max=1e300), "blur_max and vshift_max must be at most 13 px"),
    (_config(vshift_max=1e300), "blur_max and vshift_max must be at most 13 px"),
]


@pytest.mark.parametrize("record, message", RECORDS,
                         ids=["box", "disparities", "box-float", "disparities-text", "gain-huge",
                              "no-config", "list", "null", "string", "config-list",
                              "no-scale-end", "scale-end-text", "variant-list", "box-4000-digits",
                              "offset-huge", "gamma-huge", "blur-huge", "vshift-huge"])
def test_a_qat_base_records_settings_are_checked_as_the_clis(record, message, tmp_path, capsys):
    """`"box": 999` ran to the end at 15.2 GB, `"disparities": 10**7` passed 6.8 GB; a record
    of another shape was a traceback. The record is refused before the data are looked at (the
    data folder here does not exist)."""
    base = _base_model(tmp_path / "base.npz", record)
    out = tmp_path / "q.int8.npz"
    out.write_bytes(OLD)
    code = main(["train", "--qat", base, "--data", str(tmp_path / "nowhere"), "--out", str(out),
                 "--quiet"])
    err = _one_line(code, capsys.readouterr().err)
    assert f"float model {base!r}: its training record" in err and message in err
    assert len(err) < 300 + len(base)  # a crafted value is shown cut short
    assert out.read_bytes() == OLD


def test_train_config_bounds_the_windows_and_disparities_by_the_chips():
    lo, hi = box_range()
    assert TrainConfig(box=hi, aggregate=hi, disparities=max_disparities()).box == hi
    for bad in ({"box": hi + 2}, {"aggregate": hi + 2}, {"disparities": max_disparities() + 1},
                {"strips": 2.0}, {"lr": 10**400}):
        with pytest.raises(ConfigError):
            TrainConfig(**bad)


def test_augmentation_ranges_are_bounded_by_the_crop():
    """A defocus of sigma 1e6 took 70 s a crop in OpenCV (more: all the memory); a vertical
    misalignment of 1e300 rows overflowed. Both are at most the rows a sample cuts."""
    cfg = TrainConfig(box=7, blur_max=15.0, vshift_max=15.0)  # 9 + 7 - 1 rows
    assert cfg.crop_rows == 15
    assert TrainConfig(objective="triplet", aggregate=1).crop_rows == 9
    with pytest.raises(ConfigError, match="at most 15 px"):
        TrainConfig(box=7, blur_max=15.5)


@pytest.mark.parametrize("option", ["--noise-max", "--blur-max"])
def test_an_augmentation_range_is_refused_before_training(option, tmp_path, capsys):
    """`--noise-max 1e300` trained, numpy warning "overflow encountered in cast" on stderr;
    `--blur-max 1e300` took all the memory. The folder that does not exist would be the
    refusal if the range were taken."""
    out = tmp_path / "m.npz"
    code = main(["train", option, "1e300", "--data", str(tmp_path / "nowhere"), "--out",
                 str(out)])
    err = _one_line(code, capsys.readouterr().err)
    assert option[2:].replace("-", "_") in err and "must be at most" in err
    assert not out.exists()


def test_a_strip_is_at_most_a_row_of_the_widest_view(data_root):
    """A strip_width of 10**7 from a base model's record asked for 16 GB a batch."""
    dirs = training_scene_dirs(data_root)
    assert load_strip_set(dirs, TrainConfig(strip_width=400)).names
    with pytest.raises(ConfigError, match=r"strip_width 401 is wider than the widest training "
                       r"view \(400 px\)"):
        load_strip_set(dirs, TrainConfig(strip_width=401))


EMPTY = [
    (["train", "--out", ""], "--out"),
    (["train", "--data", ""], "--data"),
    (["train", "--qat", "", "--out", "q.npz"], "--qat"),
    (["train", "--qat", "base.npz", "--out", "q.npz", "--float-out", ""], "--float-out"),
    (["quantize", "", "--calib", ".", "--out", "q.npz"], "model"),
    (["quantize", "base.npz", "--calib", "", "--out", "q.npz"], "--calib"),
    (["quantize", "base.npz", "--calib", ".", "--out", ""], "--out"),
]


@pytest.mark.parametrize("argv, option", EMPTY)
def test_an_empty_file_option_is_refused(argv, option, tmp_path, monkeypatch, capsys):
    """`train --out ''` wrote ./single9x9.npz, `--data ''` read the default folder, and
    `--float-out ''` wrote no float model, with no word. (A later bad option, --epochs 0 or
    --samples 0, stops the command if '' were taken.)"""
    monkeypatch.chdir(tmp_path)
    later = ["--epochs", "0"] if argv[0] == "train" else ["--samples", "0"]
    err = _one_line(main([*argv, *later]), capsys.readouterr().err)
    assert f"argument {option}: '' is empty: give a path" in err
    assert list(tmp_path.iterdir()) == []


def test_threads_are_at_most_the_cpus(tmp_path, capsys):
    """`--threads 999` was taken."""
    assert parse_threads(str(cpu_count())) == cpu_count() and parse_threads("auto") == 0
    out = tmp_path / "m.npz"
    code = main(["train", "--threads", str(cpu_count() + 1), "--out", str(out), "--epochs", "0"])
    err = _one_line(code, capsys.readouterr().err)
    assert f"is more threads than the {cpu_count()} CPU" in err and "or auto" in err
    assert not out.exists()


def test_quiet_training_prints_nothing_on_stderr(data_root, tmp_path, capsys):
    """`train --quiet` printed its thread note."""
    out = tmp_path / "m.npz"
    argv = ["train", "--data", str(data_root), "--epochs", "1", "--steps", "1", "--strips", "2",
            "--threads", "1", "--checkpoint-every", "0", "--out", str(out)]
    assert main([*argv, "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert out.is_file()


def test_a_checkpoint_of_another_pickle_protocol_is_one_line_without_torchs_warning(
        data_root, tmp_path):
    """torch's weights-only reader warned "Detected pickle protocol 4 in the checkpoint" on
    stderr before the one error line (a warning shows only outside pytest: a process)."""
    out = tmp_path / "m.npz"
    checkpoint_path(out).write_bytes(pickle.dumps({"format": "x"}, protocol=4))
    run = subprocess.run(
        [sys.executable, "-m", "stereosim.sim.cli", "train", "--data", str(data_root), "--epochs",
         "1", "--steps", "1", "--strips", "2", "--threads", "1", "--quiet", "--out", str(out),
         "--resume"],
        capture_output=True, text=True, timeout=300)
    err = _one_line(run.returncode, run.stderr)
    assert "is not a readable training checkpoint" in err
    assert not out.exists()
