"""Cost of tracing a 720p cycle-model frame: a 100,000-cycle window with every signal.

Runs the issue's frame (1280x720, CNN descriptor, D = 128, 4 paths, LR check) on the compiled
engine without a trace and with a trace window of 100,000 SVA cycles in the middle of the frame
(all signals), writes the VCD (and the .gtkw), and prints the added wall time (target <= 1 s)
and the value changes per second of recording + writing (target >= 2 M/s).

    python benchmarks/trace_720p.py [--repeat 3] [--start 2000000] [--cycles 100000]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from speed_cycle import CONFIG, frame  # noqa: E402

from stereosim.core.config import load_config  # noqa: E402
from stereosim.sim.cycle.plan import build_plan  # noqa: E402
from stereosim.sim.cycle.simulate import simulate  # noqa: E402
from stereosim.sim.tracing import TraceRequest, run_traced, write_traces  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--start", type=int, default=2_000_000,
                    help="first SVA cycle of the window")
    ap.add_argument("--cycles", type=int, default=100_000)
    args = ap.parse_args(argv)
    left, right = frame()
    plan = build_plan(load_config(overrides=CONFIG), left.shape)
    small = build_plan(load_config(overrides=dict(CONFIG, **{"sva.disparities": 64})), (48, 256))
    simulate(small, left[:48, :256], right[:48, :256], window=(0, 10**9))  # compile
    plain, traced, writing = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        req = TraceRequest(window=f"sva:{args.start}:{args.start + args.cycles}",
                           vcd=os.path.join(tmp, "t.vcd"))
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            simulate(plan, left, right)
            plain.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            _, log = run_traced(plan, left, right, req)
            t1 = time.perf_counter()
            write_traces(log, req)
            t2 = time.perf_counter()
            traced.append(t2 - t0)
            writing.append(t2 - t1)
        size = os.path.getsize(req.vcd)
    p, t, wr = min(plain), min(traced), min(writing)
    added = t - p
    print(f"1280x720 CNN D=128, trace window {args.cycles:,} SVA cycles from {args.start:,}, "
          f"{len(log.signals)} signals, best of {args.repeat}:")
    print(f"  run without trace : {p:.3f} s")
    print(f"  run with trace    : {t:.3f} s  (recording + VCD + .gtkw; writing alone {wr:.3f} s)")
    print(f"  added by tracing  : {added:.3f} s  (target <= 1 s)")
    print(f"  value changes     : {log.n_changes:,}, VCD {size / 1e6:.1f} MB")
    print(f"  changes / s       : {log.n_changes / max(added, 1e-9) / 1e6:.2f} M per added second, "
          f"{log.n_changes / wr / 1e6:.2f} M by the writer  (target >= 2 M/s)")


if __name__ == "__main__":
    main()
