"""What a timing rule change does, on three small chips: whether the readable kernel and the
compiled engine still agree (words, statistics, report), the first and last SVA output cycle
of both engines and of the analytic estimate, and the estimate's frame-rate bound.

docs/changing-the-chip.md runs it before and after a rule change in one block's folder:

    python benchmarks/rule_change_demo.py
"""

from __future__ import annotations

import numpy as np

from stereosim.core.config import load_config
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable

CASES = [((20, 80), {"nna.descriptor": "census", "sva.disparities": 32, "sva.lanes": 16}),
         ((20, 80), {"nna.descriptor": "cnn", "sva.disparities": 32, "nna.macs": 288}),
         ((24, 96), {"nna.descriptor": "cnn", "sva.disparities": 32,
                     "nna.stereo_submodules": 2, "sva.sram_ports": "1rw", "sva.lanes": 8})]


def main() -> None:
    rng = np.random.default_rng(1)
    for shape, over in CASES:
        base = rng.integers(0, 256, (shape[0], shape[1] + 4), dtype=np.uint8)
        left, right = base[:, :shape[1]].copy(), base[:, 4:].copy()
        plan = build_plan(load_config(overrides=over), shape)
        slow, fast = run_readable(plan, left, right), run_compiled(plan, left, right)
        same = (np.array_equal(slow.words, fast.words) and slow.stats == fast.stats
                and slow.report == fast.report)
        est = estimate(plan.cfg, shape)
        c, e = slow.report["cycles"], est["latency"]
        print(f"{shape} {over}: readable = compiled: {same}; SVA II {plan.block('sva').ii}; "
              f"first/last output (SVA cycles): engines {c['first_output']['sva']}/"
              f"{c['last_output']['sva']}, estimate {e['first_output_sva_cycle']}/"
              f"{e['last_output_sva_cycle']}; estimate's fps bound "
              f"{est['throughput']['fps_bound']}")


if __name__ == "__main__":
    main()
