"""The figures docs/ quotes in generated blocks are what the code gives today: every block is
listed in benchmarks/doc_figures.py with the command that writes it (which its page names),
and the cheap ones are measured again here."""

import re
import subprocess
import sys
from pathlib import Path

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
    for name, (doc, command) in doc_figures.ELSEWHERE.items():
        assert command in _words(doc), f"docs/{doc} does not name {command}"
    for name, fig in doc_figures.FIGURES.items():
        assert f"{doc_figures.COMMAND} {name}" in _words(fig.doc), f"docs/{fig.doc}: no command"


def test_the_pages_hold_what_the_cheap_figures_measure_today():
    """``doc_figures.py --check`` runs every block of the script (a few 720p frames) and
    compares; a stale page fails with the diff."""
    done = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True,
                          text=True, timeout=600, check=False, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
