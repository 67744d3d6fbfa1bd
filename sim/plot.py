"""Plots of sweep results (``results.csv``), byte-identical for identical input.

:func:`plot_xy` draws one column against another, one line per value of an optional ``hue``
column; rows with the same hue and x (several scenes, say) are averaged and the legend says so.
Axes print plain numbers (no offset, no scientific notation) and may be logarithmic; a column
of nanoseconds or femtoseconds is drawn in us, ms or s, whichever reads best, and the label
says which. :func:`pareto_plot` shows SRAM bits against fps, coloured by accuracy, with the
Pareto-optimal points ringed and every point labelled by its configuration (the swept keys). :func:`sweep_plots` makes the built-in plots a sweep's columns allow. PNGs are
rendered with the Agg backend at a fixed size and DPI and without the ``Software`` metadata
entry, so the same CSV gives the same bytes.
"""

from __future__ import annotations

import io
import math
from collections import defaultdict
from pathlib import Path

from stereosim.sim.errors import InputError
from stereosim.sim.outputs import atomic_write_bytes

FIGSIZE = (6.4, 4.2)
DPI = 100


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
                f"column '{col}' is not in {source} (columns include: {shown}{', ...' if len(known) > 12 else ''})"
            )


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.hashsalt": "stereosim", "path.simplify": False})
    return plt, *plt.subplots(figsize=FIGSIZE, dpi=DPI)


def _png_bytes(plt, fig) -> bytes:
    buf = io.BytesIO()
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


def plot_xy(rows: list[dict], x: str, y: str, png: str | Path, *, hue: str | None = None,
            title: str | None = None, source: str = "the results", logx: bool = False,
            logy: bool = False) -> None:
    """``y`` against ``x`` (numbers, or categories in order of appearance), a line per hue;
    ``logx`` / ``logy``: logarithmic axes (their values must be positive)."""
    check_columns(rows, (x, y, hue), source)
    rows = [r for r in _ok_rows(rows) if r.get(x, "") != "" and _number(r.get(y)) is not None]
    if not rows:
        raise InputError(f"no successful rows with values in '{x}' and '{y}' in {source}")
    numeric_x = all(_number(r[x]) is not None for r in rows)
    if logx and not numeric_x:
        raise InputError(f"--logx needs numbers, but '{x}' in {source} has categories: drop "
                         "--logx")
    if logx:
        _check_log(rows, x, "--logx", source)
    if logy:
        _check_log(rows, y, "--logy", source)
    x_factor, x_label = time_scale(x, [_number(r[x]) for r in rows]) if numeric_x else (1.0, x)
    y_factor, y_label = time_scale(y, [_number(r[y]) for r in rows])
    categories = list(dict.fromkeys(r[x] for r in rows))
    groups: dict[str, dict] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        key = r.get(hue, "") if hue else ""
        xv = _number(r[x]) * x_factor if numeric_x else categories.index(r[x])
        groups[str(key)][xv].append(_number(r[y]) * y_factor)
    plt, fig, ax = _figure()
    averaged = False
    order = sorted(groups, key=lambda k: (_number(k) is None, _number(k) or 0.0, k))
    for key in order:
        pts = sorted(groups[key].items())
        averaged |= any(len(v) > 1 for _, v in pts)
        xs = [p for p, _ in pts]
        ys = [sum(v) / len(v) for _, v in pts]
        ax.plot(xs, ys, marker="o", label=f"{hue} = {key}" if hue else None)
    if not numeric_x:
        ax.set_xticks(range(len(categories)), categories, rotation=20)
    if logx:
        _log_axis(ax, "x", [v for g in groups.values() for v in g])
    elif numeric_x:
        _plain_numbers(ax, "x")
    if logy:
        _log_axis(ax, "y", [sum(v) / len(v) for g in groups.values() for v in g.values()])
    else:
        _plain_numbers(ax, "y")
    ax.set_xlabel(x_label)
    ax.set_ylabel(f"{y_label} (mean over rows)" if averaged else y_label)
    if hue:
        ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    ax.set_title(title or f"{y} vs {x}", fontsize="medium")
    _write(png, _png_bytes(plt, fig))


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


def point_labels(rows: list[dict], keys) -> dict[str, str]:
    """Each point's label: its values of those ``keys`` that differ between points, as
    ``name=value`` (the key's last dotted part when that is unambiguous); the point's number
    when no key varies."""
    first: dict[str, dict] = {}
    for r in rows:
        first.setdefault(r.get("point", ""), r)
    varying = [k for k in keys if len({str(r.get(k, "")) for r in first.values()}) > 1]
    short = {k: k.rsplit(".", 1)[-1] for k in varying}
    if len(set(short.values())) < len(short):
        short = {k: k for k in varying}
    return {p: ", ".join(f"{short[k]}={r.get(k, '')}" for k in varying) or f"point {p}"
            for p, r in first.items()}


def pareto_plot(rows: list[dict], png: str | Path, *, sram: str = "sram_bits",
                fps: str = "throughput.fps_bound", error: str | None = None,
                source: str = "the results", label_keys=()) -> None:
    """SRAM bits vs fps per point (averaged over scenes), coloured by ``error`` if given; each
    point labelled by its values of ``label_keys`` (the sweep's axes, :func:`point_labels`)."""
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
    front = pareto_front(pts)
    plt, fig, ax = _figure()
    xs, ys, cs = zip(*pts)
    colour = {"c": cs, "cmap": "viridis_r"} if error else {}
    sc = ax.scatter(xs, ys, s=40, zorder=3, **colour)
    fx = [p for p, on in zip(pts, front) if on]
    ax.scatter([p[0] for p in fx], [p[1] for p in fx], s=160, facecolors="none",
               edgecolors="red", zorder=4, label="Pareto-optimal")
    labels = point_labels(kept, label_keys)
    for k, (sx, sy, _) in zip(keys, pts):
        ax.annotate(labels[k], (sx, sy), fontsize="x-small", xytext=(3, 3),
                    textcoords="offset points")
    if error:
        fig.colorbar(sc, ax=ax, label=f"{error} (lower is better)")
    _plain_numbers(ax, "both")
    ax.set_xlabel(f"{sram} (chip SRAM)")
    ax.set_ylabel(fps + (" (work bound)" if fps.endswith("fps_bound") else ""))
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    ax.set_title("Pareto view: SRAM vs fps" + (f" vs {error}" if error else "")
                 + " (labels: the swept keys)", fontsize="medium")
    _write(png, _png_bytes(plt, fig))


def _varies(rows: list[dict], col: str) -> bool:
    return len({r.get(col) for r in rows if r.get(col, "") != ""}) > 1


def sweep_plots(rows: list[dict], axes: list[str], out_dir: str | Path) -> list[Path]:
    """The built-in plots the sweep's columns allow; returns the files written."""
    out = Path(out_dir)
    ok = _ok_rows(rows)
    if not ok:
        return []
    cols = set().union(*(r.keys() for r in ok))
    varying = [a for a in axes if _varies(ok, a)]
    written = []

    def other(*used):
        rest = [a for a in varying if a not in used]
        return rest[0] if rest else None

    totbad = next((c for c in ("metrics.nonocc.totbad", "metrics.all.totbad") if c in cols), None)
    if "nna.stereo_submodules" in varying and "throughput.fps_bound" in cols:
        p = out / "fps_vs_submodules.png"
        plot_xy(ok, "nna.stereo_submodules", "throughput.fps_bound", p,
                hue=other("nna.stereo_submodules"), title="fps vs NNA submodules (stereo pair)")
        written.append(p)
    high = "fifos.nna_left_to_sva.max_producer_occupancy"
    if "fifo.nna_to_sva_depth" in varying and high in cols:
        p = out / "fifo_highwater_vs_depth.png"
        plot_xy(ok, "fifo.nna_to_sva_depth", high, p, hue=other("fifo.nna_to_sva_depth"),
                title="NNA->SVA FIFO high-water vs depth")
        written.append(p)
    if totbad and ("sva.disparities" in varying or "sva.paths" in varying):
        x = "sva.disparities" if "sva.disparities" in varying else "sva.paths"
        hue = "sva.paths" if x == "sva.disparities" and "sva.paths" in varying else other(x)
        p = out / "totbad_vs_d_and_paths.png"
        plot_xy(ok, x, totbad, p, hue=hue, title=f"accuracy: {totbad} vs {x}")
        written.append(p)
    # functional sweeps have no measured rate: the analytic one (exact for it) stands in
    fps = next((c for c in ("throughput.fps_bound", "estimate.throughput.fps_bound")
                if c in cols), None)
    if "sram_bits" in cols and fps and len(varying) > 0:
        p = out / ("pareto_sram_fps_totbad.png" if totbad else "pareto_sram_fps.png")
        pareto_plot(ok, p, fps=fps, error=totbad, label_keys=varying)
        written.append(p)
    return written
