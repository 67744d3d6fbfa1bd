"""The chip plan drawn (sim/diagram.py, `stereosim config plan`): read off the plan, current in
docs/architecture.md, deterministic, bad input refused with one line."""

import re
from pathlib import Path

import pytest

from stereosim.core.config import load_config
from stereosim.sim.cli import main
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.figures import chip_sram
from stereosim.sim.cycle.lent import lent_report
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.diagram import MAX_DRAWN, _span, picture_layout, plan_png, plan_text
from stereosim.sim.summary import energy_lines

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"


def test_the_listing_in_the_architecture_page_is_current():
    block = re.search(r"<!-- plan:begin -->\n```\n(.*?)```\n<!-- plan:end -->",
                      DOC.read_text(encoding="utf-8"), re.S)
    assert block, "docs/architecture.md lost its plan:begin / plan:end markers"
    want = plan_text(build_plan(load_config(), (720, 1280)))
    assert block.group(1) == want, "stale: run python docs/make_plan_pictures.py"


def test_the_listing_is_read_off_the_plan():
    cfg = load_config(overrides={"nna.stereo_submodules": 6, "fifo.nna_to_merge_depth": 7,
                                 "source.kind": "camera", "sva.disparities": 64})
    plan = build_plan(cfg, (90, 200))
    text = plan_text(plan)
    for f in plan.fifos:
        line = (f"  {f.producer} --{f.name}--> {f.consumer}: {f.depth} x {f.width_bits} bits, "
                f"{f.key};")
        assert line in text
    merge = [f for f in plan.fifos if plan.block(f.consumer).kind == "merge"]
    assert len(merge) == 6 and all(f.depth == 7 for f in merge)
    for b in plan.blocks:
        assert f"  {b.name:<14} [{b.domain}] {b.kind};" in text
    for d in plan.domains.values():
        assert re.search(rf"^  {d.name} +{d.freq_hz / 1e6:.3f} MHz", text, re.M)


def test_the_picture_is_a_deterministic_png():
    plan = build_plan(load_config(overrides={"nna.stereo_submodules": 4, "sva.disparities": 32}),
                      (40, 120))
    a, b = plan_png(plan), plan_png(plan)
    assert a[:8] == b"\x89PNG\r\n\x1a\n" and a == b


def test_config_plan_prints_and_draws(tmp_path, capsys):
    png = tmp_path / "plan.png"
    code = main(["config", "plan", "--size", "120x40", "--set", "sva.disparities=32",
                 "--png", str(png)])
    out, _ = capsys.readouterr()
    assert code == 0
    cfg = load_config(overrides={"sva.disparities": 32})
    energy = "\n".join(energy_lines(estimate(cfg, (40, 120))["energy"]))
    assert out == plan_text(build_plan(cfg, (40, 120))) + energy + "\n"  # then the energy
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_config_plan_refuses_bad_input_with_one_line(tmp_path, capsys):
    cases = [["--size", "12by4"], ["--set", "nna.line_buffer_rows=8", "--set",
                                   "nna.descriptor=cnn"],
             ["--png", str(tmp_path / "missing" / "plan.png")], ["--size", "32x8"]]
    for args in cases:
        code = main(["config", "plan", *args])
        _, err = capsys.readouterr()
        assert code == 2, args
        assert len(err.strip().splitlines()) == 1 and err.startswith("stereosim: error: ")
    assert not (tmp_path / "missing").exists()


def test_the_budget_says_what_it_is_and_its_unit():
    plan = build_plan(load_config(overrides={"sva.disparities": 32}), (40, 120))
    cycles = ", ".join(f"{d} {n:,} cycles" for d, n in sorted(plan.budget.items()))
    assert (f"\ncycle budget (automatic, sim.max_cycles = 0; a run stops after this many cycles "
            f"of each clock): {cycles}\n") in plan_text(plan)
    plan = build_plan(load_config(overrides={"sva.disparities": 32, "sim.max_cycles": 5000}),
                      (40, 120))
    assert plan_text(plan).endswith(
        "cycle budget (sim.max_cycles; a run stops after this many cycles of each clock): "
        "nna 5,000 cycles, sva 5,000 cycles\n")


def _apart(a, b) -> bool:
    return a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]


LENT = {"nna.lent_submodules": 4, "nna.lent_network": str(ROOT / "configs" / "lent"
                                                           / "backbone224.toml")}
BUFFERED = {"source.kind": "camera", "source.frame_buffers": 2}


def _png_size(png: bytes) -> tuple[int, int]:
    return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")


@pytest.mark.parametrize("over", [
    {}, {"nna.stereo_submodules": 4}, {"nna.stereo_submodules": 6},
    {"nna.stereo_submodules": 10, "source.kind": "camera"},
    {"nna.stereo_submodules": 8, "nna.split": "rows"},
    BUFFERED, {"nna.stereo_submodules": 10, **BUFFERED},
    LENT, {"nna.submodules": 12, "nna.stereo_submodules": 8, **LENT, **BUFFERED,
           "dram.model": "tdm"},
    {"nna.submodules": 40, "nna.stereo_submodules": 40},
], ids=["one per camera", "2 tiles", "3 tiles", "5 tiles, camera", "4 row bands",
        "frame buffers", "5 tiles, frame buffers", "lent", "4 tiles, lent, frame buffers",
        "20 tiles"])
def test_every_block_and_fifo_is_drawn_and_nothing_overlaps(over):
    plan = build_plan(load_config(overrides={"nna.descriptor": "cnn", **over}), (720, 1280))
    pic = picture_layout(plan)
    drawn = [b for members in pic.members.values() for b in members]
    assert sorted(drawn) == sorted(b.name for b in plan.blocks)
    named = [f for fifos in pic.label_fifos.values() for f in fifos]
    assert sorted(named) == sorted(f.name for f in plan.fifos)
    boxes = [*pic.boxes.items(), *pic.labels.items(), *pic.notes.items()]
    for i, (name, box) in enumerate(boxes):
        for other, other_box in boxes[i + 1:]:
            assert _apart(box, other_box), (name, other)


def test_a_frame_buffered_camera_its_dram_and_the_memory_source_are_three_boxes():
    plan = build_plan(load_config(overrides=BUFFERED), (720, 1280))
    pic = picture_layout(plan)
    for side in ("left", "right"):
        row = [pic.boxes[n] for n in (f"camera_{side}", f"dram_{side}", f"memory_{side}")]
        assert row[0][2] <= row[1][0] and row[1][2] <= row[2][0]  # left to right, apart
    # every clock domain of the plan colours a box and is named in the legend
    assert set(plan.domains) <= set(pic.domains.values())
    for d in plan.domains.values():
        assert f"{d.name} domain, {d.freq_hz / 1e6:g} MHz" in pic.texts
    cam = plan.block("camera_left")
    assert f"{cam.domain}" == "camera" and pic.domains["camera_left"] == "camera"


def test_many_submodules_are_drawn_as_one_box_and_the_picture_stays_short():
    many = build_plan(load_config(overrides={"nna.submodules": 40,
                                             "nna.stereo_submodules": 40}), (720, 1280))
    pic = picture_layout(many)
    stacks = {n: m for n, m in pic.members.items() if len(m) > 1}
    assert stacks == {"nna_left0..19": tuple(f"nna_left{t}" for t in range(20)),
                      "nna_right0..19": tuple(f"nna_right{t}" for t in range(20))}
    assert "nna_left0..19 (x 20)" in pic.texts
    one = build_plan(load_config(), (720, 1280))
    assert _png_size(plan_png(many))[1] <= 1.5 * _png_size(plan_png(one))[1]
    # the tallest drawing: MAX_DRAWN submodules a camera and MAX_DRAWN lent ones
    tallest = build_plan(load_config(overrides={
        "nna.submodules": 3 * MAX_DRAWN, "nna.stereo_submodules": 2 * MAX_DRAWN, **LENT}),
        (720, 1280))
    drawn = picture_layout(tallest).boxes
    assert {f"nna_right{MAX_DRAWN - 1}", f"lent{tallest.lent.used - 1}"} <= set(drawn)
    assert tallest.lent.used == 4
    assert _png_size(plan_png(tallest))[1] < 1500  # the bound plan_png states


def test_the_lent_network_is_drawn_with_its_rate_and_dram_load():
    plan = build_plan(load_config(overrides={**LENT, "dram.model": "tdm"}), (720, 1280))
    pic = picture_layout(plan)
    assert [n for n in pic.boxes if n.startswith("lent")] == [
        f"lent{s}" for s in range(plan.lent.used)]
    assert pic.domains["lent0"] == "nna" and pic.domains["dram_lent"] is None
    rep = lent_report(plan.lent, plan.dram, 720 * 1280)
    (note,) = [t for t in pic.texts if t.startswith("lent network ")]
    assert f"{rep['fps']:,.1f} fps ({rep['fps_max']:,.1f} at most" in note
    assert f"{rep['dram_gbps']:.3f} GB/s" in note
    assert f"{rep['stereo_pair']['read_bound_fps']:,.1f}" in note


def test_span_shortens_names_that_differ_in_one_number():
    assert _span(["nna_left0", "nna_left19"]) == "nna_left0..19"
    assert _span(["nna_left0_to_merge", "nna_left4_to_merge"]) == "nna_left0..4_to_merge"
    assert _span(["src_left_to_nna10", "src_left_to_nna12"]) == "src_left_to_nna10..12"
    assert _span(["sva"]) == "sva"


@pytest.mark.parametrize("over", [{}, LENT, {"nna.descriptor": "census"}],
                         ids=["default", "lent", "census"])
def test_the_listing_gives_the_chips_sram_by_block_and_by_kind(over):
    plan = build_plan(load_config(overrides=over), (720, 1280))
    sram = chip_sram(plan)
    text = plan_text(plan)
    assert "SRAM per instance" not in text
    assert (f"\nSRAM on the chip: {sram['total']:,} bits ({sram['total'] / 1e6:.2f} Mbit), "
            "every instance counted once\n") in text
    by_kind = re.search(r"^  by kind: (.*)$", text, re.M).group(1)
    kinds = dict(part.rsplit(" ", 1) for part in by_kind.split("; "))
    assert {k: int(v.replace(",", "")) for k, v in kinds.items()} == sram["by_kind"]
    assert sum(sram["by_kind"].values()) == sram["total"]
    by_block = re.search(r"^  by block: (.*)$", text, re.M).group(1)
    figures = [int(part.rsplit(" ", 1)[1].replace(",", "")) for part in by_block.split("; ")]
    assert sum(figures) == sram["total"]
    n = plan.cfg.nna
    assert f"NNA stereo {n.stereo_submodules} x {sram['nna_per_submodule']:,} = " in by_block
    assert (f"NNA lent {n.lent_submodules} x" in by_block) == bool(n.lent_submodules)
    assert (f"  one NNA submodule (each of the {n.submodules}, sized for the widest tile): "
            f"{sram['nna_per_submodule']:,} bits") in text
