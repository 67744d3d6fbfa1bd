"""Put a generated block into a documentation page between its two marker comments (the
benchmarks' ``--write``)."""

from __future__ import annotations

import sys
from pathlib import Path

from stereosim.core.outputs import atomic_write_bytes


def write_between(doc: Path, begin: str, end: str, lines: list[str]) -> int:
    """Replace what ``doc`` holds between ``begin`` and ``end`` by ``lines``; 2 (with one line
    on stderr) if the page lacks the markers, else 0."""
    text = doc.read_text()
    if begin not in text or end not in text:
        print(f"{doc} lacks the {begin} / {end} markers", file=sys.stderr)
        return 2
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    atomic_write_bytes(doc, (head + begin + "\n" + "\n".join(lines) + "\n" + end + tail).encode())
    print(f"wrote {doc}")
    return 0
