"""Waveform pictures of a dump (VCD or FST) with matplotlib, for readers without a waveform viewer.

:func:`wave_png` draws the selected variables over a time window, one row each, top to bottom
in the dump's declaration order, and writes values as GTKWave's save file shows them
(:mod:`traces.gtkw`, one rule for both):

* 1-bit wires (clocks included) as digital lines;
* ``status`` signals as a strip of blocks filled with the status's GTKWave colour (none, green,
  orange, red) and named -- ``idle``, ``busy``, ``starved``, ``blocked`` -- where a block is
  wide enough, with a legend above the rows (:data:`traces.gtkw.STATUS_NAMES`,
  :data:`traces.gtkw.STATUS_COLOURS`); where the status changes every pixel or so the colours
  blend rather than the dividers making a black bar;
* counts -- rows, columns, fill levels, occupancies, words, counters
  (:data:`traces.gtkw.COUNT_NAMES`) -- in decimal, other vectors (descriptors, costs) in
  hexadecimal, their row name marked ``(hex)``; a value is written where its segment is wide
  enough for the text;
* unknown values (``x``/``z``, from other simulators' dumps) in red, with a legend entry.

Time is labelled in ns (or us for long windows); a cycle window adds that clock's cycle numbers
along the top. The PNG carries no software or date metadata, so the same input gives the same
bytes.

Windows (:func:`window_units`) use the syntax of ``stereosim run --trace-window``
(:mod:`traces.window`):

* times with a unit (``fs``, ``ps``, ``ns``, ``us``, ``ms``, ``s``), or bare integers in the
  dump's time unit; a missing bound is the dump's first or last instant: ``100ns:2.5us``,
  ``0:40us``, ``:500ns``, ``2000000:``;
* cycles of a clock the dump holds, ``sva:A:B``, ``nna:A:B``, ``camera:A:B``: cycle ``k`` starts
  at the clock's rising edge ``k``, ``phase + k * period``, as in ``run``. The period and phase
  are read off the dump's own clock wire (``clocks.sva``): the spacing of its rising edges, and
  the first one modulo the period (0 for the chip's clocks);
* ``rows:A:B`` is refused: its instants come from the run (the line buffer's and the sink's
  rows), which a dump does not hold.

Without ``--signals`` the picture is an overview: every ``status`` signal when the dump has
some (:data:`OVERVIEW`), else every signal.
"""

from __future__ import annotations

import functools
import io
from dataclasses import dataclass

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.traces.gtkw import STATUS_COLOURS, STATUS_NAMES, STATUS_SUFFIX, datafmt_of
from stereosim.traces.log import CLOCK_SCOPE, match_paths
from stereosim.traces.vcdread import MAX_TIME, VcdData, VcdVar
from stereosim.traces.window import DOMAINS, ROWS, UNITS, Window, parse_window

MAX_ROWS = 64
#: The default selection of a dump that has status signals: one row per block and stage.
OVERVIEW = ("*" + STATUS_SUFFIX,)
#: The fill of a status segment: its GTKWave colour, light enough to read black text on.
STATUS_ALPHA = 0.45
UNKNOWN_COLOUR = "red"
MIN_BLOCK_PX = 3
#: The fonts of the picture: names and values in the monospaced one, the title in the other.
MONO_FONT, TEXT_FONT = "DejaVu Sans Mono", "DejaVu Sans"


@dataclass(frozen=True)
class CycleClock:
    """A clock of the dump, in dump time units: rising edge ``k`` at ``phase + k * period``."""

    name: str
    phase: int
    period: int


def parse_wave_window(spec: str | None, option: str = "--window") -> Window:
    """``spec`` parsed as ``wave`` reads it (see the module docstring); ConfigError for a rows
    window or a malformed one, before any dump is read."""
    win = parse_window(spec, default=UNITS, option=option, kinds=(*DOMAINS, ROWS))
    if win.kind == ROWS:
        raise ConfigError(
            f"{option} {spec!r}: a rows window needs the run's row instants, which a dump does "
            "not hold: give stereosim run --trace-window rows:A:B, or here a time or cycle "
            "window, e.g. 0:40us or sva:0:3000"
        )
    return win


def clock_var(spec: str | None, variables: list[VcdVar],
              option: str = "--window") -> VcdVar | None:
    """The clock wire a cycle window ``spec`` is counted on (None for a time window);
    ConfigError naming the dump's clocks if it has no such clock."""
    win = parse_wave_window(spec, option)
    if win.kind not in DOMAINS:
        return None
    path = f"{CLOCK_SCOPE}.{win.kind}"
    for var in variables:
        if var.path == path and var.width == 1:
            return var
    have = [v.path for v in variables if v.path.startswith(CLOCK_SCOPE + ".") and v.width == 1]
    raise ConfigError(
        f"{option} {spec!r} counts cycles of {path}, which the dump does not hold "
        f"(its clocks: {', '.join(have) or 'none'}): give a time window, e.g. 0:40us"
    )


def window_clock(spec: str | None, data: VcdData, option: str = "--window") -> CycleClock | None:
    """The clock of a cycle window, its period and phase read off the dump's rising edges
    (:class:`CycleClock`); None for a time window. ConfigError if the wire holds fewer than two
    rising edges or they are not evenly spaced."""
    var = clock_var(spec, data.vars, option)
    if var is None:
        return None
    times, values = data.changes[var.code]
    t = np.asarray(times, dtype=np.int64)
    v = np.asarray([-1 if x is None else x for x in values], dtype=np.int64)
    rising = t[1:][(v[1:] == 1) & (v[:-1] == 0)]
    if rising.size < 2:
        raise ConfigError(
            f"{option} {spec!r}: {var.path} has {rising.size} rising edge(s) in the dump, too "
            "few to tell its period: give a time window, e.g. 0:40us"
        )
    gaps = np.diff(rising)
    if not (gaps == gaps[0]).all():
        raise ConfigError(
            f"{option} {spec!r}: the rising edges of {var.path} are not evenly spaced (gaps "
            f"{int(gaps.min())} to {int(gaps.max())} time units), so it counts no cycles: give "
            "a time window, e.g. 0:40us"
        )
    period = int(gaps[0])
    return CycleClock(var.path[len(CLOCK_SCOPE) + 1:], int(rising[0]) % period, period)


def window_units(spec: str | None, data: VcdData, option: str = "--window") -> tuple[int, int]:
    """``[a, b]`` in dump time units from a window (see the module docstring); times are
    rounded inwards to whole units. A cycle window needs its clock's changes in ``data``."""
    if spec is None:
        return data.first_time, data.last_time
    win = parse_wave_window(spec, option)
    a, b = win.start, win.end
    if win.is_time:
        a = None if a is None else -(-a // data.unit_fs)
        b = None if b is None else b // data.unit_fs
    elif win.kind in DOMAINS:
        clk = window_clock(spec, data, option)
        a = None if a is None else clk.phase + a * clk.period
        b = None if b is None else clk.phase + b * clk.period
    a = data.first_time if a is None else a
    b = data.last_time if b is None else b
    if b > MAX_TIME:  # (a cycle window's end past the last instant a dump can hold)
        raise ConfigError(
            f"{option} {spec!r} ends at {b} time units, after the last instant a dump can "
            f"hold (2**63 - 1); the dump runs from {data.first_time} to {data.last_time}"
        )
    if not a < b:
        raise ConfigError(f"{option} {spec!r} is empty: its start must be before its end")
    if b < data.first_time or a > data.last_time:
        raise ConfigError(
            f"{option} {spec!r} is outside the dump, which runs from {data.first_time} to "
            f"{data.last_time} (x {data.unit_fs} fs)"
        )
    return a, b


def match_vars(variables: list[VcdVar], patterns: tuple[str, ...] | list[str]) -> list[VcdVar]:
    """The variables whose path matches any glob, in the dump's order (each pattern must match
    one, as for ``run --signals``: traces.log.match_paths); no patterns is the overview (see the
    module docstring). ConfigError above :data:`MAX_ROWS`."""
    if not patterns:
        has_status = any(v.path.endswith(STATUS_SUFFIX) and v.width > 1 for v in variables)
        patterns = OVERVIEW if has_status else ("*",)
    chosen = [variables[i] for i in match_paths([v.path for v in variables], patterns)]
    if len(chosen) > MAX_ROWS:
        raise ConfigError(
            f"{len(chosen)} signals match {', '.join(patterns)}; draw at most {MAX_ROWS} at once "
            "(narrow them with --signals)"
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


def value_text(var: VcdVar, value: int) -> str:
    """A known value as the picture writes it: a status by name, a count in decimal, any other
    vector in hexadecimal (traces.gtkw.datafmt_of)."""
    if var.path.endswith(STATUS_SUFFIX) and 0 <= value < len(STATUS_NAMES):
        return STATUS_NAMES[value]
    return str(value) if datafmt_of(var.path, var.width) == "dec" else f"{value:x}"


def _row_name(var: VcdVar) -> str:
    hexa = var.width > 1 and datafmt_of(var.path, var.width) == "hex"
    return f"{var.path} (hex)" if hexa else var.path


def _status_colour(var: VcdVar, value) -> str | None:
    """The fill of a status segment (None: no fill)."""
    if value is None or not 0 <= value < len(STATUS_COLOURS):
        return None
    return STATUS_COLOURS[value]


@functools.lru_cache(maxsize=4)
def _glyphs(family: str) -> frozenset[int]:
    """The code points the font ``family`` draws (the font matplotlib picks for it)."""
    from matplotlib import font_manager
    from matplotlib.ft2font import FT2Font

    path = font_manager.findfont(font_manager.FontProperties(family=family))
    return frozenset(FT2Font(path).get_charmap())


def drawable(text: str, family: str) -> str:
    """``text`` with each character the font has no glyph for, and each control character,
    written as ``?`` -- what matplotlib would draw as an empty box, with a warning on stderr."""
    glyphs = _glyphs(family)
    return "".join(c if c.isprintable() and ord(c) in glyphs else "?" for c in text)


def wave_png(data: VcdData, variables: list[VcdVar], a: int, b: int, *,
             title: str | None = None, clock: CycleClock | None = None,
             width_in: float = 12.0) -> bytes:
    """The picture of ``variables`` over ``[a, b]`` (dump time units) as PNG bytes; ``clock``
    (a cycle window's) numbers its cycles along the top."""
    fig = wave_figure(data, variables, a, b, title=title, clock=clock, width_in=width_in)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, metadata={"Software": None})
    return buf.getvalue()


def wave_figure(data: VcdData, variables: list[VcdVar], a: int, b: int, *,
                title: str | None = None, clock: CycleClock | None = None,
                width_in: float = 12.0):
    """The matplotlib Figure :func:`wave_png` saves (its texts and legend are what a reader
    sees)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import to_rgba
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.ticker import MaxNLocator

    span_fs = (b - a) * data.unit_fs
    unit, scale = ("us", 1e9) if span_fs >= 10**8 else ("ns", 1e6)
    k = data.unit_fs / scale  # dump units -> plotted unit

    n = len(variables)
    row_in, bottom_in = 0.42, 0.55
    statuses = [v for v in variables if v.path.endswith(STATUS_SUFFIX) and v.width > 1]
    names = [_row_name(v) for v in variables]
    width_px = width_in * 100
    label_w = min(0.45, 0.0062 * max(len(s) for s in names) + 0.025)
    px_per_unit = width_px * (0.98 - label_w) / max(b - a, 1)
    # plotted from the window's start when floats cannot tell its ends apart in dump time
    # (a window of a few units at 10**18): matplotlib refuses equal limits
    origin = a if abs(a) * k * 1e-9 > (b - a) * k else 0
    black, red, polys, faces, labels = _row_shapes(data, variables, a, b, k, px_per_unit,
                                                   origin)

    legend = []
    if statuses:
        legend += [Patch(facecolor=to_rgba(c, STATUS_ALPHA) if c else "white", edgecolor="0.3",
                         linewidth=0.6, label=name)
                   for name, c in zip(STATUS_NAMES, STATUS_COLOURS)]
    if red:
        legend.append(Line2D([], [], color=UNKNOWN_COLOUR, linewidth=1.2, label="unknown (x/z)"))
    top_in = 0.2 + (0.3 if title else 0) + (0.32 if legend else 0) + (0.4 if clock else 0)
    height_in = top_in + row_in * n + bottom_in
    fig = Figure(figsize=(width_in, height_in), dpi=100)
    ax = fig.add_axes((label_w, bottom_in / height_in, 0.98 - label_w, row_in * n / height_in))
    ax.set_xlim((a - origin) * k, (b - origin) * k)
    ax.set_ylim(-0.2, n)
    if polys:
        ax.add_collection(PolyCollection(polys, facecolors=faces, edgecolors="none"))
    ax.add_collection(LineCollection(black, colors="black", linewidths=0.8))
    if red:
        ax.add_collection(LineCollection(red, colors=UNKNOWN_COLOUR, linewidths=0.8))
    for x, y, text in labels:
        ax.text(x, y, text, ha="center", va="center", fontsize=7.5, family=MONO_FONT)
    ax.set_yticks([n - 1 - r + 0.45 for r in range(n)])
    ax.set_yticklabels([drawable(name, MONO_FONT) for name in names], fontsize=8,
                       family=MONO_FONT, parse_math=False)
    ax.tick_params(axis="y", length=0)
    ax.tick_params(axis="x", labelsize=8)
    ax.set_xlabel(f"time ({unit})" if not origin else
                  f"time ({unit}) after {origin} x {data.unit_fs} fs", fontsize=8)
    ax.grid(axis="x", color="0.85", linewidth=0.5)
    for side in ("top", "right", "left"):
        ax.spines[side].set_visible(False)
    if clock is not None:
        def to_cycles(x):
            return (np.asarray(x) / k + (origin - clock.phase)) / clock.period

        def to_time(c):
            return (np.asarray(c) * clock.period - (origin - clock.phase)) * k

        top = ax.secondary_xaxis("top", functions=(to_cycles, to_time))
        top.xaxis.set_major_locator(MaxNLocator(integer=True))
        top.tick_params(labelsize=8)
        top.set_xlabel(f"{clock.name} cycle", fontsize=8)
    if title:
        fig.suptitle(drawable(title, TEXT_FONT), fontsize=10, y=1 - 0.08 / height_in,
                     va="top", family=TEXT_FONT, parse_math=False)
    if legend:
        y_in = height_in - 0.2 - (0.3 if title else 0)
        fig.legend(handles=legend, loc="upper right", bbox_to_anchor=(0.98, y_in / height_in),
                   ncol=len(legend), fontsize=8, frameon=False, handlelength=1.6,
                   columnspacing=1.2)
    return fig


def _row_shapes(data: VcdData, variables: list[VcdVar], a: int, b: int, k: float,
                px_per_unit: float, origin: int = 0) -> tuple[list, list, list, list, list]:
    """What :func:`wave_figure` draws of each row, top row first, in plotted units (``k`` per
    dump unit): the black and the red (unknown) polylines, the status blocks' polygons and
    their fills, and the value labels ``(x, y, text)`` that fit their segment."""
    from matplotlib.colors import to_rgba

    def x(t) -> float:  # a dump instant (exact integer) -> plotted units
        return (t - origin) * k

    n = len(variables)
    black, red, polys, faces, labels = [], [], [], [], []
    for row, var in enumerate(variables):
        y = n - 1 - row
        lo, hi = y + 0.15, y + 0.75
        times, values = data.changes.get(var.code, ([], []))
        runs = _segments(times, values, a, b)
        if var.width == 1:
            for i, (s, e, v) in enumerate(runs):
                level = hi if v == 1 else lo
                seg = [(x(s), level), (x(e), level)]
                (red if v is None else black).append(seg)
                if i and v is not None and runs[i - 1][2] is not None:
                    black.append([(x(s), lo), (x(s), hi)])
            continue
        mid = (lo + hi) / 2
        if var.path.endswith(STATUS_SUFFIX):
            # a status row is a strip of coloured blocks, outlined, with a divider at each change
            # between blocks both at least MIN_BLOCK_PX wide: where it changes every pixel or
            # so, the colours blend instead of the dividers drawing a black bar
            black.extend([[(x(a), hi), (x(b), hi)], [(x(a), lo), (x(b), lo)]])
            for i, (s, e, v) in enumerate(runs):
                colour = _status_colour(var, v)
                if colour is not None:
                    polys.append([(x(s), lo), (x(s), hi), (x(e), hi), (x(e), lo)])
                    faces.append(to_rgba(colour, STATUS_ALPHA))
                wide = (e - s) * px_per_unit >= MIN_BLOCK_PX
                if i and wide and (s - runs[i - 1][0]) * px_per_unit >= MIN_BLOCK_PX:
                    black.append([(x(s), lo), (x(s), hi)])
                if v is None:
                    red.extend([[(x(s), hi), (x(e), hi)], [(x(s), lo), (x(e), lo)]])
                    continue
                text = value_text(var, v)
                if (e - s) * px_per_unit > 7 * len(text) + 6:
                    labels.append(((x(s) + x(e)) / 2, mid, text))
            continue
        slope = min(0.25 * (e - s) for s, e, _ in runs) if runs else 0
        slope = min(slope, 3 / px_per_unit)  # 3 pixels wide crossings
        for s, e, v in runs:
            target = red if v is None else black
            # crossings at changes only, not at the window's edges
            s1 = x(s) + slope * k if s > a else x(s)
            e1 = x(e) - slope * k if e < b else x(e)
            left = [(x(s), mid)] if s > a else []
            right = [(x(e), mid)] if e < b else []
            for level in (hi, lo):
                target.append(left + [(s1, level), (e1, level)] + right)
            if v is None:
                continue
            text = value_text(var, v)
            if (e - s) * px_per_unit > 7 * len(text) + 6:
                labels.append(((x(s) + x(e)) / 2, mid, text))

    return black, red, polys, faces, labels
