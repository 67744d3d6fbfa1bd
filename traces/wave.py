"""Waveform pictures of a VCD with matplotlib, for readers without a waveform viewer.

:func:`wave_png` draws the selected variables over a time window, one row each, top to bottom
in the VCD's declaration order: 1-bit wires (clocks included) as digital lines, vectors as bus
segments (two lines that cross at each change) labelled with their hexadecimal value where the
segment is wide enough for the text; unknown values (``x``/``z``) are drawn in red. Time is
labelled in ns (or us for long windows). The PNG carries no software or date metadata, so the
same input gives the same bytes.

Windows (:func:`window_units`) use the syntax of ``stereosim run --trace-window``
(:mod:`traces.window`): times with a unit (``fs``, ``ps``, ``ns``, ``us``, ``ms``, ``s``), or
bare integers in the VCD's time unit; a missing bound is the dump's first or last timestamp:
``100ns:2.5us``, ``0:40us``, ``:500ns``, ``2000000:``. Cycle and row windows need the chip's
plan, so only ``run`` takes them.
"""

from __future__ import annotations

import io
from fnmatch import fnmatchcase

import numpy as np

from stereosim.sim.errors import ConfigError
from stereosim.traces.vcdread import VcdData, VcdVar
from stereosim.traces.window import UNITS, parse_window

MAX_ROWS = 64


def window_units(spec: str | None, data: VcdData, option: str = "--window") -> tuple[int, int]:
    """``[a, b]`` in VCD time units from a window (see the module docstring); times are rounded
    inwards to whole units."""
    if spec is None:
        return data.first_time, data.last_time
    win = parse_window(spec, default=UNITS, option=option, kinds=())
    a, b = win.start, win.end
    if win.is_time:
        a = None if a is None else -(-a // data.unit_fs)
        b = None if b is None else b // data.unit_fs
    a = data.first_time if a is None else a
    b = data.last_time if b is None else b
    if not a < b:
        raise ConfigError(f"{option} {spec!r} is empty: its start must be before its end")
    if b < data.first_time or a > data.last_time:
        raise ConfigError(
            f"{option} {spec!r} is outside the dump, which runs from {data.first_time} to "
            f"{data.last_time} (x {data.unit_fs} fs)"
        )
    return a, b


def match_vars(variables: list[VcdVar], patterns: list[str]) -> list[VcdVar]:
    """The variables whose path matches any glob; ConfigError naming a few paths otherwise."""
    chosen = [v for v in variables if any(fnmatchcase(v.path, p) for p in patterns)]
    if not chosen:
        names = ", ".join(v.path for v in variables[:6]) + (", ..." if len(variables) > 6 else "")
        raise ConfigError(
            f"no signal matches {', '.join(patterns)}; the dump has {len(variables)}: {names}"
        )
    if len(chosen) > MAX_ROWS:
        raise ConfigError(
            f"{len(chosen)} signals match {', '.join(patterns)}; draw at most {MAX_ROWS} at once "
            "(narrow the patterns)"
        )
    return chosen


def _segments(times: list[int], values: list, a: int, b: int) -> list[tuple[int, int, object]]:
    """Runs ``(start, end, value)`` covering ``[a, b]`` (value None before the first change)."""
    t = np.asarray(times, dtype=np.int64)
    k0 = int(np.searchsorted(t, a, side="right"))
    k1 = int(np.searchsorted(t, b, side="right"))
    starts = [a] + t[k0:k1].tolist()
    vals = [values[k0 - 1] if k0 else None] + values[k0:k1]
    ends = starts[1:] + [b]
    runs = []
    for s, e, v in zip(starts, ends, vals):
        if runs and runs[-1][2] == v:
            runs[-1] = (runs[-1][0], e, v)
        elif e > s or not runs:
            runs.append((s, e, v))
    return runs


def wave_png(data: VcdData, variables: list[VcdVar], a: int, b: int, *,
             title: str | None = None, width_in: float = 12.0) -> bytes:
    """The picture of ``variables`` over ``[a, b]`` (VCD time units) as PNG bytes."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    span_fs = (b - a) * data.unit_fs
    unit, scale = ("us", 1e9) if span_fs >= 10**8 else ("ns", 1e6)
    k = data.unit_fs / scale  # VCD units -> plotted unit

    n = len(variables)
    dpi = 100
    fig = Figure(figsize=(width_in, 0.9 + 0.42 * n), dpi=dpi)
    label_w = min(0.45, 0.0056 * max(len(v.path) for v in variables) + 0.025)
    height_in = 0.9 + 0.42 * n
    ax = fig.add_axes((label_w, 0.55 / height_in, 0.98 - label_w, 0.42 * n / height_in))
    ax.set_xlim(a * k, b * k)
    ax.set_ylim(-0.2, n)
    axis_px = width_in * dpi * (0.98 - label_w)
    px_per_unit = axis_px / max(b - a, 1)
    black, red = [], []
    for row, var in enumerate(variables):
        y = n - 1 - row
        lo, hi = y + 0.15, y + 0.75
        times, values = data.changes.get(var.code, ([], []))
        runs = _segments(times, values, a, b)
        if var.width == 1:
            for i, (s, e, v) in enumerate(runs):
                level = hi if v == 1 else lo
                seg = [(s * k, level), (e * k, level)]
                (red if v is None else black).append(seg)
                if i and v is not None and runs[i - 1][2] is not None:
                    black.append([(s * k, lo), (s * k, hi)])
        else:
            mid = (lo + hi) / 2
            slope = min(0.25 * (e - s) for s, e, _ in runs) if runs else 0
            slope = min(slope, 3 / px_per_unit)  # 3 pixels wide crossings
            for s, e, v in runs:
                target = red if v is None else black
                # crossings at changes only, not at the window's edges
                s1 = s + slope if s > a else s
                e1 = e - slope if e < b else e
                ys, ye = (mid if s > a else None), (mid if e < b else None)
                for level in (hi, lo):
                    line = [(s1 * k, level), (e1 * k, level)]
                    if ys is not None:
                        line.insert(0, (s * k, ys))
                    if ye is not None:
                        line.append((e * k, ye))
                    target.append(line)
                if v is None:
                    continue
                label = f"{v:x}"
                if (e - s) * px_per_unit > 7.5 * len(label) + 6:
                    ax.text((s + e) / 2 * k, mid, label, ha="center", va="center", fontsize=7,
                            family="DejaVu Sans Mono")
    ax.add_collection(LineCollection(black, colors="black", linewidths=0.8))
    if red:
        ax.add_collection(LineCollection(red, colors="red", linewidths=0.8))
    ax.set_yticks([n - 1 - r + 0.45 for r in range(n)])
    ax.set_yticklabels([v.path for v in variables], fontsize=7, family="DejaVu Sans Mono")
    ax.tick_params(axis="y", length=0)
    ax.tick_params(axis="x", labelsize=7)
    ax.set_xlabel(f"time ({unit})", fontsize=8)
    ax.grid(axis="x", color="0.85", linewidth=0.5)
    for side in ("top", "right", "left"):
        ax.spines[side].set_visible(False)
    if title:
        ax.set_title(title, fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    return buf.getvalue()
