"""The trace outputs of a fixed log equal the golden files byte for byte (regenerate them with
tests/golden/make_traces_golden.py only when a format changes on purpose)."""

import importlib.util
from pathlib import Path

from stereosim.traces.gtkw import gtkw_text, status_filter_text
from stereosim.traces.timeline import timeline_bytes
from stereosim.traces.vcd import vcd_bytes

GOLDEN = Path(__file__).resolve().parents[1] / "golden"


def _script():
    spec = importlib.util.spec_from_file_location("make_traces_golden",
                                                  GOLDEN / "make_traces_golden.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_outputs_equal_the_golden_files():
    script = _script()
    log = script.golden_log()
    assert vcd_bytes(log, version=script.VERSION) == (GOLDEN / "traces_small.vcd").read_bytes()
    assert gtkw_text(log, "traces_small.vcd", "traces_small.status.txt").encode() == (
        GOLDEN / "traces_small.gtkw").read_bytes()
    assert status_filter_text().encode() == (GOLDEN / "traces_small.status.txt").read_bytes()
    assert timeline_bytes(log) == (GOLDEN / "traces_small.timeline.json").read_bytes()
