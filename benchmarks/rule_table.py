"""docs/architecture.md's "Where each rule lives", read off the code: every public rule, plan
entry, stage, buffer and contract definition of the modules that hold the chip's rules, what
its docstring says it is, and which parts of the code read it (found in their syntax trees), so
the table cannot claim a reader that does not read the rule or miss one that does.

``python benchmarks/doc_figures.py --write rules`` writes it; the suite checks the page holds
what this prints.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "sim", "nna", "sva", "quant", "traces")
# the modules whose public definitions are the chip's rules, in the table's order
# (a block's own rule is in its folder: sva/<stage>/timing.py, nna/submodule/timing.py)
SOURCES = ("sim/cycle/rules.py", "sim/cycle/fifo/rule.py", "sim/cycle/stages.py",
           "sim/cycle/plan.py", "sim/cycle/figures.py", "sim/cycle/buffers.py",
           "sim/cycle/contract.py", "core/timing.py", "nna/geometry.py",
           "nna/submodule/timing.py", "sva/geometry.py", "sva/hamming/timing.py",
           "sva/box/timing.py", "sva/sgm/timing.py", "sva/wta/timing.py", "sva/lr/timing.py",
           "sva/median/timing.py")
# who reads a rule, by where the reading module lives (the first match names it)
READERS = (("FIFO block", "sim/cycle/fifo/"), ("readable engine", "sim/cycle/readable/"),
           ("compiled engine", "sim/cycle/compiled/"),
           ("driver", "sim/cycle/simulate.py"), ("estimate", "sim/cycle/estimate.py"),
           ("plan", "sim/cycle/plan.py"), ("stages", "sim/cycle/stages.py"),
           ("buffers", "sim/cycle/buffers.py"), ("contract", "sim/cycle/contract.py"),
           ("reports", "sim/cycle/report.py"), ("reports", "sim/cycle/energy.py"),
           ("reports", "sim/cycle/figures.py"),
           ("frames", "sim/cycle/frames.py"), ("traces", "traces/"), ("traces", "sim/tracing.py"),
           ("application", "sim/"), ("NNA stages", "nna/"), ("SVA stages", "sva/"),
           ("integer arithmetic", "quant/"), ("core", "core/"))
SUMMARY_CHARS = 150


def _reader(path: str) -> str:
    return next(name for name, prefix in READERS if path.startswith(prefix))


def _summary(doc: str | None) -> str:
    """A docstring's first sentence, on one line, at most SUMMARY_CHARS characters."""
    text = " ".join((doc or "").split())
    first = re.split(r"(?<=\.)\s", text, maxsplit=1)[0]
    if len(first) > SUMMARY_CHARS:
        first = first[:SUMMARY_CHARS].rsplit(" ", 1)[0] + " ..."
    return first.replace("|", "\\|")


def _names_used(path: Path) -> set[str]:
    """Every name a module reads, imports or reaches as an attribute."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Name):
            names.add(node.id)
        elif isinstance(node, ast.Attribute):
            names.add(node.attr)
        elif isinstance(node, ast.alias):
            names.add(node.name)
    return names


def definitions() -> list[tuple[str, str, str]]:
    """``(module, name, summary)`` of every public top-level function and class of SOURCES."""
    out = []
    for src in SOURCES:
        for node in ast.parse((ROOT / src).read_text()).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
                out.append((src, node.name, _summary(ast.get_docstring(node))))
    return out


def table() -> list[str]:
    """The Markdown table: one row a definition that a module other than its own reads."""
    used = {str(p.relative_to(ROOT)): _names_used(p)
            for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}
    lines = ["| rule | lives in | read by |", "|---|---|---|"]
    for src, name, summary in definitions():
        readers = sorted({_reader(path) for path, names in used.items()
                          if path != src and name in names})
        if readers:
            lines.append(f"| {summary} | `{src}: {name}` | {', '.join(readers)} |")
    return lines
