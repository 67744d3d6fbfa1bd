"""Measured timings live in dated, machine-named result files that the benchmark scripts write
(benchmarks/machine.py: ``--write-result``), and the docs link them: every link resolves, and
the writer names its file by script, date and CPU and keeps what the script printed."""

import re
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import machine  # noqa: E402  (benchmarks/ is a folder of scripts, not a package)

LINK = re.compile(r"\]\(((?:\.\./)?benchmarks/results/[^)#\s]+)\)")


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.parametrize("page", _pages(), ids=lambda p: p.name)
def test_every_linked_result_file_exists(page):
    for link in LINK.findall(page.read_text()):
        target = (page.parent / link).resolve()
        assert target.is_file(), f"{page.name} links {link}, which does not exist"


def test_performance_md_links_result_files():
    links = LINK.findall((ROOT / "docs" / "performance.md").read_text())
    assert len(links) >= 3


def test_result_files_are_named_by_script_date_and_cpu():
    for path in (ROOT / "benchmarks" / "results").glob("*.md"):
        assert re.fullmatch(r"[a-z0-9_]+-\d{4}-\d\d-\d\d-[a-z0-9-]+\.md", path.name), path.name
        assert path.read_text().startswith("# "), path.name


def test_the_writer_appends_what_the_block_printed(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(machine, "RESULTS", tmp_path)
    monkeypatch.setattr(machine, "ROOT", tmp_path)
    monkeypatch.setattr(sys, "argv", ["speed_x.py", "--repeat", "2"])
    days = {datetime.now(UTC).strftime("%Y-%m-%d")}
    with machine.result_file("speed_x", write=True):
        print("ratio 0.42")
    with machine.result_file("speed_x", write=True):
        print("ratio 0.43")
    with machine.result_file("speed_x", write=False):
        print("not kept")
    with pytest.raises(RuntimeError), machine.result_file("speed_x", write=True):
        print("failed run")
        raise RuntimeError
    (path,) = tmp_path.iterdir()
    days.add(datetime.now(UTC).strftime("%Y-%m-%d"))  # the writer's day, at midnight either
    assert path.name in {f"speed_x-{day}-{machine.cpu_slug()}.md" for day in days}
    text = path.read_text()
    assert text.count("# speed_x, ") == 1 and text.count("\n## ") == 2
    assert "`python benchmarks/speed_x.py --repeat 2`" in text
    assert "ratio 0.42" in text and "ratio 0.43" in text
    assert "not kept" not in text and "failed run" not in text
    assert f"machine: {machine.describe()}" in text
    assert "ratio 0.42" in capsys.readouterr().out  # the terminal still sees it
