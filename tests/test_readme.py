"""README.md's tour, checked against the code: every ``stereosim`` line parses with today's
command line (an option renamed or removed fails here), and the lines that answer in seconds
without files the README leaves to the reader run as written and succeed (the analytic
estimate, the configuration's listings, a network file's back end, a functional run). The
waveform example is run in tests/traces/test_readme_wave.py. The set-up section quotes no
commit and no dated figure."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from stereosim.sim.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _tour() -> list[list[str]]:
    """The arguments of every line of README's code blocks that starts ``stereosim `` (a
    comment after ``#`` dropped; a line a shell would continue is joined)."""
    out, block = [], False
    for line in README.read_text().splitlines():
        if line.startswith("```"):
            block = not block
        elif block and line.startswith("stereosim "):
            out.append(shlex.split(line, comments=True)[1:])
    return out


TOUR = _tour()
# what runs here: no file the README asks the reader to bring, seconds each
RUNS = [a for a in TOUR if a[0] in ("estimate", "config") and "a.toml" not in a]
RUNS += [a for a in TOUR if a[:1] == ["run"] and a[1:] == ["--mode", "functional"]]


def test_the_tour_is_there():
    assert len(TOUR) >= 25 and len(RUNS) >= 5


@pytest.mark.parametrize("args", TOUR, ids=[" ".join(a)[:60] for a in TOUR])
def test_every_tour_line_parses(args):
    parsed = build_parser().parse_args(args)
    assert callable(parsed.func)


@pytest.mark.parametrize("args", RUNS, ids=[" ".join(a)[:60] for a in RUNS])
def test_the_quick_tour_lines_run_as_written(args, tmp_path, monkeypatch, capsys):
    """From a scratch folder, with the README's repository paths made absolute (the README is
    run from the checkout); outputs (--png, --out) land in the scratch folder."""
    monkeypatch.chdir(tmp_path)
    args = [str(ROOT / a) if (ROOT / a).exists() and not a.startswith("-") else a for a in args]
    assert main(args) == 0, capsys.readouterr().err
    out, err = capsys.readouterr()
    assert out.strip() and "Traceback" not in err


def _setup_section() -> str:
    text = README.read_text()
    return text.split("\n## Set-up", 1)[1].split("\n## ", 1)[0]


def test_the_setup_section_quotes_no_commit_and_no_dated_log():
    """The set-up says what to type and roughly how long it takes; a figure of one machine on
    one day (a commit hash, a date) belongs in a result file that docs/performance.md links."""
    setup = _setup_section()
    assert "pip install -e" in setup and "stereosim run" in setup
    hashes = [w for w in re.findall(r"\b[0-9a-f]{7,40}\b", setup)
              if re.search(r"\d", w) and re.search(r"[a-f]", w)]
    assert not hashes, f"README's set-up quotes commit(s) {hashes}"
    dates = re.findall(r"\b20\d\d-\d\d-\d\d\b", setup)
    assert not dates, f"README's set-up quotes dated figures ({dates})"
