"""The figures docs/ quotes in generated blocks are what the code gives today: every block is
listed in benchmarks/doc_figures.py with the command that writes it (which its page names),
and the cheap ones are measured again here."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "doc_figures.py"
sys.path.insert(0, str(SCRIPT.parent))

import doc_figures  # noqa: E402  (benchmarks/ is a folder of scripts, not a package)


def _blocks() -> dict[str, str]:
    """Every generated block of docs/: its name -> its page."""
    found = {}
    for page in sorted((ROOT / "docs").glob("*.md")):
        for name in re.findall(r"<!-- ([\w-]+):begin -->", page.read_text()):
            assert f"<!-- {name}:end -->" in page.read_text(), f"{page.name}: {name} never ends"
            found[name] = page.name
    return found


def _words(page: str) -> str:
    """A page's text with its line breaks and runs of spaces as single spaces."""
    return " ".join((ROOT / "docs" / page).read_text().split())


def test_every_generated_block_is_listed_with_a_command_its_page_names():
    blocks = _blocks()
    listed = {name: fig.doc for name, fig in doc_figures.FIGURES.items()}
    listed |= {name: doc for name, (doc, _) in doc_figures.ELSEWHERE.items()}
    assert blocks == listed
    for doc, command in doc_figures.ELSEWHERE.values():
        assert command in _words(doc), f"docs/{doc} does not name {command}"
    for name, fig in doc_figures.FIGURES.items():
        assert f"{doc_figures.COMMAND} {name}" in _words(fig.doc), f"docs/{fig.doc}: no command"


@pytest.mark.parametrize("name", list(doc_figures.FIGURES))
def test_the_page_holds_what_the_block_measures_today(name):
    """Every block of the script (a few 720p frames at most) is measured again, here, and
    compared with its page, as ``doc_figures.py --check NAME`` does; a stale page fails with
    the diff. One test a block, so that the suite's workers share them."""
    diff = doc_figures.stale(name, doc_figures.FIGURES[name].lines())
    assert not diff, "\n".join(diff)


def test_the_script_checks_from_the_command_line(monkeypatch, capsys):
    """``doc_figures.py --check NAME`` exits 0 where the page holds the block, and 1 with the
    diff where it does not (here a page whose block lost its last line)."""
    done = subprocess.run([sys.executable, str(SCRIPT), "--check", "row-windows"],
                          capture_output=True, text=True, timeout=600, check=False, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    held = doc_figures.current("row-windows")
    monkeypatch.setattr(doc_figures, "current", lambda name: held[:-1])
    assert doc_figures.main(["--check", "row-windows"]) == 1
    assert f"+{held[-1]}" in capsys.readouterr().out.splitlines()


def _middeval3_robustness() -> dict[str, dict[str, tuple[str, str]]]:
    """docs/ablation.md's robustness block, its MiddEval3 table: condition -> descriptor ->
    (totbad, bad2) as the page prints them."""
    text = (ROOT / "docs" / "ablation.md").read_text()
    block = text.split("<!-- robustness:begin -->", 1)[1].split("<!-- robustness:end -->", 1)[0]
    table = block.split("**MiddEval3", 1)[1].split("\n\n", 2)[1]
    lines = [line.strip().strip("|").split("|") for line in table.splitlines()]
    head = [cell.strip() for cell in lines[0]]
    rows = {}
    for cells in lines[2:]:
        pairs = [re.fullmatch(r"\**([\d.]+) \(([\d.]+)\)\**", c.strip()) for c in cells[1:]]
        rows[cells[0].strip()] = {name: m.groups() for name, m in zip(head[1:], pairs)}
    return rows


def test_the_readme_quotes_the_robustness_table_as_it_stands():
    """README.md's figures for the learned descriptor against the census (totbad and bad2 on
    clean MiddEval3, totbad with noise of sigma 8) are those of docs/ablation.md's robustness
    block, which benchmarks/robustness.py writes."""
    rows = _middeval3_robustness()
    readme = " ".join((ROOT / "README.md").read_text().split())
    clean, noisy = rows["clean"], rows["noise 8"]
    for cnn, census in ((clean["cnn"][0], clean["census"][0]),
                        (clean["cnn"][1], clean["census"][1]),
                        (noisy["cnn"][0], noisy["census"][0])):
        assert f"({cnn} vs {census})" in readme, f"README.md does not quote ({cnn} vs {census})"
    gap = float(noisy["census"][0]) - float(noisy["cnn"][0])
    assert f"{gap:.1f} points less totbad with noise of sigma 8" in readme


def test_the_clock_kernel_example_runs_as_its_page_says():
    """docs/clock-kernel.md's example (a counter, a depth-2 FIFO, a collector) asserts the
    cycles it takes; the page's code is run as it stands."""
    text = (ROOT / "docs" / "clock-kernel.md").read_text()
    section = text.split("## Running: budget, watchdog, statistics", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    scope: dict = {}
    exec(compile(code, "docs/clock-kernel.md", "exec"), scope)
    assert scope["stats"]["cycles"] == {"clk": 6}
