"""Hostile-user cases, one test each: every way in is checked (exit 2 and one line
from the CLI, a UserError from the API), every way out is whole (old outputs intact, nothing
half-written, no traceback, no death by signal)."""

from __future__ import annotations

import contextlib
import dataclasses
import dis
import errno
import json
import os
import runpy
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from stereosim.core import outputs, signals
from stereosim.core.config import ChipConfig, load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import encode_png
from stereosim.sim.api import run
from stereosim.sim.cli import main

RUN_FILES = ("disparity.pfm", "disparity.png", "report.json")


def _pair(h=20, w=48, shift=3, seed=1):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return np.ascontiguousarray(base[:, shift:]), np.ascontiguousarray(base[:, :w])


def _write_pair(folder, h=20, w=48, seed=1):
    left, right = _pair(h, w, seed=seed)
    folder.mkdir(parents=True, exist_ok=True)
    lp, rp = folder / "l.png", folder / "r.png"
    lp.write_bytes(encode_png(left))
    rp.write_bytes(encode_png(right))
    return lp, rp


def _cli(argv, capfd):
    code = main([str(a) for a in argv])
    out, err = capfd.readouterr()
    return code, out, err


def _one_line_error(code, err):
    """The one error line of a command that exit 2; numba's compile notice (core.progress) may
    come before it when the kernels' cache is cold, as in a run of this file alone."""
    assert code == 2, err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("stereosim: compiling")]
    assert len(lines) == 1 and lines[0].startswith("stereosim: error: "), err
    assert "Traceback" not in err
    return lines[0]


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())} if folder.is_dir() else {}


@pytest.fixture
def old_run(tmp_path, capfd):
    """A folder with a complete output set from an earlier run, and the pair it came from."""
    left, right = _write_pair(tmp_path / "in")
    out = tmp_path / "out"
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "16", "--out", out], capfd)
    assert code == 0, err
    return left, right, out, _snapshot(out)


# ---------------------------------------------------------------- the API takes no unchecked config


def _replace(cfg, section, **values):
    return dataclasses.replace(cfg, **{section: dataclasses.replace(getattr(cfg, section),
                                                                    **values)})


@pytest.mark.parametrize("mode", ["functional", "cycle"])
@pytest.mark.parametrize("section, values, message", [
    ("sva", {"paths": 5}, r"'sva.paths' must be in \[1, 4\]; got 5"),
    ("sva", {"paths": 64}, r"'sva.paths' must be in \[1, 4\]"),
    ("sva", {"disparities": 17}, r"'sva.disparities' must be one of 16, 32"),
    ("sva", {"box_size": 0}, r"'sva.box_size' must be in \[1, 15\]"),
    ("sva", {"box_size": 4}, r"'sva.box_size' must be odd"),
    ("sim", {"watchdog_cycles": 0}, r"'sim.watchdog_cycles' must be in \[10, "),
    ("fifo", {"nna_to_sva_depth": 0}, r"'fifo.nna_to_sva_depth' must be in \[1, "),
    ("clocks", {"sva_mhz": 0.0}, r"'clocks.sva_mhz' must be in \[0.001, "),
    ("clocks", {"nna_mhz": float("nan")}, r"'clocks.nna_mhz' must be a finite number"),
    ("source", {"memory_gbps": float("inf")}, r"'source.memory_gbps' must be a finite number"),
    ("sva", {"p1": "80"}, r"'sva.p1' must be an integer"),
    ("nna", {"stereo_submodules": 3}, r"nna.stereo_submodules=3 must be even"),
])
def test_a_hand_built_config_gets_load_configs_checks(mode, section, values, message):
    left, right = _pair()
    cfg = _replace(load_config(overrides={"sva.disparities": 16}), section, **values)
    with pytest.raises(ConfigError, match=message):
        run(left, right, mode=mode, config=cfg)


def test_a_config_with_a_section_of_the_wrong_class_is_refused():
    left, right = _pair()
    cfg = dataclasses.replace(ChipConfig(), sva=load_config().nna)
    with pytest.raises(ConfigError, match="config section 'sva' must be a SvaConfig"):
        run(left, right, config=cfg)


def test_numpy_scalars_are_accepted_as_overrides():
    cfg = load_config(overrides={"sva.disparities": np.int64(32), "sva.lr_check": np.bool_(False),
                                 "clocks.nna_mhz": np.float32(400.0)})
    assert (cfg.sva.disparities, cfg.sva.lr_check, cfg.clocks.nna_mhz) == (32, False, 400.0)
    assert type(cfg.sva.disparities) is int


def test_masks_must_be_a_mapping():
    left, right = _pair()
    gt = np.full(left.shape, 3.0, np.float32)
    with pytest.raises(InputError, match="masks must be a dict"):
        run(left, right, overrides={"sva.disparities": 16}, gt=gt, masks=[gt > 0])


@pytest.mark.parametrize("value, message", [(-1.0, "the gt= array holds the negative disparity -1"),
                                            (1e30, "the gt= array holds the disparity 1e\\+30")])
def test_impossible_gt_values_are_refused(value, message):
    left, right = _pair()
    gt = np.full(left.shape, 3.0, np.float32)
    gt[2, 5] = value
    with pytest.raises(InputError, match=message):
        run(left, right, overrides={"sva.disparities": 16}, gt=gt)


def test_no_cap_reads_the_file_it_has(tmp_path, capfd):
    """--max-pixels 0 (no cap) reads the image it has: the reader must not ask for a buffer of
    the cap's size (a MemoryError on every image)."""
    left, right = _write_pair(tmp_path / "in")
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "16", "--max-pixels", "0", "--out", tmp_path / "o"],
                        capfd)
    assert code == 0, err


def test_the_api_caps_the_image_size():
    left, right = _pair(h=40, w=64)
    with pytest.raises(InputError, match=r"64x40 \(0.0 M pixels\), above the cap"):
        run(left, right, overrides={"sva.disparities": 16}, max_pixels=1000)
    assert run(left, right, overrides={"sva.disparities": 16}, max_pixels=None).disparity.shape \
        == (40, 64)


# ---------------------------------------------------------------- strict JSON


def test_report_json_is_strict_when_a_metric_is_undefined(tmp_path, capfd):
    left, right = _write_pair(tmp_path / "in")
    gt = np.full((20, 48), np.inf, np.float32)  # no known pixel: every metric undefined
    from stereosim.core.io import pfm_bytes

    (tmp_path / "gt.pfm").write_bytes(pfm_bytes(gt))
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right, "--gt",
                         tmp_path / "gt.pfm", "--disparities", "16", "--out", tmp_path / "o"],
                        capfd)
    assert code == 0, err

    def refuse(name):
        raise ValueError(f"bare {name} in report.json")

    report = json.loads((tmp_path / "o" / "report.json").read_text(), parse_constant=refuse)
    assert report["metrics"]["all"]["bad2"] is None
    assert "no pixel with known ground truth" in report["metrics_undefined"]["all"]


# ---------------------------------------------------------------- the output set


def test_outputs_are_checked_before_the_run(old_run, tmp_path, capfd, monkeypatch):
    left, right, out, before = old_run

    def no_run(*a, **k):
        raise AssertionError("the simulation ran before the outputs were checked")

    monkeypatch.setattr("stereosim.sim.cli.run", no_run)
    (tmp_path / "adir").mkdir()
    cases = [
        (["--vcd", tmp_path / "adir"], "--vcd path .* is a folder"),
        (["--vcd", out / "report.json"], "would both write"),
        (["--vcd", tmp_path / "t.vcd", "--timeline", tmp_path / "t.vcd"], "would both write"),
        (["--vcd", tmp_path / "t.vcd", "--timeline", tmp_path / "t.gtkw"], "would both write"),
        (["--vcd", tmp_path / ("v" * 300 + ".vcd")], "too long"),
    ]
    for extra, message in cases:
        code, _, err = _cli(["run", "--left", left, "--right", right, "--disparities", "16",
                             "--out", out, *extra], capfd)
        line = _one_line_error(code, err)
        assert __import__("re").search(message, line), line
        assert _snapshot(out) == before


def test_an_empty_out_is_refused(tmp_path, capfd, monkeypatch):
    """--out '' is refused: it would write the set (disparity.pfm, disparity.png, report.json)
    into the working directory."""
    left, right = _write_pair(tmp_path / "in")
    monkeypatch.chdir(tmp_path)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "16", "--out", ""], capfd)
    assert "--out is empty" in _one_line_error(code, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_a_full_disk_leaves_the_old_set(old_run, capfd, monkeypatch):
    left, right, out, before = old_run
    real = outputs._write_fd
    written = []

    def full(fd, data):
        written.append(1)
        if len(written) == 3:  # the report, after both disparity maps
            raise OSError(errno.ENOSPC, "No space left on device")
        real(fd, data)

    monkeypatch.setattr(outputs, "_write_fd", full)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "32", "--out", out], capfd)
    assert "No space left on device" in _one_line_error(code, err)
    assert _snapshot(out) == before


def test_a_read_only_folder_is_refused_before_the_run(tmp_path, capfd, monkeypatch):
    left, right = _write_pair(tmp_path / "in")
    real = os.access
    monkeypatch.setattr(outputs.os, "access",
                        lambda p, mode: False if str(p).endswith("ro") else real(p, mode))
    (tmp_path / "ro").mkdir()
    code, _, err = _cli(["run", "--left", left, "--right", right, "--disparities", "16", "--out",
                         tmp_path / "ro" / "out"], capfd)
    assert "cannot write --out disparity.pfm into" in _one_line_error(code, err)
    assert list((tmp_path / "ro").iterdir()) == []


def _handles_sigterm(pid: int) -> bool:
    """Has process ``pid`` installed a SIGTERM handler (Linux: SigCgt in /proc/PID/status)?"""
    with open(f"/proc/{pid}/status") as f:
        caught = next(line for line in f if line.startswith("SigCgt:")).split()[1]
    return bool(int(caught, 16) >> (signal.SIGTERM - 1) & 1)


@pytest.mark.parametrize("delay", [0.0, 0.4, 1.5])
def test_sigterm_during_a_run_leaves_the_old_set_and_no_temporary_files(old_run, tmp_path,
                                                                        delay):
    """SIGTERM once stereosim's handler is in (before that the process holds nothing): at
    the start of the work, during the simulation, while the files are written, or as the
    interpreter shuts down (numba's and llvmlite's objects freed: once under load a signal
    there printed "Exception ignored"; a signal after the default actions are back killed
    the process) -- the exit status and stderr are the signal's or the run's, nothing else."""
    _, _, out, before = old_run
    left, right = _write_pair(tmp_path / "big", h=120, w=300, seed=2)
    cmd = [sys.executable, "-m", "stereosim.sim.cli", "run", "--left", str(left),
           "--right", str(right), "--disparities", "32", "--out", str(out),
           "--vcd", str(out / "t.vcd"), "--force"]
    # as from a shell: no signal blocked (the test process may hold some, and hand them down)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.pthread_sigmask(signal.SIG_SETMASK, set()))
    deadline = time.monotonic() + 60
    while proc.poll() is None and not _handles_sigterm(proc.pid):
        assert time.monotonic() < deadline, "stereosim never installed its SIGTERM handler"
        time.sleep(0.01)
    time.sleep(delay)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    leftovers = [p.name for p in out.iterdir() if p.name.startswith(".")]
    assert leftovers == []
    # a first run may note first that it compiles the kernels (killed during it, it will say
    # so again next time): those lines, then the one that says what happened, if any
    lines = [ln for ln in err.decode().splitlines() if not ln.startswith("stereosim: compiling")]
    if proc.returncode == 0:  # it finished first (the signal came as it shut down, or never)
        assert lines == [], err.decode()  # no line: no "Exception ignored" as numba shuts down
        assert sorted(p.name for p in out.iterdir()) == sorted([*RUN_FILES, "t.vcd", "t.gtkw",
                                                                "t.status.txt"])
    else:
        assert proc.returncode == 143 and len(lines) == 1, err.decode()
        if lines[0] != "stereosim: terminated":  # after the publish: then the new set is whole
            assert lines == ["stereosim: terminated after writing its outputs (they are "
                             "complete)"]
            assert json.loads((out / "report.json").read_text())["config"]["sva"][
                "disparities"] == 32
        else:
            assert _snapshot(out) == before


def test_stdout_on_a_full_device_is_one_line(tmp_path):
    with open("/dev/full", "w") as full:
        proc = subprocess.run([sys.executable, "-m", "stereosim.sim.cli", "config", "show"],
                              stdout=full, stderr=subprocess.PIPE, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.decode().splitlines() == [
        "stereosim: error: cannot write to standard output (No space left on device): check "
        "the device or pipe it writes to"]


# ---------------------------------------------------------------- eval keeps going


def _dataset(tmp_path):
    """Three 2014-layout scenes: a good one, one without GT, one with a corrupt image."""
    root = tmp_path / "ds"
    for name in ("a_good", "b_nogt", "c_corrupt"):
        lp, rp = _write_pair(root / name, h=20, w=48)
        lp.rename(root / name / "im0.png")
        rp.rename(root / name / "im1.png")
    from stereosim.core.io import pfm_bytes

    (root / "a_good" / "disp0GT.pfm").write_bytes(pfm_bytes(np.full((20, 48), 3.0, np.float32)))
    (root / "c_corrupt" / "disp0GT.pfm").write_bytes(pfm_bytes(np.full((20, 48), 3.0,
                                                                       np.float32)))
    (root / "c_corrupt" / "im1.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    return root


def test_eval_scores_the_good_scenes_and_reports_the_others(tmp_path, capfd):
    root = _dataset(tmp_path)
    code, out, err = _cli(["eval", root, "--disparities", "16", "--json", "--out",
                           tmp_path / "ev.json"], capfd)
    line = _one_line_error(code, err)
    assert "2 of 3 scenes failed" in line
    doc = json.loads(out)
    assert doc == json.loads((tmp_path / "ev.json").read_text())
    assert doc["scenes"]["a_good"]["metrics"]["all"]["n"] == 20 * 48
    assert "no ground truth" in doc["scenes"]["b_nogt"]["error"]
    assert "corrupt" in doc["scenes"]["c_corrupt"]["error"]
    assert doc["failed"] == 2


def test_eval_table_shows_failed_scenes(tmp_path, capfd):
    root = _dataset(tmp_path)
    code, out, err = _cli(["eval", root, "--disparities", "16"], capfd)
    _one_line_error(code, err)
    assert "a_good: all totbad" in out
    assert "FAILED b_nogt: scene b_nogt has no ground truth" in out


def test_eval_refuses_a_bad_override_once(tmp_path, capfd):
    root = _dataset(tmp_path)
    code, out, err = _cli(["eval", root, "--set", "sva.pathz=2"], capfd)
    assert "unknown config key 'sva.pathz'" in _one_line_error(code, err)
    assert out == ""


# ---------------------------------------------------------------- numbers and files


@pytest.mark.parametrize("argv, message", [
    (["run", "--set", "clocks.nna_mhz=nan"], "'clocks.nna_mhz' must be a finite number"),
    (["run", "--set", "clocks.camera_mhz=inf"], "'clocks.camera_mhz' must be a finite number"),
    (["run", "--set", "source.memory_gbps=nan"], "'source.memory_gbps' must be a finite"),
    (["run", "--vcd", "x.vcd", "--trace-limit", "nan"], "'nan' is not a finite number"),
    (["run", "--gt-scale", "nan"], "'nan' is not a finite number"),
    (["train", "--lr", "nan"], "'nan' is not a finite number"),
    (["train", "--noise-max", "inf"], "'inf' is not a finite number"),
    (["train", "--blur-max", "nan"], "'nan' is not a finite number"),
    (["train", "--epochs", "0"], "'0' must be at least 1"),
    (["train", "--box", "4"], "box must be odd and >= 1, got 4"),
    (["quantize", "m.npz", "--calib", ".", "--out", "q.npz", "--act-quantile", "nan"],
     "'nan' is not a finite number"),
    (["run", "--max-pixels", "-1"], "must be a whole number >= 0"),
])
def test_non_finite_and_impossible_numbers_are_refused_by_name(argv, message, capfd, tmp_path,
                                                               monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = _cli(argv, capfd)
    assert message in _one_line_error(code, err)


def test_outputs_of_long_jobs_are_checked_first(tmp_path, capfd):
    (tmp_path / "d").mkdir()
    for argv in (["quantize", tmp_path / "m.npz", "--calib", tmp_path, "--out", tmp_path / "d"],
                 ["train", "--data", tmp_path, "--out", tmp_path / "d"],
                 ["config", "plan", "--png", tmp_path / "d"]):
        code, _, err = _cli(argv, capfd)
        assert "--" in _one_line_error(code, err) and "is a folder" in err


def test_an_unreadable_or_too_long_config_is_one_line(tmp_path, capfd):
    (tmp_path / "c.toml").mkdir()
    for path, message in ((tmp_path / "c.toml", "is a folder"),
                          (tmp_path / ("c" * 5000 + ".toml"), "cannot read config file"),
                          (tmp_path / "bin.toml", "is not UTF-8 text")):
        if path.name == "bin.toml":
            path.write_bytes(b"\xff\xfe\x00")
        code, _, err = _cli(["config", "show", "--config", path], capfd)
        assert message in _one_line_error(code, err)



# ---------------------------------------------------------------- outputs never replace inputs


@pytest.fixture
def no_work(monkeypatch):
    """Every simulation, training and quantization fails the test: what is tested here must be
    refused before any of them starts."""
    def refuse(*a, **k):
        raise AssertionError("the work started before the outputs were checked")

    for name in ("cli.run", "train_cli.train", "train_cli.quantize"):
        monkeypatch.setattr(f"stereosim.sim.{name}", refuse)


def _inputs(tmp_path):
    left, right = _write_pair(tmp_path / "in")
    (tmp_path / "c.toml").write_text("[sva]\np1 = 200\n")
    (tmp_path / "m.npz").write_bytes(b"a model")
    return left, right, _dataset(tmp_path)


@pytest.mark.parametrize("argv, message", [
    (["run", "--left", "{l}", "--right", "{r}", "--html", "{l}"],
     r"--html path .*l.png is the input --left .*l.png: write it elsewhere"),
    (["run", "--left", "{l}", "--right", "{r}", "--gt", "{t}/out/disparity.pfm", "--out",
      "{t}/out"], r"--out disparity.pfm path .* is the input --gt"),
    (["run", "--left", "{l}", "--right", "{r}", "--vcd", "{r}"], r"--vcd path .* is the input "
     r"--right"),
    (["run", "--left", "{l}", "--right", "{r}", "--config", "{t}/c.toml", "--timeline",
      "{t}/c.toml"], r"--timeline path .* is the input --config"),
    (["run", "--left", "{t}/in/disparity_kitti.png", "--right", "{r}", "--save-as", "kitti",
      "--out", "{t}/in"], r"--save-as kitti path .* is the input --left"),
    (["run", "{t}/ds/a_good", "--html", "{t}/ds/a_good/im0.png"],
     r"--html path .*im0.png is the input scene file"),
    (["quantize", "{t}/m.npz", "--calib", "{t}/ds", "--out", "{t}/m.npz"],
     r"--out path .*m.npz is the input model"),
    (["config", "plan", "--config", "{t}/c.toml", "--png", "{t}/c.toml"],
     r"--png path .*c.toml is the input --config"),
    (["eval", "{t}/ds", "--out", "{t}/ds/a_good/disp0GT.pfm"],
     r"--out path .*disp0GT.pfm is the input scene file"),
    (["eval", "{t}/ds", "--save", "{t}/ds", "--algo-name", "GT"],
     r"--save path .*a_good/disp0GT.pfm is the input scene file"),
    (["eval", "{t}/ds", "--save", "{t}/x", "--out", "{t}/x"],
     r"--out path .*x is a folder --save writes into"),
])
def test_an_output_never_replaces_an_input(argv, message, tmp_path, capfd, no_work):
    """`run --html L.png`, `quantize m.npz --out m.npz`, ...: an output that would overwrite
    what the command reads is one line before any work, and every input stays as it was."""
    left, right, _ = _inputs(tmp_path)
    (tmp_path / "in" / "disparity_kitti.png").write_bytes(left.read_bytes())
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "disparity.pfm").write_bytes((tmp_path / "ds" / "a_good" /
                                                      "disp0GT.pfm").read_bytes())
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    args = [a.format(l=left, r=right, t=tmp_path) for a in argv]
    code, _, err = _cli(args + (["--disparities", "16"] if argv[0] in ("run", "eval") else []),
                          capfd)
    assert __import__("re").search(message, _one_line_error(code, err)), err
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize("option", ["--html", "--vcd", "--timeline", "--energy", "--gt"])
def test_an_empty_file_option_is_refused(option, tmp_path, capfd, no_work):
    """`--html ''` (an unset shell variable, say) is one line, not silently ignored."""
    left, right = _write_pair(tmp_path / "in")
    code, _, err = _cli(["run", "--left", left, "--right", right, option, "", "--out",
                         tmp_path / "o"], capfd)
    assert f"{option} is empty: give a file name" in _one_line_error(code, err)
    assert not (tmp_path / "o").exists()


def test_a_deeply_nested_toml_value_is_one_line(tmp_path, capfd):
    """3,000 nested arrays (or inline tables) are one line, not a RecursionError traceback."""
    deep = "[" * 3000 + "1" + "]" * 3000
    (tmp_path / "deep.toml").write_text(f"[sva]\np1 = {deep}\n")
    (tmp_path / "plain.toml").write_text("[sva]\np1 = 200\n")
    cases = [
        (["config", "show", "--set", f"sva.p1={deep}"], "the value of sva.p1 nests arrays or "
         "tables too deeply to be read"),
        (["config", "show", "--set", "sva.p1=" + "{a = " * 3000 + "1" + "}" * 3000],
         "the value of sva.p1 nests"),
        (["config", "show", "--config", tmp_path / "deep.toml"], "deep.toml nests arrays or "
         "tables too deeply to be read: flatten them"),
        (["config", "diff", tmp_path / "plain.toml", tmp_path / "deep.toml"], "deep.toml nests"),
    ]
    for argv, message in cases:
        code, out, err = _cli(argv, capfd)
        assert message in _one_line_error(code, err) and out == ""


def test_a_closed_stdout_is_refused_before_any_work(tmp_path):
    """`stereosim estimate --json >&-` is one line, not an AttributeError traceback; `run` says
    so before any work, not after publishing."""
    left, right = _write_pair(tmp_path / "in")
    for argv in (["estimate", "--json"],
                 ["run", "--left", str(left), "--right", str(right), "--disparities", "16",
                  "--out", str(tmp_path / "o")]):
        proc = subprocess.run([sys.executable, "-m", "stereosim", *argv], stderr=subprocess.PIPE,
                              preexec_fn=lambda: os.close(1), timeout=120, check=False)
        assert proc.returncode == 2
        assert proc.stderr.decode().splitlines() == [
            "stereosim: error: standard output is closed: give stereosim one (e.g. > /dev/null)"]
    assert not (tmp_path / "o").exists()


def test_an_unreadable_video_is_one_line(tmp_path, capfd):
    """FFmpeg's own log line does not come out beside ours: its last line is part of ours."""
    (tmp_path / "bad.mp4").write_bytes(bytes(range(256)) * 12)
    code, _, err = _cli(["run", "--left-video", tmp_path / "bad.mp4", "--right-video",
                         tmp_path / "bad.mp4", "--disparities", "16", "--out", tmp_path / "o"],
                        capfd)
    line = _one_line_error(code, err)
    assert "the left video" in line and "cannot be read" in line and "0x" not in line


def test_max_pixels_zero_means_no_cap_in_the_api_as_on_the_command_line():
    left, right = _pair(h=40, w=64)
    result = run(left, right, mode="functional", overrides={"sva.disparities": 16}, max_pixels=0)
    assert result.disparity.shape == (40, 64)
    for bad in (-1, 2.5, True):
        with pytest.raises(InputError, match="max_pixels must be a whole number >= 0"):
            run(left, right, overrides={"sva.disparities": 16}, max_pixels=bad)


# ---------------------------------------------------------------- signals


def test_sigterm_during_start_up_is_one_line(tmp_path):
    """The console entry installs the handler before it imports the command line (numba,
    OpenCV): a SIGTERM while they load ends with the one line, not a silent death."""
    proc = subprocess.Popen([sys.executable, "-m", "stereosim", "config", "show"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.pthread_sigmask(signal.SIG_SETMASK, set()))
    deadline = time.monotonic() + 60
    while not _handles_sigterm(proc.pid):
        assert proc.poll() is None and time.monotonic() < deadline, "no SIGTERM handler"
        time.sleep(0.001)
    with open(f"/proc/{proc.pid}/maps") as f:
        loading = "llvmlite" not in f.read()  # numba's compiler is not loaded yet
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert loading, "the handler came only once the heavy modules were loaded"
    assert (proc.returncode, err.decode(), out) == (143, "stereosim: terminated\n", b"")


def test_a_signal_after_the_outputs_are_written_says_so(old_run, capfd, monkeypatch):
    """A signal once the new set is published exits 130/143 with a line that says the outputs
    are complete (not only "interrupted", and no staging folder left behind)."""
    left, right, out, _ = old_run

    def summary_then_signal(*a, **k):
        os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr("stereosim.sim.cli.print_summary", summary_then_signal)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "32", "--out", out], capfd)
    assert (code, err) == (130, "stereosim: interrupted after writing its outputs (they are "
                                "complete)\n")
    report = json.loads((out / "report.json").read_text())
    assert report["config"]["sva"]["disparities"] == 32
    assert sorted(p.name for p in out.iterdir()) == sorted(RUN_FILES)


class _SigtermWhenFreed:
    """An object whose finalizer sends this process SIGTERM: the handler runs inside it."""

    def __del__(self):
        os.kill(os.getpid(), signal.SIGTERM)


def test_a_signal_raised_inside_a_finalizer_still_ends_the_command(old_run, capfd, monkeypatch):
    """A signal whose exception is raised while Python runs a finalizer (llvmlite frees its
    objects in ``__del__``) cannot propagate there: it ends the command with its one line, no
    "Exception ignored" traceback, and the status of the signal."""
    left, right, out, _ = old_run

    def summary_then_a_finalizer(*a, **k):
        _SigtermWhenFreed()

    monkeypatch.setattr("stereosim.sim.cli.print_summary", summary_then_a_finalizer)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "32", "--out", out], capfd)
    assert (code, err) == (143, "stereosim: terminated after writing its outputs (they are "
                                "complete)\n")
    assert sorted(p.name for p in out.iterdir()) == sorted(RUN_FILES)


def _sigterm_at_instruction(k, function):
    """A trace function that sends this process SIGTERM at the k-th bytecode instruction run in
    frames of ``function`` (a name) once a handler is in; ``k=0`` only counts them. NOPs are
    skipped: Python never runs a signal handler there (a NOP is in no ``try``'s range, so an
    exception raised there by the trace function would skip every handler)."""

    def tracer(frame, event, arg):
        if event == "call":
            if frame.f_code.co_name != function:
                return None
            frame.f_trace_opcodes = True
        elif (event == "opcode" and signals.current() is not None
              and frame.f_code.co_code[frame.f_lasti] != dis.opmap["NOP"]):
            tracer.count += 1
            if tracer.count == k:
                os.kill(os.getpid(), signal.SIGTERM)
        return tracer
    tracer.count = 0
    return tracer


def test_sigterm_at_any_instruction_of_a_file_open_is_one_line(old_run, capfd):
    """core.io.open_file hands a descriptor to a file object; a SIGTERM between the two closed
    it there and again in the file object: "Bad file descriptor", exit 2. At every instruction
    of it, for both input images: the signal's line and status, the old set intact -- or,
    after the last, a finished run."""
    left, right, out, before = old_run
    argv = ["run", "--mode", "functional", "--left", left, "--right", right, "--disparities",
            "16", "--out", out]
    counter = _sigterm_at_instruction(0, "open_file")
    sys.settrace(counter)
    try:
        assert _cli(argv, capfd)[0] == 0
    finally:
        sys.settrace(None)
    finished = _snapshot(out)
    for k in range(1, counter.count + 1):
        sys.settrace(_sigterm_at_instruction(k, "open_file"))
        try:
            code, _, err = _cli(argv, capfd)
        finally:
            sys.settrace(None)
        assert (code, err) == (143, "stereosim: terminated\n"), (k, code, err)
        assert _snapshot(out) in (before, finished), k
    assert counter.count > 20, counter.count  # the two opens were walked through


def test_sigterm_at_any_instruction_of_an_atomic_write_leaves_no_file(tmp_path):
    """A SIGTERM just after the temporary file's creation, before the code that removes it on
    failure knew its name, left ``.out.bin.XXXX.tmp`` behind. At every instruction of
    core.outputs.atomic_write_bytes: the signal stops it, and the folder holds the whole new
    file or nothing."""
    out = tmp_path / "out.bin"
    data = bytes(range(256)) * 64

    def write(tracer):
        out.unlink(missing_ok=True)
        with signals.handling():
            sys.settrace(tracer)
            try:
                outputs.atomic_write_bytes(out, data)
                return "written"
            except signals.Terminated:
                return "terminated"
            finally:
                sys.settrace(None)

    counter = _sigterm_at_instruction(0, "atomic_write_bytes")
    assert write(counter) == "written"
    outcomes = set()
    for k in range(1, counter.count + 1):
        outcomes.add(write(_sigterm_at_instruction(k, "atomic_write_bytes")))
        assert [p.name for p in tmp_path.iterdir()] in ([], ["out.bin"]), k
        assert not out.exists() or out.read_bytes() == data, k
    assert "terminated" in outcomes and counter.count > 20, (outcomes, counter.count)


def test_what_fails_after_a_signal_cut_a_callback_short_is_the_signal(old_run, capfd,
                                                                     monkeypatch):
    """A signal raised inside a finalizer or a C callback cannot propagate, and the code it cut
    short may leave the work broken: numba, when LLVM's callback that hands it the compiled
    object was cut, raised "no compiled object yet" (CI: a traceback and exit 1). The failure
    that follows is the signal's: its line and status, the old set intact."""
    left, right, out, before = old_run

    def cut_short(*a, **k):
        _SigtermWhenFreed()
        raise RuntimeError("no compiled object yet")  # what numba then said

    monkeypatch.setattr("stereosim.sim.cli.html_files", cut_short)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "32", "--out", out], capfd)
    assert (code, err) == (143, "stereosim: terminated\n")
    assert _snapshot(out) == before


def test_a_finalizer_that_fails_once_a_signal_stops_the_command_prints_nothing(old_run, capfd,
                                                                             monkeypatch):
    """Objects left half made by the work a signal cut short fail as they are freed (llvmlite's
    after an interrupted compile: "Exception ignored in ObjectRef.__del__" and a traceback
    after the signal's line); once a signal stops the command, the signal's line is all."""
    left, right, out, before = old_run

    class HalfMade:
        def __del__(self):
            raise RuntimeError("freed half made")

    def cut_short(*a, **k):
        half = HalfMade()  # freed with this frame, once the signal's exception is handled
        os.kill(os.getpid(), signal.SIGTERM)
        return half

    monkeypatch.setattr("stereosim.sim.cli.html_files", cut_short)
    # Python's own hook, which prints to stderr (pytest's turns the failure into a warning)
    monkeypatch.setattr(sys, "unraisablehook", sys.__unraisablehook__)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "32", "--out", out], capfd)
    assert (code, err) == (143, "stereosim: terminated\n")
    assert _snapshot(out) == before


# A process's entry, then an object freed in the interpreter's last stretch of shutdown (a
# module global: after Python put the signals' default actions back, as numba's and llvmlite's
# objects are freed), whose finalizer does {late}.
_SHUTDOWN = """
import os, signal, sys
from stereosim.core import signals

class Late:
    def __del__(self):
        {late}
        sum(range(1000))  # bytecodes in which a Python handler would run

late = Late()

def command():
    {command}
    return 0

sys.exit(signals.entry(command))
"""


@pytest.mark.parametrize("command", ["pass", "os.kill(os.getpid(), signal.SIGTERM)"])
def test_a_signal_during_the_interpreters_shutdown_changes_nothing(command):
    """A SIGTERM while the interpreter shuts down -- the command's outcome decided, whether it
    finished or a signal stopped it -- once killed the process (no status, no line); the
    process exits with its status and its one line, or none."""
    code = _SHUTDOWN.format(late="os.kill(os.getpid(), signal.SIGTERM)", command=command)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    want = (0, b"") if command == "pass" else (143, b"stereosim: terminated\n")
    assert (proc.returncode, proc.stderr) == want


def test_a_finalizer_that_fails_during_the_shutdown_after_a_signal_prints_nothing():
    """After a signal stopped the command, an object left half made that fails as the
    interpreter frees it in its last stretch ("Exception ignored in ... __del__", seen under
    load once numba's compile was cut) prints nothing: the signal's line is all."""
    code = _SHUTDOWN.format(late="raise RuntimeError('freed half made')",
                            command="os.kill(os.getpid(), signal.SIGTERM)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    assert (proc.returncode, proc.stderr) == (143, b"stereosim: terminated\n")


def test_a_signal_after_the_outcome_is_decided_changes_nothing(tmp_path, capfd, monkeypatch):
    """Once main knows its outcome (a status, or a one-line error) a signal no longer cuts it
    short: no traceback, no second line, no other status."""
    real = signals.Handler.settle

    def settle_then_signal(self):
        real(self)
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(signals.Handler, "settle", settle_then_signal)
    assert _cli(["config", "show", "--plain"], capfd)[0] == 0
    code, _, err = _cli(["config", "show", "--set", "sva.pathz=2"], capfd)
    assert "unknown config key 'sva.pathz'" in _one_line_error(code, err)
    assert signals.current() is None  # the caller's handlers are back


@pytest.mark.parametrize("argv, message", [
    (["train", "--box", "999"], "'999' is not a window the chip's box filter has: give an odd "
     "K in 1..15 (sva.box_size's range)"),
    (["train", "--aggregate", "17"], "give an odd K in 1..15"),
])
def test_train_windows_are_bounded_by_the_chips_box_filter(argv, message, capfd, tmp_path,
                                                           monkeypatch):
    """`train --box 999` was accepted (77 s a step)."""
    monkeypatch.chdir(tmp_path)
    code, _, err = _cli(argv, capfd)
    assert message in _one_line_error(code, err)


def test_sighup_before_the_switch_leaves_the_old_set(old_run, capfd, monkeypatch):
    left, right, out, before = old_run

    def hang_up(*a, **k):
        os.kill(os.getpid(), signal.SIGHUP)

    monkeypatch.setattr("stereosim.sim.cli.html_files", hang_up)
    code, _, err = _cli(["run", "--mode", "functional", "--left", left, "--right", right,
                         "--disparities", "32", "--out", out], capfd)
    assert (code, err) == (129, "stereosim: hung up\n")
    assert _snapshot(out) == before



@contextlib.contextmanager
def _as_a_process():
    """Run a process's entry in this process: the entry installs its handler for the rest of
    the process, so the handlers, the unraisable hook and the trace function are put back."""
    previous = {signum: signal.getsignal(signum) for signum in signals.HELD}
    hook = sys.unraisablehook
    for signum in signals.HELD:  # as a new Python process has them
        signal.signal(signum, signal.default_int_handler if signum == signal.SIGINT
                      else signal.SIG_DFL)
    try:
        yield
    finally:
        sys.settrace(None)
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        sys.unraisablehook = hook


def _run_entry(module, argv, monkeypatch, tracer):
    """``python -m module argv...`` in this process, traced by ``tracer``: its exit status, or
    the signal's exception that escaped it (the process would print a traceback, exit 1)."""
    monkeypatch.setattr(sys, "argv", [module, *argv])
    with _as_a_process():
        try:
            sys.settrace(tracer)
            runpy.run_module(module, run_name="__main__", alter_sys=False)
        except SystemExit as stop:
            return stop.code
        except KeyboardInterrupt as exc:
            return f"escaped: {exc!r}"
    return "no exit"


def _sigterm_at_call(k):
    """A trace function that sends this process SIGTERM at the k-th Python call made once the
    handler is in (a real signal: the handler raises wherever Python runs it next); ``k=0``
    only counts them (``tracer.calls``)."""

    def tracer(frame, event, arg):
        if event == "call" and signals.current() is not None:
            tracer.calls += 1
            if tracer.calls == k:
                os.kill(os.getpid(), signal.SIGTERM)
        return None
    tracer.calls = 0
    return tracer


@pytest.mark.filterwarnings("ignore:.*found in sys.modules:RuntimeWarning")
@pytest.mark.parametrize("module", ["stereosim", "stereosim.sim.cli"])
def test_sigterm_the_moment_the_handler_is_in_is_one_line(module, capfd, monkeypatch):
    """A SIGTERM at any Python call after the handler goes in -- the first ones run before the
    command's own ``try``: CI once got a traceback and exit 1 there -- ends with the one line
    and 143, or (once the outcome is decided) changes nothing: 0 and no line."""
    argv = ["config", "show", "--plain"]
    counter = _sigterm_at_call(0)
    assert _run_entry(module, argv, monkeypatch, counter) == 0
    capfd.readouterr()
    outcomes = []
    # every one of the first calls (the start: install, the command's try), then a sample
    for k in sorted({*range(1, 121), *np.linspace(121, counter.calls, 40).astype(int)}):
        code = _run_entry(module, argv, monkeypatch, _sigterm_at_call(k))
        err = capfd.readouterr().err
        assert (code, err) in {(143, "stereosim: terminated\n"), (0, "")}, (k, code, err)
        outcomes.append(code)
    assert outcomes[0] == 143 and outcomes[-1] == 0, counter.calls  # both sides seen
