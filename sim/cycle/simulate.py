"""One frame on the engine ``sim.engine`` selects (the one place that decides)."""

from __future__ import annotations

import numpy as np

from sim.config import ChipConfig
from sim.cycle.chip import run_cycle
from sim.cycle.fast import run_cycle_fast
from sim.cycle.schedule import run_schedule


def fast_engine_models(cfg: ChipConfig) -> bool:
    """The compiled steps (sim/fast.py) cover one NNA submodule per camera; the schedule engine
    (sim/schedule.py) covers splits too."""
    return cfg.nna.stereo_submodules == 2


def simulate(left: np.ndarray, right: np.ndarray, cfg: ChipConfig) -> tuple[np.ndarray, dict]:
    """One frame on the engine ``sim.engine`` selects: (output words, cycle report).

    ``readable``: the reference kernel. ``fast`` and ``auto``: the compiled engine -- the
    schedule engine for a frame that completes, the compiled steps (one submodule per camera)
    or the readable kernel (splits) for one that stops early, which they report exactly. Every
    engine gives identical words, reports and statistics (tests/sim/test_fast.py,
    tests/sim/test_schedule.py); the readable one runs ~5e4 cycles/s, the others millions.
    """
    engine = "readable" if cfg.sim.engine == "readable" else "fast"
    if engine == "fast" and fast_engine_models(cfg):
        words, report, _ = run_cycle_fast(left, right, cfg)
    else:
        done = None
        if engine == "fast":
            done = run_schedule(left, right, cfg)
        if done is None:
            engine = "readable"
            words, report, _ = run_cycle(left, right, cfg)
        else:
            words, report, _ = done
    report["engine"] = engine
    return words, report


