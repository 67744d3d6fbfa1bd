"""The guide to results.csv's columns (sim/columns.py, columns.md beside a sweep's CSV): every
column of every mode described, no rule left describing nothing, clocks read from the rows."""

import re

import numpy as np
import pytest

from stereosim.core.io import encode_png, pfm_bytes
from stereosim.sim.columns import RULES, config_help, describe, guide_text, rule_of
from stereosim.sim.sweep import Task, run_task
from stereosim.sim.sweep_results import CSV_NAME, GUIDE_NAME, finish_results, write_rows

AXES = ["nna.stereo_submodules"]
# the keys the sample's points set besides the axis
FIXED = ["sva.disparities", "source.kind", "source.frame_buffers", "dram.model",
         "nna.lent_submodules", "nna.lent_network", "nna.descriptor", "sva.weight_mode"]


def _scene(root):
    """A scene folder with GT and a non-occlusion mask (so both masks are scored)."""
    root.mkdir()
    rng = np.random.default_rng(5)
    left = rng.integers(0, 256, (24, 64), dtype=np.uint8)
    (root / "im0.png").write_bytes(encode_png(left))
    (root / "im1.png").write_bytes(encode_png(np.roll(left, -4, axis=1)))
    (root / "disp0GT.pfm").write_bytes(pfm_bytes(np.full((24, 64), 4.0, np.float32)))
    mask = np.full((24, 64), 255, np.uint8)
    mask[:, :6] = 128
    (root / "mask0nocc.png").write_bytes(encode_png(mask))
    return root


@pytest.fixture(scope="module")
def sample(tmp_path_factory, lent_toml):
    """Rows of every kind a sweep writes -- cycle (column tiles; a camera; a camera behind
    frame buffers and the DRAM channel; a lent network beside the DRAM channel), functional
    with GT (and the hybrid descriptor's, with automatic weights), estimate (tiles, a camera;
    a lent network without a channel) -- as results.csv
    and its guide."""
    tmp = tmp_path_factory.mktemp("columns")
    scene = str(_scene(tmp / "scene"))
    lent = {"nna.lent_submodules": 2, "nna.lent_network": lent_toml(
        tmp / "lent.toml", [(3, 1, 8, 1), (3, 8, 8, 2)])}
    runs = [
        ("cycle", "64x24", {"nna.stereo_submodules": 4}),
        ("cycle", "64x24", {"nna.stereo_submodules": 4, "source.kind": "camera"}),
        ("cycle", "64x24", {"nna.stereo_submodules": 6, "source.kind": "camera",
                            "source.frame_buffers": 2, "dram.model": "tdm"}),
        ("cycle", "64x24", {"nna.stereo_submodules": 2, "dram.model": "tdm", **lent}),
        ("functional", scene, {"nna.stereo_submodules": 2}),
        ("functional", scene, {"nna.stereo_submodules": 2, "nna.descriptor": "hybrid",
                               "sva.weight_mode": "auto"}),
        ("estimate", "64x24", {"nna.stereo_submodules": 4, "source.kind": "camera"}),
        ("estimate", "64x24", {"nna.stereo_submodules": 2, **lent}),
    ]
    tasks = [Task(i, i, spec, spec, {"sva.disparities": 16, **over}, None, mode)
             for i, (mode, spec, over) in enumerate(runs)]
    rows = [run_task(t) for t in tasks]
    assert [r["error"] for r in rows] == [""] * len(rows)
    path = tmp / CSV_NAME
    write_rows(path, rows, AXES)
    finish_results(path, tasks, AXES)
    header = path.read_text().splitlines()[0].split(",")
    return header, rows, (tmp / GUIDE_NAME).read_text()


def test_every_column_is_described_and_every_rule_describes_one(sample):
    header, _, _ = sample
    undescribed = [c for c in header if describe(c, AXES, FIXED)[0] == "not described"]
    assert undescribed == []
    used = {rule_of(c) for c in header} | {rule_of(c[9:]) for c in header
                                           if c.startswith("estimate.")}
    assert [p for p, _, _ in RULES if p not in used] == []


def test_a_lent_networks_columns_are_described(sample):
    """Every column of the report's lent_network section (sim.cycle.lent.lent_report),
    flattened, with and without a DRAM channel, in its own group of the guide."""
    header, _, guide = sample
    lent = [c for c in header if c.startswith("lent_network.")]
    assert {"lent_network.fps", "lent_network.layers", "lent_network.stereo_pair.note",
            "lent_network.stereo_pair.read_bound_fps"} <= set(lent)
    assert [c for c in lent if describe(c, AXES, FIXED)[0] != "lent network"] == []
    assert f"## lent network ({len(lent)})" in guide


def test_the_guide_beside_the_csv_lists_each_column_once(sample):
    header, _, guide = sample
    listed = re.findall(r"^\| `([^`]+)` \|", guide, re.MULTILINE)
    assert sorted(listed) == sorted(header) and len(set(header)) == len(header)
    assert f"its {len(header)} columns" in guide
    assert "not described" not in guide


def test_rates_say_bound_or_measured_and_counts_their_clock(sample):
    guide = sample[2]

    def text(col):
        line = next(ln for ln in guide.splitlines() if ln.startswith(f"| `{col}` |"))
        return line

    assert "**work bound**" in text("throughput.fps_bound")
    assert "**measured**" in text("throughput.fps_measured")
    assert "work bound" in text("estimate.throughput.fps_bound")
    assert "work bound" in text("dram.read_bound_fps")
    # the clock of a block or FIFO end comes from the rows themselves
    assert "the nna clock (460 MHz)" in text("blocks.nna_left0.busy")
    assert "the camera clock (74.25 MHz)" in text("blocks.camera_left.idle")
    assert "the nna clock (460 MHz)" in text("fifos.src_left_to_nna0.cycles_empty")
    # a camera feeds it in one point, a memory source (nna clock) in the others
    assert ("its clock (the camera clock (74.25 MHz) or the nna clock (460 MHz), as "
            "fifos.src_left_to_nna0.producer_domain says)") in text(
        "fifos.src_left_to_nna0.cycles_full")
    assert "% of the evaluated pixels wrong by more than 2 px" in text("metrics.nonocc.bad2")
    # configuration keys carry the help they are declared with
    assert config_help()["sva.paths"] in text("config.sva.paths")
    assert text("nna.stereo_submodules").startswith(
        f"| `nna.stereo_submodules` | swept: {config_help()['nna.stereo_submodules']}")


def test_a_column_no_rule_knows_is_listed_as_not_described():
    guide = guide_text(["point", "throughput.fps_teleported"], [])
    assert "## not described (1)" in guide and "`throughput.fps_teleported`" in guide
