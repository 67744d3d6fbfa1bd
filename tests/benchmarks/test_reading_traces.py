"""docs/reading-traces.md's pictures are centred on instants found in the runs
(benchmarks/reading_traces.py): the queries that find them, the pictures the page shows, and
the refusal of a run that no longer tells the page's story. (The figures themselves are
checked by test_doc_figures.py.)"""

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from stereosim.traces.log import Clock, Signal, TraceLog, validate

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import reading_traces  # noqa: E402  (benchmarks/ is a folder of scripts, not a package)


def _trace() -> reading_traces.Trace:
    """A 4-bit count x: 0, then 3 at 10 fs, 0 at 30 fs, 3 at 50 fs (and 7 then 3 at 50 fs: the
    last change at an instant wins); a 1-bit pulse p high over [20, 25) and [60, 65)."""
    log = validate(TraceLog(
        signals=[Signal("top.a.x", 4, "sva"), Signal("top.a.p", 1, "sva")],
        clocks=[Clock("sva", 5, 0)], start_fs=0, end_fs=100,
        initial=np.array([0, 0], np.uint64),
        times_fs=np.array([10, 20, 25, 30, 50, 50, 60, 65], np.int64),
        ids=np.array([0, 1, 1, 0, 0, 0, 1, 1], np.int32),
        values=np.array([3, 1, 0, 0, 7, 3, 1, 0], np.uint64)))
    return reading_traces.Trace(log, {}, None, None)


def test_a_signal_is_read_after_the_changes_at_an_instant():
    tr = _trace()
    assert [tr.at("top.a.x", t) for t in (0, 9, 10, 29, 30, 50, 99)] == [0, 0, 3, 3, 0, 3, 3]
    assert tr.when("top.a.x", lambda v: v == 3) == 10
    assert tr.when("top.a.x", lambda v: v == 3, after=10) == 10
    assert tr.when("top.a.x", lambda v: v == 3, after=20) == 20
    # at 10 fs x has already turned 3: the 0 it held before does not count
    assert tr.when("top.a.x", lambda v: v == 0, after=10) == 30
    assert tr.when("top.a.x", lambda v: v == 3, after=31) == 50
    assert tr.when("top.a.x", lambda v: v == 7) is None
    assert tr.values("top.a.x", 15, 50) == (0, 3)
    assert tr.values("top.a.x", 31, 50) == (0, 0)
    assert tr.rises("top.a.p", 0, 100) == 2
    assert tr.rises("top.a.p", 0, 60) == 1
    assert list(tr.steps("top.a.x")) == [10, 30, 50]
    assert tr.cycle(24) == 4


def test_the_page_shows_every_picture_the_script_draws():
    drawn = {pic.png for pic in reading_traces.pictures()}
    page = (ROOT / "docs" / reading_traces.DOC).read_text()
    assert set(re.findall(r"\(img/(trace_\w+\.png)\)", page)) == drawn
    assert {p.name for p in (ROOT / "docs" / "img").glob("trace_*.png")} == drawn


def test_a_run_that_no_longer_tells_the_story_is_refused():
    """A FIFO deep enough never fills: section 3 has no stall to show, and says so. (4096 no
    longer is: the SVA holds its input back for thousands of cycles while its box rows catch
    up with the rows its ring took at the frame's start.)"""
    deep = (("nna.descriptor", "census"), ("fifo.nna_to_sva_depth", 1 << 18))
    with pytest.raises(reading_traces.StoryChanged,
                       match="section 3: the 262144-deep FIFO fills"):
        reading_traces.fifo_stall(deep)
