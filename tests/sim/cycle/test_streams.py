"""Streams of frames: frames back to back through the chip, overlapping in the
pipeline as the blocks allow, in both engines -- every frame's words equal the functional
model's for that frame, and the cycles follow the formulas written out here by hand."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from stereosim.core import progress
from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.io import encode_png, pfm_bytes
from stereosim.nna.descriptor import compute_descriptor
from stereosim.sim import api
from stereosim.sim.api import run, run_stream
from stereosim.sim.cli import main
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.frames import MAX_FRAMES, FrameSupply, check_frame_count
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable
from stereosim.sva.pipeline.pipeline import sva_stream

# census (1 NNA cycle per descriptor), equal clocks: the worked example of docs/architecture.md
# (row 0 of the first frame ready at 6W + 3, its first word popped at 6W + 4 + L)
# the 3x3 median and 5x5 box of tests/sim/cycle/readable/test_chip.py's derivation (first output
# at 6W + 4 + L)
SAME = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "nna.descriptor": "census",
        "sva.disparities": 16, "sva.median": 3, "sva.box_size": 5}
ENGINES = [run_readable, run_compiled]


def _stream(n, h, w, seed=0):
    """n different pairs (the right view the left shifted by 2 plus noise)."""
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (n, h, w + 2), dtype=np.uint8)
    right = np.clip(left[:, :, 2:].astype(int) + rng.integers(-3, 4, (n, h, w)), 0, 255)
    return left[:, :, :w].copy(), right.astype(np.uint8)


def _functional(left, right, plan):
    cfg = plan.cfg
    return sva_stream(compute_descriptor(left, cfg.nna), compute_descriptor(right, cfg.nna), left,
                      cfg.sva, plan.descriptor_bits)


@pytest.mark.parametrize("run", ENGINES)
def test_every_frame_of_a_stream_is_the_functional_models(run):
    cfg = load_config(overrides={**SAME, "nna.descriptor": "cnn"})
    left, right = _stream(3, 12, 40, seed=1)
    got = {}
    plan = build_plan(cfg, (12, 40), 3)
    frame = run(plan, left, right, on_frame=lambda f, words: got.__setitem__(f, words.copy()))
    assert sorted(got) == [0, 1, 2]
    for f in range(3):
        np.testing.assert_array_equal(got[f], _functional(left[f], right[f], plan))
    np.testing.assert_array_equal(frame.words, got[2])
    assert not np.array_equal(got[0], got[1])  # the frames differ, and so do their words


@pytest.mark.parametrize("run", ENGINES)
def test_an_sva_bound_stream_leaves_a_word_every_ii_across_frames(run):
    """The SVA (II 2, slot II 1; box 5: r = 2, 4 passes; 3x3 median: S = W + 1) is the
    bottleneck and the rows of the next frame are ready before it needs them (its row buffers
    take the next frame's first r + 2 rows while this one's last rows are issued, and rows
    r + 2 .. 2r + 2 once it is issued), so the frames follow one SVA frame apart:
    P = H (W - 1) II + (H - 1) max(II, r + 1) + max(II, r + 1 + S + 4W) ticks
    (``sva_frame_ticks``: a row's words, a row's start, the frame's start). Frame 0's words
    leave as in tests/sim/cycle/readable/test_chip.py::test_census_first_and_last_output_cycles
    (first 9W + 9 + L, last 10W + 5 + (H - 1)(2W + 1) + L), frame f's last P f cycles after frame
    0's, and the stream sustains clock / P frames per second."""
    h, w, frames = 7, 40, 3
    plan = build_plan(load_config(overrides=SAME), (h, w), frames)
    lat, ii = plan.block("sva").latency, plan.block("sva").ii
    assert (ii, plan.block("sva").slot_ii) == (2, 1)
    left, right = _stream(frames, h, w, seed=2)
    rep = run(plan, left, right).report
    p = h * (w - 1) * ii + (h - 1) * max(ii, 3) + max(ii, 3 + w + 1 + 4 * w)
    first, last0 = 9 * w + 9 + lat, 10 * w + 5 + (h - 1) * (2 * w + 1) + lat
    assert rep["cycles"]["first_output"]["sva"] == first
    assert rep["cycles"]["last_output"]["sva"] == last0 + p * (frames - 1)
    period = plan.domains["sva"].period_fs
    ends = [(last0 + p * f) * period for f in range(frames)]
    stream = rep["stream"]
    assert stream["frames_completed"] == frames
    assert stream["sustained_fps"] == round((frames - 1) / ((ends[-1] - ends[0]) / 1e15), 3)
    assert stream["sustained_fps"] == round(400e6 / p, 3)


@pytest.mark.parametrize("run", ENGINES)
def test_a_slow_source_paces_the_frames_and_every_frame_takes_as_long(run):
    """A memory source at a quarter of a byte per cycle (0.1 GB/s at 400 MHz) sends pixel k in
    cycle 4k + 3 (its token bucket), frame after frame: everything downstream keeps up, so every
    event of frame f is frame 0's, 4 H W cycles later -- the same latency for every frame."""
    h, w, frames = 6, 36, 3
    over = {**SAME, "source.memory_gbps": 0.1}
    plan = build_plan(load_config(overrides=over), (h, w), frames)
    left, right = _stream(frames, h, w, seed=3)
    res = run(plan, left, right)
    first_in, last_out, _ = res.frame_times
    period = plan.domains["nna"].period_fs
    for f in range(frames):
        assert first_in[f] == (4 * f * h * w + 3) * period
        assert last_out[f] - last_out[0] == 4 * f * h * w * period
    lat = res.report["stream"]["latency_ms"]
    assert lat["min"] == lat["max"] == lat["median"]
    assert res.report["stream"]["sustained_fps"] == round(400e6 / (4 * h * w), 3)


@pytest.mark.parametrize("run", ENGINES)
def test_a_camera_stream_keeps_its_frame_period_with_blanking(run):
    """A camera at the chip's clock with horizontal and vertical blanking delivers frame f's
    pixel (x, y) in cycle f (H + vblank)(W + hblank) + y (W + hblank) + x; the census chip
    keeps up, so frame f leaves exactly f frame periods after frame 0."""
    h, w, frames = 6, 40, 3
    over = {**SAME, "source.kind": "camera", "clocks.camera_mhz": 400,
            "source.camera_hblank": 50, "source.camera_vblank": 3}
    plan = build_plan(load_config(overrides=over), (h, w), frames)
    cam = plan.block("camera_left")
    assert cam.frame_clocks == (h + 3) * (w + 50)
    left, right = _stream(frames, h, w, seed=4)
    res = run(plan, left, right)
    first_in, last_out, _ = res.frame_times
    per = plan.domains["camera"].period_fs
    for f in range(frames):
        assert first_in[f] == f * cam.frame_clocks * per
        assert last_out[f] - last_out[0] == f * cam.frame_clocks * per
    assert res.report["stream"]["sustained_fps"] == round(400e6 / cam.frame_clocks, 3)
    assert res.report["blocks"]["camera_left"]["busy"] == frames * h * (w + 50)


@pytest.mark.parametrize("over", [
    {"nna.descriptor": "cnn", "fifo.nna_to_sva_depth": 3},
    {"nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 5},
    {"nna.stereo_submodules": 4, "nna.split": "rows", "nna.descriptor": "cnn"},
    {"source.kind": "camera", "clocks.camera_mhz": 100, "source.camera_vblank": 2},
    {"sva.lanes": 8, "fifo.sva_to_sink_depth": 1},
])
def test_the_engines_agree_on_streams(over):
    """Words, report, statistics and frame instants of both engines over 3 frames (splits,
    cameras, slow SVAs and a stalling sink included)."""
    h, w, frames = 11, 40, 3
    plan = build_plan(load_config(overrides={**SAME, **over}), (h, w), frames)
    left, right = _stream(frames, h, w, seed=5)
    stall = (3, 1) if "fifo.sva_to_sink_depth" in over else None
    slow = run_readable(plan, left, right, sink_stall=stall)
    fast = run_compiled(plan, left, right, sink_stall=stall)
    np.testing.assert_array_equal(fast.words, slow.words)
    assert fast.stats == slow.stats
    assert fast.report == slow.report
    np.testing.assert_array_equal(fast.frame_times, slow.frame_times)


def test_a_stream_is_checked():
    cfg = load_config(overrides=SAME)
    with pytest.raises(ConfigError, match="at least one frame"):
        build_plan(cfg, (6, 40), 0)
    left, right = _stream(2, 6, 40)
    with pytest.raises(ConfigError, match="the plan is for 3 frame"):
        run_compiled(build_plan(cfg, (6, 40), 3), left, right)
    bad = FrameSupply(2, (6, 40), lambda f: (left[f], right[f][:, :30]))
    with pytest.raises(InputError, match="frame 0's right image is 30x6"):
        run_compiled(build_plan(cfg, (6, 40), 2), bad)


def test_the_cli_runs_a_stream_with_a_trace_across_frames(tmp_path):
    """stereosim run --frames 3 on the default scene (RGB, made grey): the report's stream, a
    VCD window in the second frame, the saved frames, one set."""
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "stereosim.sim.cli", "run", "--frames", "3",
           "--descriptor", "census", "--disparities", "32", "--save-every", "2",
           "--vcd", str(out / "t.vcd"),
           "--trace-window", "sva:700000:700400", "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "3 of 3 frames completed" in done.stdout and "0 dropped" in done.stdout
    rep = json.loads((out / "report.json").read_text())
    assert rep["stream"]["frames"] == 3 and rep["stream"]["sustained_fps"] > 0
    assert sorted(p.name for p in (out / "frames").iterdir()) == [
        "disparity_00000.pfm", "disparity_00000.png", "disparity_00002.pfm",
        "disparity_00002.png"]
    assert set(rep["files"]) >= {"t.vcd", "frames/disparity_00002.pfm", "disparity.pfm"}
    assert (out / "t.vcd").read_text().count("#") > 100


# ---- accuracy, progress and the length of a stream ---------------------------------------------

TINY = {"nna.descriptor": "census", "sva.disparities": 16}


def _scene(folder, h=24, w=64):
    """A Middlebury 2014 scene folder: a pair shifted by 4 pixels, its GT (4 px, unknown in
    the first columns) and a mask with an occluded band."""
    folder.mkdir(parents=True)
    base = np.random.default_rng(11).integers(0, 256, (h, w + 4), dtype=np.uint8)
    (folder / "im0.png").write_bytes(encode_png(base[:, 4:].copy()))
    (folder / "im1.png").write_bytes(encode_png(base[:, :w].copy()))
    gt = np.full((h, w), 4.0, np.float32)
    gt[:, :6] = np.inf
    (folder / "disp0GT.pfm").write_bytes(pfm_bytes(gt))
    mask = np.full((h, w), 255, np.uint8)
    mask[:, w - 8:] = 128
    (folder / "mask0nocc.png").write_bytes(encode_png(mask))
    return folder


@pytest.mark.parametrize("mode", ["cycle", "functional"])
def test_run_stream_scores_every_frame_against_the_ground_truth(mode):
    """gt= and masks= score each frame as run() scores one; the report gains every frame's
    metrics and their mean once the stream has been iterated."""
    (l0, l1), (r0, r1) = (list(v) for v in _stream(2, 10, 48, seed=6))
    pairs = [(l0, r0), (l1, r1), (l0, r0)]
    gt = np.full((10, 48), 2.0, np.float32)
    gt[:, :3] = np.inf
    masks = {"left": np.arange(48)[None, :].repeat(10, 0) < 24, "all": np.ones((10, 48), bool)}
    stream = run_stream(pairs, mode=mode, overrides=TINY, gt=gt, masks=masks)
    assert "metrics_per_frame" not in stream.report  # known only once the frames are computed
    frames = list(stream)
    cfg = load_config(overrides=TINY)
    for frame, (left, right) in zip(frames, pairs, strict=True):
        alone = run(left, right, mode="functional", config=cfg, gt=gt, masks=masks)
        assert frame.metrics == alone.report["metrics"]
    assert frames[0].metrics == frames[2].metrics != frames[1].metrics
    rep = stream.report
    assert rep["metrics_per_frame"] == [{"frame": f.index, "metrics": f.metrics} for f in frames]
    for mask in masks:
        assert rep["metrics_mean"][mask]["bad2"] == pytest.approx(
            sum(f.metrics[mask]["bad2"] for f in frames) / 3)
    plain = run_stream(pairs[:1], mode=mode, overrides=TINY)
    assert next(iter(plain)).metrics is None and "metrics_mean" not in plain.report


def test_a_streams_ground_truth_is_checked_before_any_kernel_runs(monkeypatch):
    def no_kernel(*args, **kw):
        raise AssertionError("a kernel ran")

    monkeypatch.setattr(api, "simulate", no_kernel)
    left, right = _stream(1, 8, 40)
    pairs = [(left[0], right[0])] * 2
    with pytest.raises(InputError, match="masks need ground truth"):
        run_stream(pairs, overrides=TINY, masks={"all": np.ones((8, 40), bool)})
    with pytest.raises(InputError, match="GT is"):
        run_stream(pairs, overrides=TINY, gt=np.zeros((8, 41), np.float32))


def test_the_cli_scores_a_scene_stream_frame_by_frame(tmp_path, capsys):
    """stereosim run SCENE --frames 3: the scene's GT and mask score every frame (the pair
    repeated: each frame scores as the single frame does), the summary gives the mean."""
    scene = _scene(tmp_path / "S")
    opts = ["--descriptor", "census", "--disparities", "16"]
    assert main(["run", str(scene), *opts, "--out", str(tmp_path / "one"), "--json"]) == 0
    assert main(["run", str(scene), "--frames", "3", *opts, "--out", str(tmp_path / "st")]) == 0
    out = capsys.readouterr().out
    one = json.loads((tmp_path / "one" / "report.json").read_text())
    rep = json.loads((tmp_path / "st" / "report.json").read_text())
    assert set(one["metrics"]) == {"nonocc", "all"}
    assert rep["metrics_per_frame"] == [{"frame": f, "metrics": one["metrics"]} for f in range(3)]
    for mask, m in one["metrics"].items():
        assert rep["metrics_mean"][mask]["bad2"] == pytest.approx(m["bad2"])
    assert "accuracy, mean of 3 frames" in out
    assert main(["run", "--left-video", "l.mp4", "--right-video", "r.mp4", "--gt", "g.pfm",
                 "--out", str(tmp_path / "v")]) == 2
    assert "videos have no ground truth" in capsys.readouterr().err


def test_a_stream_longer_than_the_cap_is_refused_up_front(tmp_path, capsys):
    """More camera frames than MAX_FRAMES is one line and exit status 2, before any frame is
    read (the API) or any file written (the CLI); sva.pairs counts every pair's frames."""
    check_frame_count(MAX_FRAMES)
    check_frame_count(MAX_FRAMES // 2, 2)
    with pytest.raises(InputError, match="2 camera pairs = 100,002 camera frames"):
        check_frame_count(MAX_FRAMES // 2 + 1, 2)
    reads = []

    class Huge:  # a stream of 10^12 frames that counts the frames read
        def __len__(self):
            return 10 ** 12

        def __getitem__(self, f):
            reads.append(f)
            return np.zeros((8, 40), np.uint8), np.zeros((8, 40), np.uint8)

    with pytest.raises(InputError, match=f"above the cap of {MAX_FRAMES:,}"):
        run_stream(Huge(), overrides=TINY)
    assert reads == []
    scene = _scene(tmp_path / "S")
    out = tmp_path / "o"
    assert main(["run", str(scene), "--frames", str(MAX_FRAMES + 1), "--save-every", "1",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{MAX_FRAMES + 1:,} frames, above the cap" in err
    assert not out.exists()


def test_a_stream_shows_progress_on_a_terminal_and_never_in_json(tmp_path, capsys,
                                                                  monkeypatch):
    scene = _scene(tmp_path / "S")
    args = ["run", str(scene), "--frames", "3", "--descriptor", "census", "--disparities",
            "16", "--out", str(tmp_path / "o")]
    assert main(args) == 0
    assert "timing pass" not in capsys.readouterr().err  # captured: not a terminal
    monkeypatch.setattr(progress, "show_progress", lambda quiet=False, stream=None: not quiet)
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "timing pass: 100%" in err and "3/3" in err and "frames: 100%" in err
    assert main([*args, "--json"]) == 0
    captured = capsys.readouterr()
    assert "timing pass" not in captured.err and "frames:" not in captured.err
    assert json.loads(captured.out)["frames"] == 3


def test_a_streams_report_has_the_sections_of_one_frames(tmp_path, lent_toml):
    """A stream's report has the keys of one frame's but the frame's ``output`` and adds
    ``frames`` (docs/report.md, "Keys of a stream"): the lent network's section too."""
    path = lent_toml(tmp_path / "n.toml", [(3, 1, 4, 1)], width=16, height=8)
    over = {**SAME, "nna.lent_submodules": 1, "nna.lent_network": path}
    left, right = _stream(1, 8, 40)
    one = run(left[0], right[0], mode="functional", overrides=over).report
    stream = run_stream([(left[0], right[0])] * 2, mode="functional", overrides=over).report
    assert set(stream) == set(one) - {"output"} | {"frames"}
    assert stream["frames"] == 2 and stream["lent_network"] == one["lent_network"]
