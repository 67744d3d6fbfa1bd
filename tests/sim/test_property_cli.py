"""Property: whatever the command line, stereosim ends in exactly one of two ways.

Hypothesis builds argv from a grammar of real and broken options and files (good and corrupt
images, ground truth, masks, configurations, scene folders; output folders that are fresh, hold
an earlier run, are files, or have names too long; trace paths that collide or are folders;
non-finite numbers). The outcome must be either

* exit 0 with a complete output set (the three files, the report's SHA-256 manifest matching
  them, every requested trace file) and nothing on stderr, or
* exit 2 with exactly one line on stderr and every earlier output left byte for byte as it was,

never anything else (another status, a traceback, an exception out of ``main``, a stray
temporary file). STEREOSIM_PROPERTY_EXAMPLES sets the number of examples.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from stereosim.core.io import encode_png, pfm_bytes
from stereosim.core.progress import COMPILE_MESSAGE
from stereosim.sim.cli import main

EXAMPLES = int(os.environ.get("STEREOSIM_PROPERTY_EXAMPLES", "40"))
RUN_FILES = ("disparity.pfm", "disparity.png", "report.json")
H, W = 16, 44


def _said(stderr: str) -> str:
    """stderr without the compile notice's two lines, which a run prints when it is the
    first of its process to compile a kernel (which one is, depends on the test order)."""
    return "".join(line for line in stderr.splitlines(keepends=True)
                   if line.rstrip("\n") != COMPILE_MESSAGE
                   and not line.startswith("stereosim: compiling took "))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Every input file the grammar may name, made once."""
    root = tmp_path_factory.mktemp("inputs")
    rng = np.random.default_rng(4)
    base = rng.integers(0, 256, (H, W + 4), dtype=np.uint8)
    left, right = base[:, 4:].copy(), base[:, :-4].copy()
    put = {
        "l.png": encode_png(left), "r.png": encode_png(right),
        "rgb.png": encode_png(np.dstack([left] * 3)),
        "narrow.png": encode_png(right[:, :-6].copy()),
        "wide16.png": encode_png(left.astype(np.uint16) * 257),
        "corrupt.png": encode_png(left)[:40], "empty.png": b"",
        "text.png": b"not an image\n",
        "gt.pfm": pfm_bytes(np.full((H, W), 4.0, np.float32)),
        "gt_nan.pfm": pfm_bytes(np.full((H, W), np.inf, np.float32)),
        "gt_neg.pfm": pfm_bytes(np.full((H, W), -2.0, np.float32)),
        "gt_small.pfm": pfm_bytes(np.full((H - 1, W), 4.0, np.float32)),
        "gt_bad.pfm": b"Pf\n44 16\nxx\n",
        "mask.png": encode_png(np.full((H, W), 255, np.uint8)),
        "mask_small.png": encode_png(np.full((H, W - 1), 255, np.uint8)),
        "good.toml": b"[sva]\npaths = 2\n", "bad.toml": b"[sva]\npathz = 2\n",
        "broken.toml": b"[sva\n", "binary.toml": b"\xff\xfe\x00\x01",
    }
    for name, data in put.items():
        (root / name).write_bytes(data)
    (root / "adir").mkdir()
    scene = root / "scene"
    scene.mkdir()
    shutil.copy(root / "l.png", scene / "im0.png")
    shutil.copy(root / "r.png", scene / "im1.png")
    shutil.copy(root / "gt.pfm", scene / "disp0GT.pfm")
    (scene / "calib.txt").write_text("ndisp=20\n")
    (root / "notscene").mkdir()
    old = root / "old"
    assert main(["run", "--mode", "functional", "--left", str(root / "l.png"), "--right",
                 str(root / "r.png"), "--disparities", "16", "--out", str(old)]) == 0
    return root


IMAGE_NAMES = ["l.png", "r.png", "rgb.png", "narrow.png", "wide16.png", "corrupt.png", "empty.png",
               "text.png", "missing.png", "adir"]


FAULTS = ("inputs", "left", "right", "disparities", "set", "config", "gt", "scale", "mask",
          "out", "vcd", "timeline", "window", "limit", "trace-alone", "mode", "pixels")


@st.composite
def run_argv(draw):
    """(argv template with {in} / {out} / {work} placeholders, which trace files it names).

    Each example picks up to two faults; every other option is drawn from its good values
    (which include leaving it out), so about a third of the examples are runs that work."""
    faults = draw(st.sets(st.sampled_from(FAULTS), max_size=2))

    def opt(name, good, bad):
        return draw(st.sampled_from(bad if name in faults else good))

    argv = ["run"]
    inputs = opt("inputs", ["pair"], ["scene", "notscene", "left-only", "scene+left"])
    if inputs in ("pair", "left-only", "scene+left"):
        argv += ["--left", "{in}/" + opt("left", ["l.png", "rgb.png"], IMAGE_NAMES)]
    if inputs == "pair":
        argv += ["--right", "{in}/" + opt("right", ["r.png"], IMAGE_NAMES)]
    if inputs in ("scene", "scene+left"):
        argv += ["{in}/scene"]
    if inputs == "notscene":
        argv += ["{in}/notscene"]
    tracing = draw(st.booleans())
    mode = opt("mode", ["cycle"] if tracing else ["functional", "cycle"],
               ["functional" if tracing else "cycle", "fast", ""])
    argv += ["--mode", mode]
    d = opt("disparities", ["16", "32"], [None, "17", "0", "-16", "256", "x"])  # None: 128
    if d is not None:
        argv += ["--disparities", d]
    good_sets = [[], ["sva.paths=2"], ["sva.median=0"], ["nna.descriptor=census"],
                 ["sva.lr_check=false", "sva.subpixel=off"], ["fifo.nna_to_sva_depth=1"],
                 ["nna.stereo_submodules=4"], ["source.kind=camera"],
                 ["nna.stereo_submodules=4", "nna.split=rows"]]
    bad_sets = [["sva.paths=9"], ["sva.nope=1"], ["clocks.nna_mhz=nan"], ["novalue"],
                ["sva.box_size=4"], ["fifo.nna_to_sva_depth=0"], ["sim.watchdog_cycles=0"],
                ["nna.cnn.weights=x.npz"], ["sva=1"], ["clocks.sva_mhz=-inf"]]
    for item in opt("set", good_sets, bad_sets):
        argv += ["--set", item]
    config = opt("config", [None, "good.toml"], ["bad.toml", "broken.toml", "binary.toml",
                                                 "adir", "missing.toml"])
    if config:
        argv += ["--config", "{in}/" + config]
    gt = opt("gt", [None, "gt.pfm", "gt_nan.pfm"], ["gt_neg.pfm", "gt_small.pfm", "gt_bad.pfm",
                                                    "missing.pfm", "l.png"])
    if gt:
        argv += ["--gt", "{in}/" + gt]
    scale = opt("scale", [None, "1"] if gt else [None], ["nan", "-1", "0", "inf"])
    if scale:
        argv += ["--gt-scale", scale]
    mask = opt("mask", [None], ["mask.png", "mask_small.png", "corrupt.png"])
    if mask:
        argv += ["--mask", "{in}/" + mask]
    argv += ["--out", opt("out", ["{out}", "{work}/fresh", "{work}/new/deeper"],
                          ["{in}/l.png", "{work}/" + "n" * 300, "{in}/l.png/sub", ""])]
    traces = []
    if tracing:
        vcd = opt("vcd", ["{work}/t.vcd", "{out}/t.vcd"],
                  ["{in}/adir", "{out}/report.json", "{work}/t.json", "{out}/disparity.png"])
        argv += ["--vcd", vcd]
        traces += [vcd, vcd[:-4] + ".gtkw" if vcd.endswith(".vcd") else None]
        timeline = opt("timeline", [None, "{work}/t.json"], ["{work}/t.vcd", "{work}/t.gtkw",
                                                             "{in}/adir"])
        if timeline:
            argv += ["--timeline", timeline]
            traces.append(timeline)
        window = opt("window", ["0:500", "rows:0:2", "nna:0:300"],
                     ["x", "5:1", "camera:0:10", "rows:0:99", "0:1", "99999999:"])
        argv += ["--trace-window", window]
        limit = opt("limit", [None, "50"], ["0", "nan", "0.0001", "inf", "-3"])
        if limit:
            argv += ["--trace-limit", limit]
        if draw(st.booleans()):
            argv += ["--force"]
    elif "trace-alone" in faults:
        argv += [draw(st.sampled_from(["--force", "--trace-window", "--trace"]))]
    if draw(st.booleans()):
        argv += ["--json"]
    pixels = opt("pixels", [None, "0"], ["100", "-1", "many"])
    if pixels:
        argv += ["--max-pixels", pixels]
    return argv, [t for t in traces if t]


@contextlib.contextmanager
def _inside(folder: Path):
    """Run with ``folder`` as the working directory (hypothesis examples cannot use
    monkeypatch.chdir)."""
    old = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(old)


def _snapshot(folder: Path) -> dict:
    if not folder.exists():
        return {}
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None
            for p in sorted(folder.rglob("*"))}


@settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES <= 100,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(case=run_argv())
def test_run_ends_whole_or_in_one_line(case, files, capfd):
    template, traces = case
    work = Path(tempfile.mkdtemp(dir=files.parent))
    out = work / "out"
    shutil.copytree(files / "old", out)
    subst = {"{in}": str(files), "{out}": str(out), "{work}": str(work)}

    def fill(text):
        for key, value in subst.items():
            text = text.replace(key, value)
        return text

    argv = [fill(a) for a in template]
    before_work = _snapshot(work)
    before_inputs = _snapshot(files)
    with _inside(work):  # a relative path never writes into the repository
        code = main(argv)
    stdout, stderr = capfd.readouterr()
    assert _snapshot(files) == before_inputs, "an input file changed"
    assert not [p for p in work.rglob("*") if ".stereosim-stage-" in str(p) or
                str(p).endswith(".tmp")], "a temporary file was left"
    if code == 2:
        lines = _said(stderr).splitlines()
        assert len(lines) == 1 and lines[0].startswith("stereosim: error: "), stderr
        assert "out of memory" not in lines[0], argv  # inputs of a few hundred pixels
        event("exit 2: " + " ".join(lines[0].split()[2:5]))
        assert _snapshot(work) == before_work, f"a failed run changed the outputs: {argv}"
        return
    assert code == 0, (code, stderr)
    event("exit 0")
    assert _said(stderr) == ""
    dest = Path(argv[argv.index("--out") + 1])
    report = json.loads((dest / "report.json").read_text(), parse_constant=_strict)
    for name, digest in report["files"].items():
        assert hashlib.sha256((dest / name).read_bytes()).hexdigest() == digest, name
    for name in RUN_FILES:
        assert (dest / name).is_file()
    for t in traces:
        assert Path(fill(t)).is_file(), t
    if "--json" in argv:
        assert json.loads(stdout, parse_constant=_strict) == report


def _strict(name):
    raise AssertionError(f"bare {name} in JSON")


@st.composite
def other_argv(draw):
    """config show / config plan / estimate / eval with real and broken options."""
    command = draw(st.sampled_from([["config", "show"], ["config", "plan"], ["estimate"],
                                    ["eval", "{in}"], ["eval", "{in}/scene"], ["eval", "{work}"],
                                    ["config", "diff", "{in}/good.toml", "{in}/bad.toml"]]))
    argv = list(command)
    if command[0] != "config" or command[1] != "diff":
        for item in draw(st.lists(st.sampled_from(["sva.paths=2", "sva.paths=0",
                                                   "clocks.sva_mhz=inf", "x=1", "sva=1"]),
                                  max_size=2)):
            argv += ["--set", item]
        config = draw(st.sampled_from([None, "good.toml", "bad.toml", "broken.toml", "adir"]))
        if config:
            argv += ["--config", "{in}/" + config]
    if command[0] == "eval" and draw(st.booleans()):
        argv += ["--out", draw(st.sampled_from(["{work}/ev.json", "{in}/adir"]))]
    if command[:2] == ["config", "plan"] and draw(st.booleans()):
        argv += ["--png", draw(st.sampled_from(["{work}/p.png", "{in}/adir"]))]
    if command[0] in ("estimate", "config") and draw(st.booleans()) and command[1:2] != ["diff"]:
        if command[0] == "estimate" or command[1] == "plan":
            argv += ["--size", draw(st.sampled_from(["640x480", "0x0", "axb", "64x8"]))]
    return argv


@settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES <= 100,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(template=other_argv())
def test_other_commands_end_in_zero_or_one_line(template, files, capfd):
    work = Path(tempfile.mkdtemp(dir=files.parent))
    argv = [a.replace("{in}", str(files)).replace("{work}", str(work)) for a in template]
    before = _snapshot(files)
    with _inside(work):
        code = main(argv)
    _, stderr = capfd.readouterr()
    assert _snapshot(files) == before
    if code == 2:
        lines = [ln for ln in stderr.splitlines() if ln.startswith("stereosim: error: ")]
        assert len(lines) == 1, stderr
        assert lines == [ln for ln in stderr.splitlines() if "eval:" not in ln], stderr
        return
    assert code == 0, (code, stderr)
