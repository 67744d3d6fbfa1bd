"""A synthetic but realistic trace log, for the writer benchmark, tests and examples.

It mimics what the engines record for a stereo frame: the three clocks of the chip at their
configured defaults (``clocks.camera_mhz``, ``nna_mhz``, ``sva_mhz``; periods rounded as
:class:`sim.cycle.rules.ClockDomain` does), two cameras, two NNA instances of two submodules
each, the FIFOs between them and the SVA stages, with the signals an architect looks at --
``status`` (0 idle, 1 busy, 2 starved, 3 blocked), valid and ready bits, row and column
counters, line-buffer fill, FIFO occupancy / push / pop / full / empty, 32-bit descriptors that
change every cycle, the disparity out and LR-check rejects. Each signal changes on rising edges
of its domain's clock with a fixed probability per cycle; values are drawn from a seeded
generator, so a (cycles, seed) pair always gives the same log.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from stereosim.core.config import ClockConfig
from stereosim.sim.cycle.rules import ClockDomain
from stereosim.traces.log import Clock, Signal, TraceLog

# the default clocks of the chip, by domain: clocks.camera_mhz -> "camera", ...
CHIP_CLOCKS_MHZ = {f.name.removesuffix("_mhz"): f.default for f in dataclasses.fields(ClockConfig)}

# (path, width, domain, kind, changes per cycle)
_COUNTER, _RANDOM, _TOGGLE, _STATUS, _LEVEL = "counter", "random", "toggle", "status", "level"


def _signal_table() -> list[tuple[str, int, str, str, float]]:
    table = []
    for side in ("left", "right"):
        cam = f"top.cameras.{side}"
        table += [
            (f"{cam}.status", 2, "camera", _STATUS, 0.02),
            (f"{cam}.valid", 1, "camera", _TOGGLE, 0.5),
            (f"{cam}.pixels_sent", 32, "camera", _COUNTER, 0.95),
        ]
        for sub in ("sub0", "sub1"):
            nna = f"top.nna.{side}.{sub}"
            table += [
                (f"{nna}.status", 2, "nna", _STATUS, 0.05),
                (f"{nna}.line_buffer.fill", 4, "nna", _LEVEL, 0.02),
                (f"{nna}.line_buffer.row", 11, "nna", _COUNTER, 0.001),
                (f"{nna}.mac_array.phase", 16, "nna", _COUNTER, 1.0),
                (f"{nna}.mac_array.valid", 1, "nna", _TOGGLE, 0.1),
                (f"{nna}.descriptor", 32, "nna", _RANDOM, 1.0),
                (f"{nna}.col", 11, "nna", _COUNTER, 0.1),
            ]
    for name, dom in (
        ("camera_left_to_nna", "nna"),
        ("camera_right_to_nna", "nna"),
        ("nna_left_to_sva", "sva"),
        ("nna_right_to_sva", "sva"),
    ):
        fifo = f"top.fifo.{name}"
        table += [
            (f"{fifo}.occupancy", 5, dom, _LEVEL, 0.3),
            (f"{fifo}.push", 1, dom, _TOGGLE, 0.3),
            (f"{fifo}.pop", 1, dom, _TOGGLE, 0.3),
            (f"{fifo}.full", 1, dom, _TOGGLE, 0.01),
            (f"{fifo}.empty", 1, dom, _TOGGLE, 0.05),
        ]
    for stage in ("cost", "aggregation", "sgm", "wta", "lr_check"):
        sva = f"top.sva.{stage}"
        table += [
            (f"{sva}.status", 2, "sva", _STATUS, 0.05),
            (f"{sva}.valid", 1, "sva", _TOGGLE, 0.4),
            (f"{sva}.col", 11, "sva", _COUNTER, 0.25),
        ]
    table += [
        ("top.sva.cost.value", 32, "sva", _RANDOM, 1.0),
        ("top.sva.sgm.path_cost", 32, "sva", _RANDOM, 1.0),
        ("top.sva.lr_check.reject", 1, "sva", _TOGGLE, 0.05),
        ("top.sva.output.valid", 1, "sva", _TOGGLE, 0.4),
        ("top.sva.output.disparity", 8, "sva", _RANDOM, 0.25),
        ("top.sva.output.row", 11, "sva", _COUNTER, 0.0005),
    ]
    return table


def chip_clocks() -> list[Clock]:
    """The chip's three clocks with the kernel's period rounding."""
    out = []
    for name, mhz in CHIP_CLOCKS_MHZ.items():
        dom = ClockDomain(name, mhz * 1e6)
        out.append(Clock(name=name, period_fs=dom.period_fs, phase_fs=dom.phase_fs))
    return out


def _values(kind: str, width: int, n: int, rng: np.random.Generator) -> np.ndarray:
    mask = (1 << width) - 1
    if kind == _COUNTER:
        return (np.arange(1, n + 1, dtype=np.uint64) & np.uint64(mask)).astype(np.uint64)
    if kind == _TOGGLE:
        return (np.arange(1, n + 1, dtype=np.uint64) & np.uint64(1)).astype(np.uint64)
    if kind == _STATUS:
        return rng.integers(0, 4, n, dtype=np.uint64)
    if kind == _LEVEL:
        return rng.integers(0, mask + 1, n, dtype=np.uint64)
    return rng.integers(0, mask, n, dtype=np.uint64, endpoint=True)


def synthetic_log(sva_cycles: int = 100_000, seed: int = 0) -> TraceLog:
    """A log of ``sva_cycles`` SVA cycles (from t = 0) with about 60 signals."""
    rng = np.random.default_rng(seed)
    clocks = {c.name: c for c in chip_clocks()}
    end_fs = clocks["sva"].phase_fs + sva_cycles * clocks["sva"].period_fs
    signals, times, ids, values = [], [], [], []
    for i, (path, width, domain, kind, rate) in enumerate(_signal_table()):
        signals.append(Signal(path=path, width=width, domain=domain))
        clk = clocks[domain]
        n_cycles = (end_fs - 1 - clk.phase_fs) // clk.period_fs + 1
        edges = clk.phase_fs + np.arange(n_cycles, dtype=np.int64) * clk.period_fs
        t = edges[rng.random(n_cycles) < rate]
        times.append(t)
        ids.append(np.full(t.size, i, dtype=np.int32))
        values.append(_values(kind, width, t.size, rng))
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    return TraceLog(
        signals=signals,
        clocks=list(clocks.values()),
        start_fs=0,
        end_fs=int(end_fs),
        initial=np.zeros(len(signals), dtype=np.uint64),
        times_fs=t[order],
        ids=np.concatenate(ids)[order],
        values=np.concatenate(values)[order],
    )
