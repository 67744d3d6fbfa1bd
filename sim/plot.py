"""Plots of sweep results (``results.csv``), byte-identical for identical input.

:func:`plot_xy` draws one column against another, one line per value of an optional ``hue``
column; rows with the same hue and x (several scenes, say) are averaged and the legend says so.
Axes print plain numbers (no offset, no scientific notation) and may be logarithmic; a column
of nanoseconds or femtoseconds is drawn in us, ms or s, whichever reads best, and the label
says which; a frame-rate column says which rate it is (:data:`RATE_KINDS`: measured, or a work
bound); an axis whose values are all whole numbers (a count such as
``nna.stereo_submodules``) is ticked at whole numbers only. :func:`pareto_plot` shows SRAM
bits (or another cost: the chip's area in mm^2, power in mW, :data:`COSTS`) against fps,
coloured by accuracy, with the Pareto-optimal points ringed and every point labelled by its
configuration (the swept keys), the labels placed where they overlap neither one another nor
the points; with a target rate (the camera's, :func:`target_rate`, or one
given) it draws the target as a dashed line, rings only the optimal points that reach it and
boxes the least SRAM among them, or says that none does. :func:`sweep_plots`
makes the built-in plots a sweep's columns allow; they use the rate the runs measured wherever
they measured one (:func:`rate_column`: a cycle sweep's ``throughput.fps_measured``), since the
work bound can be far from it (column tiles behind shallow merge FIFOs), and
:func:`rate_gaps` names the points where the two differ by more than :data:`RATE_GAP`. Both
plotting functions return the data they drew (:func:`xy_data`, :class:`ParetoData`), so a test
can hold a plot to the CSV. PNGs are rendered with the Agg backend at a fixed size and DPI and
without the ``Software`` metadata entry, so the same CSV gives the same bytes.
"""

from __future__ import annotations

import io
import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from stereosim.core.errors import InputError
from stereosim.core.outputs import atomic_write_bytes

FIGSIZE = (6.4, 4.2)
DPI = 100

MEASURED_RATE = "throughput.fps_measured"
BOUND_RATE = "throughput.fps_bound"
# the frame-rate columns of a sweep, in the order the plots prefer them, and what each is
RATE_KINDS = {
    MEASURED_RATE: "measured, one frame alone",
    BOUND_RATE: "work bound",
    "estimate.throughput.fps_bound": "work bound, analytic estimate",
}
# a measured rate this far (as a share of the bound) from the work bound is worth a note, in a
# sweep's summary and in run's (sim/summary.py)
RATE_GAP = 0.03
# the columns that carry a sweep's target frame rate, in the order preferred: the camera's own
# rate (an estimate sweep's; a cycle or functional sweep's estimate.* copy of it)
TARGET_COLUMNS = ("throughput.camera_fps", "estimate.throughput.camera_fps")
# a point meets the target when its rate is at most this share below it (rates are rounded)
TARGET_SLACK = 1e-6


def _number(text):
    if isinstance(text, (int, float)):
        return float(text)
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def _ok_rows(rows: list[dict]) -> list[dict]:
    return [r for r in rows if r.get("status", "ok") == "ok"]


def check_columns(rows: list[dict], columns, source: str) -> None:
    # a row with more cells than the header has a None key (not a CSV a sweep wrote)
    known = {k for r in rows for k in r if isinstance(k, str)}
    for col in columns:
        if col is not None and col not in known:
            shown = ", ".join(sorted(known)[:12])
            raise InputError(
                f"column '{col}' is not in {source} "
                f"(columns include: {shown}{', ...' if len(known) > 12 else ''})"
            )


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.hashsalt": "stereosim", "path.simplify": False})
    return plt, *plt.subplots(figsize=FIGSIZE, dpi=DPI)


def _png_bytes(plt, fig, *, layout: bool = True) -> bytes:
    buf = io.BytesIO()
    if layout:
        fig.tight_layout()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def _write(path: str | Path, data: bytes) -> None:
    p = Path(path)
    if not p.parent.is_dir():
        raise InputError(f"folder {p.parent} of {p} does not exist: create it first")
    atomic_write_bytes(p, data)


# time columns in a unit too small to read, and their size in seconds
_SMALL_UNITS = {"ns": 1e-9, "fs": 1e-15}
_READABLE = (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))


def time_scale(column: str, values) -> tuple[float, str]:
    """(factor, label) to draw ``column``: a column named ``..._ns`` / ``...ns`` (or fs) is
    converted to the largest of s, ms, us in which its largest value is at least 1; any other
    column is drawn as it is."""
    unit = next((u for u in _SMALL_UNITS if column.endswith(("_" + u, "." + u))), None)
    if unit is None:
        return 1.0, column
    top = max((abs(v) for v in values), default=0.0) * _SMALL_UNITS[unit]
    name, size = next(((n, sz) for n, sz in _READABLE if top >= sz), _READABLE[-1])
    return _SMALL_UNITS[unit] / size, f"{column} (in {name})"


def _plain_numbers(ax, axis: str) -> None:
    """Tick labels as plain numbers: no offset ('+1.234e6') and no scientific notation."""
    ax.ticklabel_format(axis=axis, style="plain", useOffset=False)


def _integer_ticks(ax, axis: str, values) -> None:
    """Ticks at whole numbers only on an axis whose values are all whole (a count such as
    ``nna.stereo_submodules``: no tick at 36.5)."""
    from matplotlib.ticker import MaxNLocator

    if values and all(float(v).is_integer() for v in values):
        (ax.xaxis if axis == "x" else ax.yaxis).set_major_locator(MaxNLocator(integer=True))


def _tick_text(value, _pos=None) -> str:
    return f"{value:,.0f}" if float(value).is_integer() else f"{value:.4g}"


def _log_axis(ax, axis: str, values) -> None:
    """A logarithmic axis labelled with plain numbers; its minor ticks labelled too when the
    data span less than a decade (else no decade tick would carry a label)."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    getattr(ax, f"set_{axis}scale")("log")
    target = ax.xaxis if axis == "x" else ax.yaxis
    lo, hi = min(values), max(values)
    if hi < 10 * lo:  # narrow: as many decimals as the span needs
        places = max(0, 1 - math.floor(math.log10(hi - lo))) if hi > lo else 3
        text = FuncFormatter(lambda v, _pos: f"{v:,.{places}f}")
        target.set_major_formatter(text)
        target.set_minor_formatter(text)
    else:
        target.set_major_formatter(FuncFormatter(_tick_text))
        target.set_minor_formatter(NullFormatter())


def _check_log(rows: list[dict], col: str, flag: str, source: str) -> None:
    bad = [r[col] for r in rows if (_number(r[col]) or 0.0) <= 0]
    if bad:
        raise InputError(f"{flag} needs positive values, but '{col}' in {source} has "
                         f"{bad[0]!r}: drop {flag} or filter those rows")


def rate_label(column: str) -> str:
    """A frame-rate column named with the rate it is (:data:`RATE_KINDS`); others as they are."""
    return f"{column} ({RATE_KINDS[column]})" if column in RATE_KINDS else column


def _axis_label(column: str, values) -> tuple[float, str]:
    """(factor, label) of an axis: :func:`time_scale`'s, a rate's kind on a second line."""
    factor, label = time_scale(column, values)
    if column in RATE_KINDS:
        label = f"{column}\n({RATE_KINDS[column]})"
    return factor, label


def rate_column(rows: list[dict]) -> str | None:
    """The frame rate a sweep's plots use: the first of :data:`RATE_KINDS` that every
    successful row has -- the measured rate of a cycle sweep, else the work bound (an estimate
    sweep's; a functional sweep's analytic one). None when no column has one for every row."""
    ok = _ok_rows(rows)
    return next((c for c in RATE_KINDS if ok and all(_number(r.get(c)) is not None for r in ok)),
                None)


def rate_gaps(rows: list[dict]) -> list[dict]:
    """The successful rows whose measured rate and work bound differ by more than
    :data:`RATE_GAP` of the bound, the largest gap first (stable: then in row order)."""
    gaps = []
    for r in _ok_rows(rows):
        measured, bound = _number(r.get(MEASURED_RATE)), _number(r.get(BOUND_RATE))
        if measured is not None and bound and abs(measured / bound - 1) > RATE_GAP:
            gaps.append((-abs(measured / bound - 1), len(gaps), r))
    return [r for *_, r in sorted(gaps, key=lambda g: g[:2])]


def _hue_order(key: str) -> tuple:
    """Hue values in order: numbers by value, before text; a value of several keys
    ("288 / 64") part by part."""
    return tuple((_number(part) is None, _number(part) or 0.0, part)
                 for part in key.split(" / "))


def xy_data(rows: list[dict], x: str, y: str, *, hue: str | None = None,
            source: str = "the results") -> dict[str, list[tuple[float | str, float]]]:
    """What :func:`plot_xy` draws: per hue value (sorted; "" without ``hue``), the points
    (x, mean of ``y`` over the rows with that hue and x), in x order; categorical x values keep
    the order they first appear in."""
    check_columns(rows, (x, y, hue), source)
    rows = [r for r in _ok_rows(rows) if r.get(x, "") != "" and _number(r.get(y)) is not None]
    if not rows:
        raise InputError(f"no successful rows with values in '{x}' and '{y}' in {source}")
    numeric_x = all(_number(r[x]) is not None for r in rows)
    categories = list(dict.fromkeys(r[x] for r in rows))
    groups: dict[str, dict] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        key = r.get(hue, "") if hue else ""
        xv = _number(r[x]) if numeric_x else categories.index(r[x])
        groups[str(key)][xv].append(_number(r[y]))
    order = sorted(groups, key=_hue_order)
    return {key: [(xv if numeric_x else categories[xv], sum(v) / len(v))
                  for xv, v in sorted(groups[key].items())] for key in order}


def plot_xy(rows: list[dict], x: str, y: str, png: str | Path, *, hue: str | None = None,
            title: str | None = None, source: str = "the results", logx: bool = False,
            logy: bool = False) -> dict[str, list[tuple[float | str, float]]]:
    """``y`` against ``x`` (numbers, or categories in order of appearance), a line per hue;
    ``logx`` / ``logy``: logarithmic axes (their values must be positive). Returns what it
    drew (:func:`xy_data`)."""
    data = xy_data(rows, x, y, hue=hue, source=source)
    rows = [r for r in _ok_rows(rows) if r.get(x, "") != "" and _number(r.get(y)) is not None]
    numeric_x = all(_number(r[x]) is not None for r in rows)
    if logx and not numeric_x:
        raise InputError(f"--logx needs numbers, but '{x}' in {source} has categories: drop "
                         "--logx")
    if logx:
        _check_log(rows, x, "--logx", source)
    if logy:
        _check_log(rows, y, "--logy", source)
    x_factor, x_label = _axis_label(x, [_number(r[x]) for r in rows]) if numeric_x else (1.0, x)
    y_factor, y_label = _axis_label(y, [_number(r[y]) for r in rows])
    categories = list(dict.fromkeys(r[x] for r in rows))
    counts: dict[tuple, int] = defaultdict(int)
    for r in rows:
        counts[(str(r.get(hue, "")) if hue else "", r[x])] += 1
    averaged = any(n > 1 for n in counts.values())
    plt, fig, ax = _figure()
    for key, pts in data.items():
        xs = [p * x_factor if numeric_x else categories.index(p) for p, _ in pts]
        ys = [v * y_factor for _, v in pts]
        ax.plot(xs, ys, marker="o", label=f"{hue} = {key}" if hue else None)
    if not numeric_x:
        ax.set_xticks(range(len(categories)), categories, rotation=20)
    if logx:
        _log_axis(ax, "x", [p * x_factor for pts in data.values() for p, _ in pts])
    elif numeric_x:
        _plain_numbers(ax, "x")
        _integer_ticks(ax, "x", [p * x_factor for pts in data.values() for p, _ in pts])
    if logy:
        _log_axis(ax, "y", [v * y_factor for pts in data.values() for _, v in pts])
    else:
        _plain_numbers(ax, "y")
        _integer_ticks(ax, "y", [v * y_factor for pts in data.values() for _, v in pts])
    ax.set_xlabel(x_label)
    ax.set_ylabel(f"{y_label}, mean over rows" if averaged else y_label)
    if hue:
        ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    ax.set_title(title or f"{y} vs {x}", fontsize="medium")
    _write(png, _png_bytes(plt, fig))
    return data


def pareto_front(points: list[tuple[float, float, float]]) -> list[bool]:
    """Points (sram, fps, error) on the Pareto front: no other point is at least as good in all
    three (less SRAM, more fps, less error) and better in one."""
    front = []
    for i, (s, f, e) in enumerate(points):
        dominated = any(
            s2 <= s and f2 >= f and e2 <= e and (s2, f2, e2) != (s, f, e)
            for j, (s2, f2, e2) in enumerate(points) if j != i
        )
        front.append(not dominated)
    return front


def _label_parts(rows: list[dict], keys) -> dict[str, list[tuple[str, str]]]:
    """Each point's (name, value) of those ``keys`` that differ between points; the name is
    the key's last dotted part when that is unambiguous."""
    first: dict[str, dict] = {}
    for r in rows:
        first.setdefault(r.get("point", ""), r)
    varying = [k for k in keys if len({str(r.get(k, "")) for r in first.values()}) > 1]
    short = {k: k.rsplit(".", 1)[-1] for k in varying}
    if len(set(short.values())) < len(short):
        short = {k: k for k in varying}
    return {p: [(short[k], str(r.get(k, ""))) for k in varying] for p, r in first.items()}


def point_labels(rows: list[dict], keys) -> dict[str, str]:
    """Each point's label: its values of those ``keys`` that differ between points, as
    ``name=value`` (the key's last dotted part when that is unambiguous); the point's number
    when no key varies."""
    return {p: ", ".join(f"{k}={v}" for k, v in parts) or f"point {p}"
            for p, parts in _label_parts(rows, keys).items()}


@dataclass(frozen=True)
class ParetoPoint:
    """One point of a Pareto view: its label (the swept keys), SRAM bits, frame rate and
    error, averaged over its scenes, and whether it is Pareto-optimal."""

    point: str
    label: str
    sram: float
    fps: float
    error: float | None
    optimal: bool
    parts: tuple[tuple[str, str], ...] = ()  # the label's (name, value) pairs
    meets: bool | None = None  # reaches the view's target rate (None: no target)


@dataclass
class ParetoData:
    """What a Pareto view shows: the columns it reads and its points in point order;
    ``label_boxes`` (display pixels, x0, y0, x1, y1) once drawn: one per label, and points
    at the same place share one label; ``key`` when the labels are the points' numbers."""

    sram: str
    fps: str
    error: str | None
    points: list[ParetoPoint]
    label_boxes: list[tuple[float, float, float, float]] = field(default_factory=list)
    key: list[str] = field(default_factory=list)  # "numbers: label", when numbers label it
    target: float | None = None  # the frame rate a point must reach (None: none known)
    target_source: str = ""  # where the target comes from (a column, or an option)

    @property
    def front(self) -> list[ParetoPoint]:
        return [p for p in self.points if p.optimal]

    @property
    def ringed(self) -> list[ParetoPoint]:
        """The points the plot rings: the Pareto-optimal ones that reach the target (all of
        them without a target)."""
        return [p for p in self.points if p.optimal and p.meets is not False]

    @property
    def chosen(self) -> ParetoPoint | None:
        """The point to build with a target: the least SRAM among those that reach it (then
        the highest rate, the least error, the first); None without a target or when no point
        reaches it."""
        meeting = [p for p in self.points if p.meets]
        return min(meeting, key=lambda p: (p.sram, -p.fps, p.error or 0.0), default=None)


def target_rate(rows: list[dict]) -> tuple[float, str] | None:
    """The frame rate a sweep's points must reach and the column it comes from: the camera's
    own rate (the first of :data:`TARGET_COLUMNS` every successful row has, one value for all);
    None without a camera, or when the points' cameras differ (no one line to draw)."""
    ok = _ok_rows(rows)
    for col in TARGET_COLUMNS:
        values = {_number(r.get(col)) for r in ok}
        if ok and len(values) == 1:
            (value,) = values
            if value is not None and math.isfinite(value) and value > 0:
                return value, col
    return None


def pareto_data(rows: list[dict], *, sram: str = "sram_bits", fps: str = BOUND_RATE,
                error: str | None = None, source: str = "the results",
                label_keys=(), target_fps: float | None = None) -> ParetoData:
    """The points of a Pareto view: SRAM bits, ``fps`` and ``error`` (if given) per point,
    averaged over its scenes; the front computed on those very values. The target rate:
    ``target_fps`` if given, else the camera's rate the rows carry (:func:`target_rate`);
    each point says whether it reaches it (within :data:`TARGET_SLACK`)."""
    if target_fps is not None and not (math.isfinite(target_fps) and target_fps > 0):
        raise InputError(f"a target frame rate must be a positive number, got {target_fps}")
    check_columns(rows, (sram, fps, error), source)
    acc: dict[str, list] = defaultdict(list)
    kept = []
    for r in _ok_rows(rows):
        vals = [_number(r.get(sram)), _number(r.get(fps))]
        vals.append(_number(r.get(error)) if error else 0.0)
        if all(v is not None and math.isfinite(v) for v in vals):
            acc[r.get("point", "")].append(vals)
            kept.append(r)
    if not acc:
        raise InputError(f"no successful rows with '{sram}' and '{fps}' in {source}")
    keys = sorted(acc, key=lambda k: (_number(k) is None, _number(k) or 0.0, k))
    pts = [tuple(sum(v[i] for v in acc[k]) / len(acc[k]) for i in range(3)) for k in keys]
    labels = point_labels(kept, label_keys)
    parts = _label_parts(kept, label_keys)
    target = (target_fps, "given") if target_fps is not None else target_rate(kept)
    goal = target[0] if target else None
    return ParetoData(sram, fps, error, [
        ParetoPoint(k, labels[k], s, f, e if error else None, on, tuple(parts[k]),
                    None if goal is None else f >= goal * (1 - TARGET_SLACK))
        for k, (s, f, e), on in zip(keys, pts, pareto_front(pts))
    ], target=goal, target_source=target[1] if target else "")


def _shared_labels(points: list[ParetoPoint]) -> list[tuple[tuple[float, float], str, str]]:
    """One label per place (sram, fps): the place, its label -- a key per line, the values of
    the points drawn there joined by " / " (in point order); a point without varying keys is
    named by its number -- and the numbers of its points."""
    places: dict[tuple[float, float], list[ParetoPoint]] = {}
    for p in points:
        places.setdefault((p.sram, p.fps), []).append(p)
    out = []
    for where, group in places.items():
        numbers = ", ".join(p.point for p in group)
        if not group[0].parts:
            out.append((where, ", ".join(p.label for p in group), numbers))
            continue
        lines = []
        for i, (name, _) in enumerate(group[0].parts):
            values = list(dict.fromkeys(p.parts[i][1] for p in group))
            lines.append(f"{name}={' / '.join(values)}")
        out.append((where, "\n".join(lines), numbers))
    return out


# label offsets tried around a point, in points: the directions (x, y), then farther out
_DIRECTIONS = ((1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))
_DISTANCES = (4, 10, 18, 30, 45, 65, 90)
_MARKER_PT = 7.0  # half the ring's size: a label keeps off every marker by this much
_MAX_PLACED = 200  # more labels than this are placed beside their points unchecked


def _area(a, b) -> float:
    """The area two boxes (x0, y0, x1, y1) share."""
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def _gap(box, point) -> float:
    """The distance from a point to a box (0 inside it)."""
    dx = max(box[0] - point[0], 0.0, point[0] - box[2])
    dy = max(box[1] - point[1], 0.0, point[1] - box[3])
    return math.hypot(dx, dy)


def _place_labels(fig, ax, anchors, texts) -> tuple[list[tuple[float, float, float, float]],
                                                     bool]:
    """Annotate each anchor (data coordinates) with its text at the first offset around it
    (:data:`_DIRECTIONS` x :data:`_DISTANCES`) where the text lies inside the axes, overlaps
    neither a label placed before it nor a marker, and is nearer its own point than any other;
    if none is, at the offset that overlaps least (nearer another point if it must). Offsets
    beyond the nearest get a leader line. Returns the labels' boxes in display pixels and
    whether every label found a place without overlap. Deterministic: the same order, the same
    places."""
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    inside = (frame.x0, frame.y0, frame.x1, frame.y1)
    r = _MARKER_PT * fig.dpi / 72.0
    points = [tuple(p) for p in ax.transData.transform(anchors)]
    marks = [(x - r, y - r, x + r, y + r) for x, y in points]
    placed: list[tuple[float, float, float, float]] = []
    clear = True
    offsets = [(dx * d, dy * d) for d in _DISTANCES for dx, dy in _DIRECTIONS]
    if len(texts) > _MAX_PLACED:
        offsets = offsets[:1]
    def note(anchor, text, ox, oy, leader: bool):
        return ax.annotate(
            text, anchor, xytext=(ox, oy), textcoords="offset points", fontsize="x-small",
            zorder=5, ha="left" if ox > 0 else "right" if ox < 0 else "center",
            va="bottom" if oy > 0 else "top" if oy < 0 else "center",
            arrowprops={"arrowstyle": "-", "lw": 0.7, "color": "0.35"} if leader else None)

    for anchor, own, text in zip(anchors, points, texts):
        best = None
        for ox, oy in offsets:
            trial = note(anchor, text, ox, oy, False)  # measured without its leader line
            e = trial.get_window_extent(renderer)
            trial.remove()
            box = (e.x0, e.y0, e.x1, e.y1)
            outside = (box[2] - box[0]) * (box[3] - box[1]) - _area(box, inside)
            cost = outside + sum(_area(box, b) for b in placed + marks)
            # a label nearer another point than its own reads as that point's: a place to
            # avoid, though not an overlap (areas are in square pixels)
            cost += 0.5 * any(_gap(box, q) < _gap(box, own) for q in points if q != own)
            if best is None or cost < best[0]:
                best = (cost, ox, oy, box)
            if cost <= 0:
                break
        cost, ox, oy, box = best
        note(anchor, text, ox, oy, max(abs(ox), abs(oy)) > _DISTANCES[0])
        placed.append(box)
        clear = clear and cost < 1.0
    return placed, clear


# the cost columns a Pareto view may put on its x axis besides SRAM bits: (column suffix,
# what it is, its unit); sim.sweep.area_columns writes them
COSTS = (("_mm2", "chip area", "mm^2"), ("_mw", "average power", "mW"))


def _cost_kind(column: str) -> tuple[str, str] | None:
    """(what, unit) of a cost column in mm^2 or mW (:data:`COSTS`); None: SRAM bits."""
    return next(((what, unit) for end, what, unit in COSTS if column.endswith(end)), None)


def _bits_unit(data: ParetoData) -> tuple[float, str]:
    """(x per unit, unit) for the cost axis: mm^2 or mW as they are (:data:`COSTS`); SRAM in M
    bits, k bits or bits, whichever keeps its largest value at least 1 (eight-digit tick
    labels run into each other)."""
    kind = _cost_kind(data.sram)
    if kind is not None:
        return 1.0, kind[1]
    top = max(p.sram for p in data.points)
    return next(((size, name) for size, name in ((1e6, "M bits"), (1e3, "k bits"))
                 if top >= size), (1.0, "bits"))


def _cost_name(data: ParetoData) -> str:
    kind = _cost_kind(data.sram)
    return "SRAM" if kind is None else kind[0]


def _target_words(data: ParetoData) -> str:
    """The title's two lines on the target: where it comes from, then what is ringed and
    boxed, or that no point reaches it and the best rate there is."""
    where = "" if data.target_source == "given" else f" ({data.target_source})"
    goal = f"dashed: target {data.target:,.4g} fps{where}; faded: below it"
    if data.chosen is None:
        best = max(p.fps for p in data.points)
        return f"{goal}\nno point reaches it (best {best:,.4g} fps): none ringed"
    return (f"{goal}\nringed: Pareto-optimal at or above it; boxed: the least "
            f"{_cost_name(data)} there")


def _pareto_axes(data: ParetoData, key: list[str] | None):
    """The Pareto view without its labels; with a ``key`` (lines "numbers: label"), a wider
    figure with the key to the right of the plot. Laid out before the labels are placed (a
    layout moves the axes). With a target: its line, the points below it faded, the
    Pareto-optimal points that reach it ringed and the least SRAM among them boxed; none
    ringed when no point reaches it (the title says so). The target line, the rings and the
    box carry the gids ``target``, ``ringed`` and ``chosen``."""
    plt, fig, ax = _figure()
    if key:
        fig.set_size_inches(FIGSIZE[0] + 3.8, max(FIGSIZE[1], 0.14 * len(key) + 1.4))
    scale, unit = _bits_unit(data)
    xs = [p.sram / scale for p in data.points]
    ys = [p.fps for p in data.points]
    colour = {"c": [p.error for p in data.points], "cmap": "viridis_r"} if data.error else {}
    sc = ax.scatter(xs, ys, s=40, zorder=3, **colour)
    short = [p for p in data.points if p.meets is False]
    if short:  # faded: they miss the target
        ax.scatter([p.sram / scale for p in short], [p.fps for p in short], s=40, c="white",
                   alpha=0.65, linewidths=0, zorder=3.5)
    ax.scatter([p.sram / scale for p in data.ringed], [p.fps for p in data.ringed], s=160,
               facecolors="none", edgecolors="red", zorder=4, gid="ringed")
    if data.chosen is not None:
        ax.scatter([data.chosen.sram / scale], [data.chosen.fps], s=330, marker="s",
                   facecolors="none", edgecolors="black", linewidths=1.4, zorder=4,
                   gid="chosen")
    if data.target is not None:
        ax.axhline(data.target, color="tab:red", linestyle="--", linewidth=1.1, zorder=2,
                   gid="target")
    if data.error:
        fig.colorbar(sc, ax=ax, label=f"{data.error} (lower is better)")
    _plain_numbers(ax, "both")
    ax.margins(x=0.25, y=0.2)
    kind = _cost_kind(data.sram)
    ax.set_xlabel(f"{data.sram} ({kind[0] if kind else 'chip SRAM'}, in {unit})")
    ax.set_ylabel(_axis_label(data.fps, ys)[1])
    ax.grid(True, alpha=0.3)
    labels = "numbers: the points (key on the right)" if key else "labels: the swept keys"
    marks = (f"ringed: Pareto-optimal; {labels}" if data.target is None
             else f"{_target_words(data)}\n{labels}")
    ax.set_title(f"Pareto view: {_cost_name(data)} vs fps"
                 + (f" vs {data.error}" if data.error else "") + f"\n{marks}",
                 fontsize="medium")
    if key:
        fig.tight_layout(rect=(0, 0, 0.62, 1))
        fig.text(0.64, 0.97, "\n".join(key), va="top", ha="left", fontsize="x-small")
    else:
        fig.tight_layout()
    return plt, fig, ax


def pareto_plot(rows: list[dict], png: str | Path, *, sram: str = "sram_bits",
                fps: str = BOUND_RATE, error: str | None = None,
                source: str = "the results", label_keys=(),
                target_fps: float | None = None) -> ParetoData:
    """SRAM bits vs ``fps`` per point (averaged over scenes), coloured by ``error`` if given;
    the Pareto-optimal points (on the plotted values) ringed -- with a target rate
    (``target_fps``, else the camera's rate the rows carry: :func:`target_rate`) a dashed line
    at it, only those that reach it ringed, the least SRAM among them boxed, and the title
    saying so, or that no point reaches it; each point labelled by its values of
    ``label_keys`` (the sweep's axes, :func:`point_labels`) where the labels overlap neither
    one another nor the points -- or, where they cannot, by its number, with a key beside the
    plot (``ParetoData.key``). Returns what it drew (:func:`pareto_data`, with the labels'
    boxes)."""
    data = pareto_data(rows, sram=sram, fps=fps, error=error, source=source,
                       label_keys=label_keys, target_fps=target_fps)
    places = _shared_labels(data.points)
    scale = _bits_unit(data)[0]
    anchors = [(sram / scale, fps) for (sram, fps), _, _ in places]
    key = [f"{numbers}: {text.replace(chr(10), ', ')}" for _, text, numbers in places]
    plt, fig, ax = _pareto_axes(data, None)
    boxes, clear = _place_labels(fig, ax, anchors, [text for _, text, _ in places])
    if not clear:
        plt.close(fig)
        plt, fig, ax = _pareto_axes(data, key)
        boxes, _ = _place_labels(fig, ax, anchors, [numbers for _, _, numbers in places])
        data.key = key
    data.label_boxes = boxes
    _write(png, _png_bytes(plt, fig, layout=False))
    return data


def _varies(rows: list[dict], col: str) -> bool:
    return len({r.get(col) for r in rows if r.get(col, "") != ""}) > 1


def _totbad(cols) -> str | None:
    return next((c for c in ("metrics.nonocc.totbad", "metrics.all.totbad") if c in cols), None)


def sweep_pareto(rows: list[dict], axes: list[str], target_fps: float | None = None, *,
                 cost: str = "sram_bits") -> ParetoData | None:
    """A Pareto view a sweep's plots show (None when its columns allow none): ``cost`` (chip
    SRAM bits; ``area_mm2``, mW: :data:`COSTS`) against the rate :func:`rate_column` picks,
    coloured by totbad when the scenes are scored, each point labelled by the swept keys that
    vary; the target ``target_fps``, else the camera's rate the rows carry
    (:func:`target_rate`). A cost some row leaves empty (area at a node without an SRAM
    figure) gives no view."""
    ok = _ok_rows(rows)
    cols = set().union(*(r.keys() for r in ok)) if ok else set()
    varying = [a for a in axes if _varies(ok, a)]
    fps = rate_column(ok)
    if cost not in cols or not fps or not varying:
        return None
    if any(_number(r.get(cost)) is None for r in ok):
        return None
    return pareto_data(ok, sram=cost, fps=fps, error=_totbad(cols), label_keys=varying,
                       target_fps=target_fps)


def sweep_plots(rows: list[dict], axes: list[str], out_dir: str | Path,
                target_fps: float | None = None) -> list[Path]:
    """The built-in plots the sweep's columns allow; returns the files written. Frame rates
    are the measured ones where the runs measured them (:func:`rate_column`); the Pareto
    view's target is ``target_fps``, else the camera's rate the rows carry."""
    out = Path(out_dir)
    ok = _ok_rows(rows)
    if not ok:
        return []
    cols = set().union(*(r.keys() for r in ok))
    varying = [a for a in axes if _varies(ok, a)]
    written = []

    def other(*used) -> tuple[list[dict], str | None]:
        """The rows and the hue beside the plotted keys: the one other swept key that varies,
        or all of them together (a column added to the rows), never an average over one."""
        rest = [a for a in varying if a not in used]
        if len(rest) < 2:
            return ok, rest[0] if rest else None
        name = " / ".join(rest)
        return [{**r, name: " / ".join(str(r.get(a, "")) for a in rest)} for r in ok], name

    totbad = _totbad(cols)
    fps = rate_column(ok)
    if "nna.stereo_submodules" in varying and fps:
        p = out / "fps_vs_submodules.png"
        hued, hue = other("nna.stereo_submodules")
        plot_xy(hued, "nna.stereo_submodules", fps, p, hue=hue,
                title="fps vs NNA submodules (stereo pair)")
        written.append(p)
    high = "fifos.nna_left_to_sva.max_producer_occupancy"
    if "fifo.nna_to_sva_depth" in varying and high in cols:
        p = out / "fifo_highwater_vs_depth.png"
        hued, hue = other("fifo.nna_to_sva_depth")
        plot_xy(hued, "fifo.nna_to_sva_depth", high, p, hue=hue,
                title="NNA->SVA FIFO high-water vs depth")
        written.append(p)
    if totbad and ("sva.disparities" in varying or "sva.paths" in varying):
        x = "sva.disparities" if "sva.disparities" in varying else "sva.paths"
        p = out / "totbad_vs_d_and_paths.png"
        hued, hue = other(x)
        plot_xy(hued, x, totbad, p, hue=hue, title=f"accuracy: {totbad} vs {x}")
        written.append(p)
    for cost, name in (("sram_bits", "sram"), ("area_mm2", "area"), ("power_mw", "power")):
        view = sweep_pareto(ok, axes, target_fps, cost=cost)
        if view is not None:
            p = out / f"pareto_{name}_fps{'_totbad' if view.error else ''}.png"
            pareto_plot(ok, p, sram=cost, fps=view.fps, error=view.error, label_keys=varying,
                        target_fps=target_fps)
            written.append(p)
    return written
