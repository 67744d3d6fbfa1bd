"""Plots of sweep results (``results.csv``), byte-identical for identical input.

:func:`plot_xy` draws one column against another, one line per value of an optional ``hue``
column; rows with the same hue and x (several scenes, say) are averaged and the legend says so.
:func:`pareto_plot` shows SRAM bits against fps, coloured by accuracy, with the Pareto-optimal
points ringed. :func:`sweep_plots` makes the built-in plots a sweep's columns allow. PNGs are
rendered with the Agg backend at a fixed size and DPI and without the ``Software`` metadata
entry, so the same CSV gives the same bytes.
"""

from __future__ import annotations

import io
import math
from collections import defaultdict
from pathlib import Path

from sim.errors import InputError
from sim.outputs import atomic_write_bytes

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


def plot_xy(rows: list[dict], x: str, y: str, png: str | Path, *, hue: str | None = None,
            title: str | None = None, source: str = "the results") -> None:
    """``y`` against ``x`` (numbers, or categories in order of appearance), a line per hue."""
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
    ax.set_xlabel(x)
    ax.set_ylabel(f"{y} (mean over rows)" if averaged else y)
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


def pareto_plot(rows: list[dict], png: str | Path, *, sram: str = "sram_bits",
                fps: str = "throughput.fps", error: str | None = None,
                source: str = "the results") -> None:
    """SRAM bits vs fps per point (averaged over scenes), coloured by ``error`` if given."""
    check_columns(rows, (sram, fps, error), source)
    acc: dict[str, list] = defaultdict(list)
    for r in _ok_rows(rows):
        vals = [_number(r.get(sram)), _number(r.get(fps))]
        vals.append(_number(r.get(error)) if error else 0.0)
        if all(v is not None and math.isfinite(v) for v in vals):
            acc[r.get("point", "")].append(vals)
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
    for k, (sx, sy, _) in zip(keys, pts):
        ax.annotate(str(k), (sx, sy), fontsize="x-small", xytext=(3, 3),
                    textcoords="offset points")
    if error:
        fig.colorbar(sc, ax=ax, label=f"{error} (lower is better)")
    ax.set_xlabel(f"{sram} (chip SRAM)")
    ax.set_ylabel(fps)
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)
    ax.set_title("Pareto view: SRAM vs fps" + (f" vs {error}" if error else "")
                 + " (labels: point)", fontsize="medium")
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
    if "nna.stereo_submodules" in varying and "throughput.fps" in cols:
        p = out / "fps_vs_submodules.png"
        plot_xy(ok, "nna.stereo_submodules", "throughput.fps", p,
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
    fps = next((c for c in ("throughput.fps", "estimate.throughput.fps") if c in cols), None)
    if "sram_bits" in cols and fps and len(varying) > 0:
        p = out / ("pareto_sram_fps_totbad.png" if totbad else "pareto_sram_fps.png")
        pareto_plot(ok, p, fps=fps, error=totbad)
        written.append(p)
    return written
