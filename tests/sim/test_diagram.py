"""The chip plan drawn (sim/diagram.py, `stereosim config plan`): read off the plan, current in
docs/architecture.md, deterministic, bad input refused with one line."""

import re
from pathlib import Path

import pytest

from stereosim.sim.cli import main
from stereosim.sim.config import load_config
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.diagram import picture_boxes, plan_png, plan_text

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


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
    assert out == plan_text(build_plan(load_config(overrides={"sva.disparities": 32}), (40, 120)))
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


@pytest.mark.parametrize("over", [
    {}, {"nna.stereo_submodules": 4}, {"nna.stereo_submodules": 6},
    {"nna.stereo_submodules": 10, "source.kind": "camera"},
    {"nna.stereo_submodules": 8, "nna.split": "rows"},
], ids=["one per camera", "2 tiles", "3 tiles", "5 tiles, camera", "4 row bands"])
def test_fifo_labels_overlap_no_block_and_no_other_label(over):
    plan = build_plan(load_config(overrides={"nna.descriptor": "cnn", **over}), (720, 1280))
    blocks, labels = picture_boxes(plan)
    assert set(labels) == {f.name for f in plan.fifos} and set(blocks) == {
        b.name for b in plan.blocks}
    named = list(labels.items())
    for i, (name, box) in enumerate(named):
        for other, other_box in named[i + 1:] + list(blocks.items()):
            assert _apart(box, other_box), (name, other)
