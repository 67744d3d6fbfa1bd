"""What a stream keeps per frame: the figures behind ``sim.cycle.frames.MAX_FRAMES``.

    python benchmarks/stream_memory.py [--frames 10000]

A 64x24 pair (census, D = 16) repeated N times through ``stereosim.run_stream`` in cycle mode,
measured with tracemalloc (numpy's allocations included): the peak of the timing pass and what
its report keeps, per frame; then the frames iterated with a ground truth and two masks, and
what their metrics take per frame in memory and in report.json. The per-frame figures do not
depend on the frame size (the engine's rings do, and are bounded: docs/compiled-engine.md).
"""

from __future__ import annotations

import argparse
import tracemalloc

import numpy as np

from stereosim.core.outputs import json_text
from stereosim.sim.api import run_stream

OVERRIDES = {"nna.descriptor": "census", "sva.disparities": 16}
H, W = 24, 64


def measure(frames: int) -> dict:
    rng = np.random.default_rng(0)
    base = rng.integers(0, 256, (H, W + 4), dtype=np.uint8)
    pair = (base[:, 4:].copy(), base[:, :W].copy())
    gt = np.full((H, W), 4.0, np.float32)
    masks = {"all": np.ones((H, W), bool), "nonocc": np.arange(W)[None, :].repeat(H, 0) < W - 8}
    for _ in run_stream([pair] * 2, overrides=OVERRIDES, gt=gt, masks=masks):
        pass  # compile (or load) the kernels outside the measurement
    pairs = [pair] * frames
    tracemalloc.start()
    start = tracemalloc.get_traced_memory()[0]
    stream = run_stream(pairs, overrides=OVERRIDES, gt=gt, masks=masks)
    kept, peak = tracemalloc.get_traced_memory()
    report_bytes = len(json_text(stream.report))
    tracemalloc.reset_peak()
    for _ in stream:
        pass
    scored = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    metrics_json = len(json_text(stream.report["metrics_per_frame"]))
    return {"frames": frames,
            "timing_peak_b": (peak - start) / frames,
            "timing_kept_b": (kept - start) / frames,
            "report_json_b": report_bytes / frames,
            "metrics_b": (scored - kept) / frames,
            "metrics_json_b": metrics_json / frames}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[10000])
    for n in ap.parse_args().frames:
        r = measure(n)
        print(f"{r['frames']} frames: timing pass peak {r['timing_peak_b']:.0f} B/frame "
              f"(report keeps {r['timing_kept_b']:.0f}, {r['report_json_b']:.0f} in JSON); "
              f"metrics of two masks {r['metrics_b']:.0f} B/frame "
              f"({r['metrics_json_b']:.0f} in JSON)", flush=True)


if __name__ == "__main__":
    main()
