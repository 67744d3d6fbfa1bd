"""A one-page HTML report of a run (``stereosim run --html FILE``).

:func:`html_report` turns a run's report (the dict written to ``report.json``), its disparity map
and, when known, the ground truth and the trace log into one self-contained HTML page: the
headline figures, the configuration, the disparity map with a colour bar, the error map, block
activity, FIFO occupancy histograms and a timeline. Every image is a PNG embedded as a ``data:``
URI, so the page needs no network and no other file. The same inputs give the same bytes: the
maps are encoded by :func:`core.io.encode_png`, the charts by matplotlib's Agg backend without
the ``Software`` metadata entry, and the page holds no date and no path but the scene's source.

The page reads the keys of ``report_version`` 3 (docs/report.md). A functional-mode report has
no cycle figures: those sections say so and the page shows the rest.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Mapping

import cv2
import numpy as np

from stereosim.core.io import disparity_to_colour, encode_png
from stereosim.sim.cycle.area import area_rows
from stereosim.sim.metrics import MIDDLEBURY_KEYS
from stereosim.traces.log import changes_of
from stereosim.traces.timeline import STATUS_NAMES

#: The four activities of a block, in the order the bars stack them.
STATES = ("busy", "starved", "blocked", "idle")
STATE_COLOURS = {"busy": "#2e8b57", "starved": "#e9a93a", "blocked": "#c9443b", "idle": "#c4c4c4"}
#: The error above which a pixel is bad in the error map (the ``bad2`` metric).
BAD_PX = 2.0
#: Error map colours (RGB): good pixels grade from black (exact) to this grey (BAD_PX).
ERR_GREY_MAX = 170
ERR_BAD = (220, 40, 40)
ERR_INVALID = (40, 90, 230)
ERR_UNSCORED = (255, 255, 255)
DPI = 100
GANTT_COLUMNS = 1000


# ---- reading the report ------------------------------------------------------------------------


def flatten(d: Mapping, prefix: str = "") -> list[tuple[str, object]]:
    """``(dotted key, value)`` of every leaf of a nested dict, keys sorted."""
    rows = []
    for key in sorted(d):
        value = d[key]
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            rows += flatten(value, name + ".")
        else:
            rows.append((name, value))
    return rows


def activity(entry: Mapping) -> dict[str, int] | None:
    """The cycles a block (``blocks.<block>``) or SVA stage (``sva_stages.<stage>``) spent
    busy / starved / blocked / idle; None if it counted no cycle."""
    counts = {state: int(entry[state]) for state in STATES}
    return counts if sum(counts.values()) > 0 else None


def histogram(entry: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """A FIFO's occupancy histogram (``fifos.<fifo>.occupancy_histogram``): ``(occupancy of
    each bin, cycles in it)``, as floats."""
    hist = entry["occupancy_histogram"]
    return (np.asarray(hist["occupancy"], dtype=np.float64),
            np.asarray(hist["cycles"], dtype=np.float64))


def latency_ns(report: Mapping) -> tuple[float, float] | None:
    """The frame's first-output and last-output (frame) latency in ns, from ``latency``
    (None in functional mode, which has no clock)."""
    lat = report.get("latency")
    if lat is None:
        return None
    return lat["first_output_us"] * 1e3, lat["frame_ms"] * 1e6


def _fmt(value, digits: int = 4) -> str:
    """A number for people: integers with thousands separators, floats to ``digits``
    significant digits; other values as text."""
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    if isinstance(value, float):
        if not np.isfinite(value):
            return str(value)
        if value == int(value) and abs(value) < 1e15:
            return f"{int(value):,}"
        return f"{value:,.{digits}g}" if abs(value) >= 1e-3 else f"{value:.{digits}g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt(v, digits) for v in value) + "]"
    return str(value)


def _toml(value) -> str:
    """A configuration value as TOML spells it (``true``, ``[11, 3]``; strings unquoted)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return str(value)


def _time_text(ns: float) -> str:
    if ns >= 1e6:
        return f"{ns / 1e6:.3f} ms"
    if ns >= 1e3:
        return f"{ns / 1e3:.2f} µs"
    return f"{ns:.1f} ns"


# ---- images ------------------------------------------------------------------------------------


def _uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _new_figure(width_in: float, height_in: float):
    """A matplotlib Figure on its own Agg canvas (no pyplot, no global state). matplotlib is
    imported here, not at the top, so that every other command skips its ~0.5 s import
    (as sim.plot does)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _figure_png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None}, bbox_inches="tight",
                pad_inches=0.08)
    return buf.getvalue()


def _listed_colormap(rgb: np.ndarray, over=None):
    from matplotlib.colors import ListedColormap

    cmap = ListedColormap(np.asarray(rgb, dtype=np.float64) / 255.0)
    if over is not None:
        cmap = cmap.with_extremes(over=np.asarray(over, dtype=np.float64) / 255.0)
    return cmap


def turbo_lut() -> np.ndarray:
    """The 256 RGB colours of OpenCV's TURBO map, as :func:`core.io.disparity_to_colour` uses."""
    bgr = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(1, 256), cv2.COLORMAP_TURBO)
    return bgr[0, :, ::-1].copy()


def colour_bar_png(lut: np.ndarray, vmin: float, vmax: float, label: str, *,
                   over=None) -> bytes:
    """A horizontal colour bar of ``lut`` from ``vmin`` to ``vmax`` with ticks and ``label``;
    with ``over``, an arrow of that colour for values above ``vmax``."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig = _new_figure(6.4, 0.95)
    ax = fig.add_axes((0.04, 0.55, 0.92, 0.3))
    mappable = ScalarMappable(norm=Normalize(vmin, vmax), cmap=_listed_colormap(lut, over))
    bar = fig.colorbar(mappable, cax=ax, orientation="horizontal",
                       extend="max" if over is not None else "neither")
    bar.set_label(label, fontsize=9)
    ax.tick_params(labelsize=8)
    return _figure_png(fig)


def error_image(disp: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None):
    """The error map of ``disp`` against ``gt`` as RGB, and its counts.

    Scored pixels (finite GT, inside ``mask`` if given): a valid disparity with error
    ``|d - gt| <= BAD_PX`` is grey from black (0 px) to ``ERR_GREY_MAX`` (``BAD_PX``); above it
    the pixel is bad (red); no disparity is invalid (blue). Unscored pixels are white.
    """
    d = np.asarray(disp, dtype=np.float64)
    g = np.asarray(gt, dtype=np.float64)
    scored = np.isfinite(g)
    if mask is not None:
        scored &= np.asarray(mask, dtype=bool)
    valid = scored & np.isfinite(d)
    err = np.where(valid, np.abs(np.where(valid, d, 0.0) - np.where(valid, g, 0.0)), 0.0)
    bad = valid & (err > BAD_PX)
    invalid = scored & ~np.isfinite(d)
    level = np.floor(ERR_GREY_MAX * np.clip(err / BAD_PX, 0.0, 1.0) + 0.5).astype(np.uint8)
    rgb = np.repeat(level[:, :, None], 3, axis=2)
    rgb[bad] = ERR_BAD
    rgb[invalid] = ERR_INVALID
    rgb[~scored] = ERR_UNSCORED
    counts = {"scored": int(scored.sum()), "bad": int(bad.sum()), "invalid": int(invalid.sum()),
              "max_error": float(err[valid].max()) if valid.any() else float("nan")}
    return rgb, counts


def activity_png(rows: list[tuple[str, dict[str, int]]]) -> bytes:
    """Stacked horizontal bars: the share of each block's cycles per activity, in percent."""
    fig = _new_figure(10.0, 0.6 + 0.32 * len(rows))
    ax = fig.add_subplot()
    ys = np.arange(len(rows))[::-1]
    for state in STATES:
        lefts, widths = [], []
        for _, counts in rows:
            total = sum(counts.values())
            start = sum(counts[s] for s in STATES[: STATES.index(state)])
            lefts.append(100.0 * start / total)
            widths.append(100.0 * counts[state] / total)
        ax.barh(ys, widths, left=lefts, height=0.7, color=STATE_COLOURS[state], label=state)
        for y, left, width in zip(ys, lefts, widths, strict=True):
            if width >= 6.0:
                ax.text(left + width / 2, y, f"{width:.1f}%", ha="center", va="center",
                        fontsize=8, color="white" if state != "idle" else "black")
    ax.set_yticks(ys, [name for name, _ in rows], fontsize=8)
    ax.set_xlim(0, 100)
    ax.set_xlabel("share of the block's clock cycles (%)", fontsize=8)
    ax.tick_params(axis="x", labelsize=8)
    ax.legend(ncols=4, fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.0), frameon=False)
    return _figure_png(fig)


def fifo_png(fifos: list[tuple[str, np.ndarray, np.ndarray, int]]) -> bytes:
    """One histogram per FIFO: share of cycles (%) at each occupancy 0..depth."""
    cols = 3 if len(fifos) > 4 else max(1, min(2, len(fifos)))
    nrows = -(-len(fifos) // cols)
    height = 2.3 * nrows
    fig = _new_figure(10.0, height)
    axes = fig.subplots(nrows, cols, squeeze=False)
    for ax, (name, bins, counts, depth) in zip(axes.flat, fifos, strict=False):
        share = 100.0 * counts / counts.sum() if counts.sum() else counts
        ax.bar(bins, share, width=0.9, color="#3b6fb6")
        ax.set_xlim(-0.5, depth + 0.5)
        ax.set_ylim(0, 100)
        ax.set_title(f"{name} (depth {depth})", fontsize=9)
        ax.set_xlabel("occupancy (items)", fontsize=8)
        ax.set_ylabel("% of cycles", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(fifos):]:
        ax.set_axis_off()
    # fixed margins (in inches / the figure's height): tight_layout costs seconds here
    fig.subplots_adjust(left=0.06, right=0.99, bottom=0.5 / height, top=1 - 0.3 / height,
                        wspace=0.25, hspace=0.55)
    return _figure_png(fig)


def dominant_states(t: np.ndarray, v: np.ndarray, end: int, edges: np.ndarray) -> np.ndarray:
    """For each interval ``[edges[k], edges[k+1])``, the status that filled most of it, from a
    status signal's change instants ``t`` (the first is the window's start) and values ``v``."""
    tf = t.astype(np.float64)
    seg_end = np.append(tf[1:], float(end))
    k = np.clip(np.searchsorted(tf, edges, side="right") - 1, 0, tf.size - 1)
    share = np.empty((len(STATUS_NAMES), edges.size - 1))
    for s in range(len(STATUS_NAMES)):
        on = v == s
        cum = np.concatenate([[0.0], np.cumsum((seg_end - tf) * on)])
        # time in status s before each edge: whole segments before it, then part of its own
        before = cum[k] + np.where(on[k], np.minimum(edges, seg_end[k]) - tf[k], 0.0)
        share[s] = np.diff(before)
    return np.argmax(share, axis=0)


def gantt_png(log) -> bytes | None:
    """Block status over the traced window: a row per block, coloured by the activity that
    filled most of each of :data:`GANTT_COLUMNS` time slices (None if nothing is traced)."""
    rows = []
    for i, sig in enumerate(log.signals):
        if sig.path.endswith(".status") and sig.path.count(".") >= 2:
            name = sig.path[: -len(".status")].removeprefix("top.")
            rows.append((name, *changes_of(log, i)))
    if not rows or log.end_fs <= log.start_fs:
        return None
    edges = np.linspace(log.start_fs, log.end_fs, GANTT_COLUMNS + 1)
    palette = np.array([_hex_rgb(STATE_COLOURS[s]) for s in STATUS_NAMES], dtype=np.uint8)
    image = np.stack([palette[dominant_states(t, v, log.end_fs, edges)] for _, t, v in rows])
    fig = _new_figure(10.0, 0.6 + 0.3 * len(rows))
    ax = fig.add_subplot()
    t0_us, t1_us = log.start_fs / 1e9, log.end_fs / 1e9
    ax.imshow(image, aspect="auto", interpolation="nearest",
              extent=(t0_us, t1_us, len(rows) - 0.5, -0.5))
    ax.set_yticks(range(len(rows)), [name for name, _, _ in rows], fontsize=8)
    ax.set_xlabel("time (µs)", fontsize=8)
    ax.tick_params(axis="x", labelsize=8)
    handles = [_patch(STATE_COLOURS[s], s) for s in STATES]
    ax.legend(handles=handles, ncols=4, fontsize=8, loc="lower center",
              bbox_to_anchor=(0.5, 1.0), frameon=False)
    return _figure_png(fig)


def instants_png(frame_ns: float, first_ns: float, rows: list[tuple[str, float]]) -> bytes:
    """The frame's key instants without a trace: the frame from 0 to its last output, the
    first output marked, and each block's busy share written on a bar across the frame."""
    frame_us = frame_ns / 1e3
    n = len(rows) + 1
    fig = _new_figure(10.0, 0.6 + 0.3 * n)
    ax = fig.add_subplot()
    ax.barh([0], [frame_us], height=0.6, color="#3b6fb6")
    ax.barh([0], [first_ns / 1e3], height=0.6, color="#9db7dd")
    ax.axvline(first_ns / 1e3, color="black", linestyle="--", linewidth=0.8)
    for y, (_, busy) in enumerate(rows, start=1):
        ax.barh([y], [frame_us], height=0.6, color=STATE_COLOURS["idle"])
        ax.barh([y], [frame_us * busy / 100.0], height=0.6, color=STATE_COLOURS["busy"])
        ax.text(frame_us * 0.99, y, f"busy {busy:.1f}%", ha="right", va="center", fontsize=8)
    ax.set_yticks(range(n), ["frame (outputs)"] + [name for name, _ in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, frame_us)
    ax.set_xlabel("time from the start of the frame (µs)", fontsize=8)
    ax.tick_params(axis="x", labelsize=8)
    return _figure_png(fig)


def _hex_rgb(colour: str) -> tuple[int, int, int]:
    return tuple(int(colour[i : i + 2], 16) for i in (1, 3, 5))


def _patch(colour: str, label: str):
    from matplotlib.patches import Patch

    return Patch(color=colour, label=label)


# ---- the page ----------------------------------------------------------------------------------

CSS = """
body { font-family: "DejaVu Sans", Arial, sans-serif; margin: 0; color: #1d1d1d;
       background: #ffffff; }
main { max-width: 1100px; margin: 0 auto; padding: 16px 24px 40px; }
h1 { font-size: 24px; margin: 8px 0 2px; }
h2 { font-size: 18px; margin: 28px 0 6px; border-bottom: 1px solid #d0d0d0; }
h3 { font-size: 15px; margin: 18px 0 4px; }
p.sub, p.caption, p.note { margin: 4px 0 10px; font-size: 13px; color: #444; }
p.caption { max-width: 980px; }
.cards { display: flex; flex-wrap: wrap; gap: 10px; margin: 12px 0; }
.card { border: 1px solid #d0d0d0; border-radius: 6px; padding: 8px 12px; min-width: 150px; }
.card .v { font-size: 20px; font-weight: bold; }
.card .k { font-size: 12px; color: #555; }
table { border-collapse: collapse; font-size: 12px; }
th, td { border: 1px solid #d8d8d8; padding: 2px 8px; text-align: right; }
th { background: #f1f1f1; }
td.key, th.key { text-align: left; font-family: "DejaVu Sans Mono", monospace; }
.config { columns: 3; column-gap: 18px; }
.config table { break-inside: avoid; margin-bottom: 10px; width: 100%; }
img.map { width: min(100%, 640px); image-rendering: pixelated; border: 1px solid #bbb; }
img.chart { max-width: 100%; }
.maps { display: flex; flex-wrap: wrap; gap: 20px; }
.maps figure { margin: 0; flex: 1 1 480px; }
.swatch { display: inline-block; width: 11px; height: 11px; border: 1px solid #888;
          vertical-align: middle; margin: 0 3px 0 8px; }
"""


def _img(png: bytes, cls: str, alt: str) -> str:
    return f'<img class="{cls}" alt="{html.escape(alt)}" src="{_uri(png)}">'


def _swatch(rgb) -> str:
    return f'<span class="swatch" style="background: rgb{tuple(int(c) for c in rgb)}"></span>'


def _cards(items: list[tuple[str, str]]) -> str:
    body = "".join(f'<div class="card"><div class="v">{html.escape(v)}</div>'
                   f'<div class="k">{html.escape(k)}</div></div>' for k, v in items)
    return f'<div class="cards">{body}</div>'


def _headline(report: dict) -> list[tuple[str, str]]:
    items = []
    thr = report.get("throughput")  # cycle mode only, as latency and energy
    if thr is not None:
        if thr["fps_measured"] is not None:  # None if the frame took no time
            items.append(("fps measured (one frame alone)", f"{thr['fps_measured']:,.1f}"))
        if thr["fps_bound"] is not None:
            items.append((f"fps work bound (bottleneck {thr['bottleneck']})",
                          f"{thr['fps_bound']:,.1f}"))
    lat = latency_ns(report)
    if lat is not None:
        items.append(("latency to first output", _time_text(lat[0])))
        items.append(("latency of the frame (last output)", _time_text(lat[1])))
    energy = report.get("energy")
    if energy is not None:
        total_uj = energy["per_frame_uj"]["total"]
        shown = f"{total_uj / 1e3:.3f} mJ" if total_uj >= 1e3 else f"{total_uj:.3f} µJ"
        items.append(("energy per frame", shown))
        if energy["power_mw"] is not None:  # None without a frame rate
            items.append(("power at the work-bound fps", f"{energy['power_mw']:.1f} mW"))
    out = report.get("output")  # a stream's report has none
    if out is not None:
        items.append(("valid pixels", f"{100.0 - out['invalid_percent']:.2f}%"))
    metrics = report.get("metrics", {})  # with ground truth only
    for mask in ("nonocc", "all"):
        if mask in metrics:
            items.append((f"bad2 ({mask})", f"{metrics[mask]['bad2']:.2f}%"))
            break
    return items


def _config_section(config: Mapping) -> str:
    tables = []
    for section in sorted(config):
        value = config[section]
        rows = flatten(value) if isinstance(value, Mapping) else [("", value)]
        body = "".join(f'<tr><td class="key">{html.escape(k)}</td><td>{html.escape(_toml(v))}'
                       "</td></tr>" for k, v in rows)
        tables.append(f'<table><tr><th class="key" colspan="2">{html.escape(section)}</th></tr>'
                      f"{body}</table>")
    return ('<h2 id="configuration">Configuration</h2><p class="caption">Every key of the chip '
            "configuration this run used (TOML sections; the same names work with "
            f'<code>--set</code>).</p><div class="config">{"".join(tables)}</div>')


def _area_section(report: dict) -> str:
    """The chip's area and leakage at the configured node (``report["area"]``), or nothing for
    a report without it (an older report.json)."""
    area = report.get("area")
    if not area:
        return ""
    rows = "".join(f'<tr><td class="key">{html.escape(what)}</td><td>{html.escape(figs)}'
                   "</td></tr>" for what, figs in area_rows(area))
    return (f'<h2 id="area">Area</h2><p class="caption">The chip\'s area in mm<sup>2</sup> and '
            f"leakage at {html.escape(area['node'])} ({html.escape(area['node_description'])}): "
            "logic from the RTL twin's synthesis, SRAM as macros; no wires, clock tree or pads "
            "(docs/area.md; report.json's <code>area</code> has every block).</p>"
            f"<table>{rows}</table>")


def _metrics_section(report: dict) -> str:
    metrics = report.get("metrics")  # with ground truth only
    if not metrics:
        return ('<h2 id="metrics">Accuracy</h2><p class="note">No ground truth was given, so '
                "there are no accuracy metrics (give a scene with disp0GT, or --gt).</p>")
    head = "".join(f"<th>{html.escape(k)}</th>" for k in MIDDLEBURY_KEYS)
    rows = []
    for mask, m in metrics.items():
        cells = "".join(f"<td>{_fmt(m[k], 4)}</td>" for k in MIDDLEBURY_KEYS)
        rows.append(f'<tr><td class="key">{html.escape(mask)}</td>{cells}</tr>')
    return ('<h2 id="metrics">Accuracy</h2><p class="caption">Middlebury metrics per mask: '
            "bad<i>t</i> = % of scored pixels off by more than <i>t</i> px, invalid = % with no "
            "disparity, totbad = bad2 + invalid, avgerr and rms in pixels (docs/metrics.md)."
            f'</p><table><tr><th class="key">mask</th>{head}</tr>{"".join(rows)}</table>')


def _maps_section(report: dict, disparity: np.ndarray, gt, mask) -> str:
    finite = np.isfinite(disparity)
    top = float(disparity[finite].max()) if finite.any() else 1.0
    dmax = float(report["config"]["sva"]["disparities"])
    span = (f"this frame's values span {float(disparity[finite].min()):.2f} to {top:.2f} px"
            if finite.any() else "no pixel of this frame has a disparity")
    h, w = disparity.shape
    disp_fig = (
        f"<figure>{_img(encode_png(disparity_to_colour(disparity, dmax)), 'map', 'disparity')}"
        f"{_img(colour_bar_png(turbo_lut(), 0.0, dmax, 'disparity (pixels)'), 'chart', 'bar')}"
        f'<p class="caption">Disparity map ({w}×{h}), colour scale 0 to {dmax:g} px (the '
        f"search range); {span}. Black: no "
        f"disparity (rejected by the left-right check), {100.0 * (~finite).mean():.2f}% of "
        "pixels. disparity.png uses the same colours.</p></figure>"
    )
    if gt is None:
        err_fig = ('<figure><p class="note">No ground truth: no error map.</p></figure>')
    else:
        rgb, n = error_image(disparity, gt, mask)
        grey = np.repeat(np.linspace(0, ERR_GREY_MAX, 256).round().astype(np.uint8)[:, None],
                         3, axis=1)
        bar = colour_bar_png(grey, 0.0, BAD_PX, "|d − GT| (pixels)", over=ERR_BAD)
        scored = max(n["scored"], 1)
        err_fig = (
            f"<figure>{_img(encode_png(rgb), 'map', 'error map')}{_img(bar, 'chart', 'bar')}"
            f'<p class="caption">Error |d − GT| of the scored pixels ({n["scored"]:,}: known '
            f"GT{', inside the mask' if mask is not None else ''}), grey from black (exact) to "
            f"{BAD_PX:g} px. {_swatch(ERR_BAD)}bad, error &gt; {BAD_PX:g} px: "
            f"{100.0 * n['bad'] / scored:.2f}% (bad2); {_swatch(ERR_INVALID)}no disparity: "
            f"{100.0 * n['invalid'] / scored:.2f}%; {_swatch((255, 255, 255))}not scored. "
            f"Largest error {n['max_error']:.2f} px.</p></figure>"
        )
    return (f'<h2 id="maps">Disparity and error</h2><div class="maps">{disp_fig}{err_fig}'
            "</div>")


def _block_label(name: str, entry: Mapping) -> str:
    return f"{name} ({entry['clock_domain']})"


def _no_cycles(title: str, anchor: str) -> str:
    return (f'<h2 id="{anchor}">{title}</h2><p class="note">Not available: a functional-mode '
            "run has no clock. Run with <code>--mode cycle</code> for cycle figures.</p>")


def _activity_table(blocks: Mapping) -> str:
    """The numbers behind the bars: each block's clock, cycles and share per activity."""
    rows = []
    for name, entry in blocks.items():
        counts = activity(entry)
        if counts is None:
            continue
        total = sum(counts.values())
        cells = "".join(f"<td>{100.0 * counts[s] / total:.1f}%</td>" for s in STATES)
        rows.append(f'<tr><td class="key">{html.escape(name)}</td>'
                    f"<td>{html.escape(entry['clock_domain'])}</td><td>{total:,}</td>{cells}</tr>")
    head = "".join(f"<th>{s}</th>" for s in STATES)
    return (f'<table><tr><th class="key">block</th><th>clock</th><th>cycles</th>{head}</tr>'
            f'{"".join(rows)}</table>')


def _activity_section(report: dict) -> str:
    blocks = report.get("blocks", {})  # cycle mode only
    rows = [(_block_label(k, v), a) for k, v in blocks.items()
            if (a := activity(v)) is not None]
    if not rows:
        return _no_cycles("Block activity", "activity")
    neck = report["throughput"]["bottleneck"]
    caption = (
        '<p class="caption">Share of each block\'s clock cycles (its clock domain in brackets) '
        "spent busy (doing work), starved (waiting for data from an input FIFO), blocked "
        "(waiting for space in an output FIFO) or idle, over the whole frame. "
        f"Bottleneck: {html.escape(str(neck))}.</p>"
    )
    parts = ['<h2 id="activity">Block activity</h2>',
             _img(activity_png(rows), "chart", "block activity"), caption,
             _activity_table(blocks)]
    stages = [(k, a) for k, v in report["sva_stages"].items()
              if (a := activity(v)) is not None]
    if stages:
        parts += ["<h3>SVA pipeline stages</h3>",
                  _img(activity_png(stages), "chart", "SVA stages"),
                  '<p class="caption">The same for the stages of the SVA pipeline (SVA clock).</p>']
    return "".join(parts)


def _fifo_section(report: dict) -> str:
    fifos = []
    for name, entry in report.get("fifos", {}).items():  # cycle mode only
        fifos.append((name, *histogram(entry), entry["depth"]))
    if not fifos:
        return _no_cycles("FIFO occupancy", "fifos")
    rows = "".join(
        f'<tr><td class="key">{html.escape(name)}</td><td>{depth}</td>'
        f"<td>{float((bins * counts).sum() / max(counts.sum(), 1)):.2f}</td>"
        f"<td>{int(bins[counts > 0].max()) if (counts > 0).any() else 0}</td>"
        f"<td>{100.0 * counts[0] / max(counts.sum(), 1):.1f}%</td>"
        f"<td>{100.0 * counts[-1] / max(counts.sum(), 1):.1f}%</td></tr>"
        for name, bins, counts, depth in fifos
    )
    return (
        '<h2 id="fifos">FIFO occupancy</h2>'
        + _img(fifo_png(fifos), "chart", "FIFO occupancy histograms")
        + '<p class="caption">Share of cycles (of the FIFO\'s consumer clock) at each occupancy, '
        "from 0 (empty) to the depth (full). A FIFO that sits full has a slow consumer; one that "
        "sits empty has a slow producer.</p>"
        '<table><tr><th class="key">FIFO</th><th>depth</th><th>mean</th><th>max</th>'
        f"<th>empty</th><th>full</th></tr>{rows}</table>"
    )


def _timeline_section(report: dict, log) -> str:
    if log is not None:
        png = gantt_png(log)
        if png is not None:
            return (
                '<h2 id="timeline">Timeline</h2>' + _img(png, "chart", "timeline")
                + f'<p class="caption">Status of every traced block from {log.start_fs / 1e9:.3f}'
                f" to {log.end_fs / 1e9:.3f} µs (the trace window), sliced in "
                f"{GANTT_COLUMNS} columns, each coloured by the activity that filled most of "
                "it. Open the --timeline JSON in ui.perfetto.dev or the VCD in GTKWave for "
                "every cycle.</p>"
            )
    lat = latency_ns(report)
    if lat is None:
        return _no_cycles("Timeline", "timeline")
    first, frame = lat
    rows = []
    for name, entry in report["blocks"].items():
        counts = activity(entry)
        if counts is not None:
            rows.append((_block_label(name, entry), 100.0 * counts["busy"] / sum(counts.values())))
    return (
        '<h2 id="timeline">Timeline</h2>' + _img(instants_png(frame, first, rows), "chart",
                                                  "key instants")
        + f'<p class="caption">The frame\'s key instants: first output at {_time_text(first)} '
        f"(light: filling the pipeline), last output at {_time_text(frame)}; each block's bar "
        "shows its busy share of the frame (not when it was busy). Record a trace "
        "(<code>--timeline FILE</code> or <code>--vcd FILE</code>) for a per-block Gantt chart."
        "</p>"
    )


def _title(report: dict) -> tuple[str, str]:
    scene = report.get("scene")  # the CLI adds it
    img, desc = report["image"], report["descriptor"]
    sva = report["config"]["sva"]
    parts = [f"{report['mode']} mode",
             f"{img['width']}×{img['height']}",
             f"D={sva['disparities']}",
             f"descriptor {desc['kind']} ({desc['bits']} bits)",
             f"{sva['paths']} SGM paths"]
    if "engine" in report:  # cycle mode only
        parts.append(f"engine {report['engine']}")
    parts.append(f"stereosim {report['stereosim']}")
    sub = ", ".join(parts)
    if scene is None:
        return "stereo pair", sub
    return scene["name"], f"{sub}. Input: {scene['source']}"


def html_report(report: dict, disparity: np.ndarray, *, gt: np.ndarray | None = None,
                mask: np.ndarray | None = None, log=None) -> str:
    """The one-page HTML report of a run, as text (write it encoded as UTF-8).

    ``report``: the run's report (``Result.report`` or report.json read back); ``disparity``:
    float disparities (inf or NaN where invalid); ``gt``: ground truth (inf unknown) for the
    error map; ``mask``: the pixels the error map scores (default: every pixel with known GT);
    ``log``: the run's :class:`traces.log.TraceLog`, if a trace was recorded, for the Gantt
    chart. Deterministic: the same arguments give the same text.
    """
    disparity = np.asarray(disparity, dtype=np.float32)
    if disparity.ndim != 2:
        raise ValueError(f"a disparity map is 2-D but got shape {disparity.shape}")
    for what, arr in (("gt", gt), ("mask", mask)):
        if arr is not None and np.shape(arr) != disparity.shape:
            raise ValueError(f"{what} has shape {np.shape(arr)} but the disparity map "
                             f"{disparity.shape}: give the {what} of this frame")
    name, sub = _title(report)
    body = [
        f"<h1>{html.escape(name)}</h1><p class=\"sub\">{html.escape(sub)}</p>",
        _cards(_headline(report)),
        _maps_section(report, disparity, gt, mask),
        _metrics_section(report),
        _activity_section(report),
        _fifo_section(report),
        _timeline_section(report, log),
        _area_section(report),
        _config_section(report["config"]),
    ]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>stereosim report: {html.escape(name)}</title>\n<style>{CSS}</style>\n"
        "</head>\n<body>\n<main>\n" + "\n".join(body) + "\n</main>\n</body>\n</html>\n"
    )


def html_files(path: str | None, result, inputs: dict) -> dict[str, bytes]:
    """``{path: page}`` for ``stereosim run --html PATH`` (empty without a path): the page of a
    one-frame run's :class:`sim.api.Result`, scored against ``inputs``' GT (in its
    ``nonocc`` mask when there is one)."""
    if not path:
        return {}
    masks = inputs.get("masks") or {}
    page = html_report(result.report, result.disparity, gt=inputs.get("gt"),
                       mask=masks.get("nonocc"), log=result.trace)
    return {path: page.encode("utf-8")}
