"""Regenerate the trace golden files (run only when the trace formats change on purpose):

    PYTHONPATH=. python tests/golden/make_traces_golden.py

Writes traces_small.vcd, traces_small.gtkw (naming the dump and its filter file by bare file
name, so the bytes do not depend on the folder; ``stereosim run`` writes absolute paths),
traces_small.status.txt and traces_small.timeline.json from
:func:`golden_log` -- the synthetic chip's signals and clocks over 20 SVA cycles, with values from
integer arithmetic (no random generator, whose streams may change between numpy versions);
tests/traces/test_golden.py compares them byte for byte.
"""

from pathlib import Path

import numpy as np

from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.gtkw import write_gtkw, write_status_filter
from stereosim.traces.log import TraceLog
from stereosim.traces.timeline import write_timeline
from stereosim.traces.vcd import write_vcd

GOLDEN = Path(__file__).resolve().parent
VERSION = "stereosim golden"


def golden_log() -> TraceLog:
    shape = synthetic_log(1)
    clocks = {c.name: c for c in shape.clocks}
    end_fs = 20 * clocks["sva"].period_fs
    times, ids, values = [], [], []
    for i, sig in enumerate(shape.signals):
        clk = clocks[sig.domain]
        for k in range((end_fs - 1 - clk.phase_fs) // clk.period_fs + 1):
            if (k * 7 + i * 13) % 5 < 2:
                times.append(clk.phase_fs + k * clk.period_fs)
                ids.append(i)
                v = (k * 2654435761 + i * 40503) % (1 << sig.width)
                values.append(v % 4 if sig.path.endswith(".status") else v)
    order = np.argsort(np.array(times, dtype=np.int64), kind="stable")
    return TraceLog(
        signals=shape.signals, clocks=shape.clocks, start_fs=0, end_fs=end_fs,
        initial=np.zeros(len(shape.signals), dtype=np.uint64),
        times_fs=np.array(times, dtype=np.int64)[order],
        ids=np.array(ids, dtype=np.int32)[order],
        values=np.array(values, dtype=np.uint64)[order],
    )


def main() -> None:
    log = golden_log()
    write_vcd(GOLDEN / "traces_small.vcd", log, version=VERSION)
    write_gtkw(GOLDEN / "traces_small.gtkw", log, "traces_small.vcd", "traces_small.status.txt")
    write_status_filter(GOLDEN / "traces_small.status.txt")
    write_timeline(GOLDEN / "traces_small.timeline.json", log)


if __name__ == "__main__":
    main()
