"""The what-if subcommands of ``stereosim``: ``estimate``, ``sweep`` and ``plot``.

Registered by :func:`register` from :func:`sim.cli.build_parser`; errors follow the CLI's rule
(one line, exit status 2, nothing half-written).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from stereosim.core.errors import InputError, UserError
from stereosim.core.outputs import json_text
from stereosim.sim.argtypes import finite_float, nonempty_path, nonempty_size
from stereosim.sim.cycle.area import chip_area
from stereosim.sim.cycle.energy import energy_table
from stereosim.sim.cycle.estimate import estimate, parse_size
from stereosim.sim.cycle.plan import build_plan, frame_size
from stereosim.sim.plot import (
    BOUND_RATE,
    MEASURED_RATE,
    RATE_GAP,
    pareto_plot,
    plot_xy,
    point_labels,
    rate_gaps,
    rate_label,
    sweep_pareto,
    sweep_plots,
)
from stereosim.sim.summary import format_estimate
from stereosim.sim.sweep import MAX_POINTS, load_scene_spec, load_sweep, run_sweep
from stereosim.sim.sweep_results import CSV_NAME, GUIDE_NAME, read_rows

BEST_SHOWN = 10  # Pareto-optimal points the sweep's summary lists


def _mean(rows: list[dict], column: str) -> float | None:
    values = []
    for r in rows:
        try:
            values.append(float(r[column]))
        except (KeyError, TypeError, ValueError):
            return None
    return sum(values) / len(values) if values else None


def sweep_summary(rows: list[dict], axes: list[str], target_fps: float | None = None
                  ) -> list[str]:
    """The lines a sweep prints about its results: the best points (the Pareto-optimal ones
    in chip SRAM, frame rate and accuracy when scored -- the same as the Pareto plot, on the
    measured rate when the runs measured one) named by their swept keys, with their rate
    (averaged over scenes), its work bound, SRAM and accuracy; then a note when a measured rate
    is more than :data:`~sim.plot.RATE_GAP` off its work bound."""
    view = sweep_pareto(rows, axes)
    lines = []
    if view is not None:
        by_point: dict[str, list[dict]] = {}
        for r in rows:
            if r.get("status") == "ok":
                by_point.setdefault(r.get("point", ""), []).append(r)
        best = sorted(view.front, key=lambda p: (-p.fps, p.sram))
        judged = "chip SRAM, " + rate_label(view.fps) + (f" and {view.error}" if view.error
                                                        else "")
        lines.append(f"best points (Pareto-optimal in {judged}): {len(best)} of "
                     f"{len(view.points)}")
        for p in best[:BEST_SHOWN]:
            bound = _mean(by_point[p.point], BOUND_RATE) if view.fps == MEASURED_RATE else None
            parts = [f"{p.fps:,.1f} fps" + (f" (bound {bound:,.1f})" if bound else ""),
                     f"SRAM {p.sram:,.0f} bits"]
            if p.error is not None:
                parts.append(f"{view.error.rsplit('.', 1)[-1]} {p.error:.2f}")
            lines.append(f"  {p.label}: " + ", ".join(parts))
        if len(best) > BEST_SHOWN:
            lines.append(f"  ... and {len(best) - BEST_SHOWN} more (the Pareto plot shows all)")
        target = sweep_pareto(rows, axes, target_fps=target_fps)
        if target is not None and target.target is not None:
            chosen = target.chosen
            lines.append(
                f"target {target.target:,.1f} fps ({target.target_source}): "
                + (f"the least SRAM that reaches it is {chosen.label}, {chosen.fps:,.1f} fps, "
                   f"SRAM {chosen.sram:,.0f} bits" if chosen is not None
                   else f"no point reaches it (best {max(p.fps for p in target.points):,.1f} "
                   "fps)"))
    gaps = rate_gaps(rows)
    if gaps:
        worst = gaps[0]
        label = point_labels(rows, axes).get(worst.get("point", ""), "")
        measured, bound = float(worst[MEASURED_RATE]), float(worst[BOUND_RATE])
        why = ("blocks wait on each other: see its blocks.*.blocked columns" if measured < bound
               else "one frame alone skips what paces a stream, such as a camera's blanking")
        ok = sum(r.get("status") == "ok" for r in rows)
        lines.append(
            f"note: {len(gaps)} of {ok} runs measured a frame rate more than "
            f"{RATE_GAP:.0%} off the work bound; the most: {label} ({worst.get('scene')}) ran "
            f"at {measured:,.1f} fps against a bound of {bound:,.1f} ({why}). The plots and "
            f"the best points use the measured rate ({MEASURED_RATE})"
        )
    return lines


def register(sub, add_config_options, scene_config) -> None:
    """Add the three subcommands to ``sub`` (the parser's subparsers)."""

    def cmd_estimate(args) -> int:
        size, ndisp = args.size, None
        if size is None:
            shape = None  # the configured camera's frame size, else 720p
        elif size == "default" or Path(size).is_dir():
            data = load_scene_spec(size if size == "default" else str(Path(size)))
            shape = data["left"].shape[:2]
            ndisp = data.get("ndisp")
        else:
            shape = parse_size(size)
        table = energy_table(args.energy) if args.energy is not None else None
        cfg = scene_config(args, ndisp)
        shape = shape or frame_size(cfg)
        est = estimate(cfg, shape, table)  # the plan refuses a chip it cannot build
        est["area"] = chip_area(build_plan(cfg, shape), cfg.power.node)
        if args.json:
            sys.stdout.write(json_text(est))
        else:
            print(format_estimate(est))
        return 0

    e = sub.add_parser("estimate", help="analytic fps, latency, SRAM, area and traffic (no "
                       "simulation)")
    e.add_argument("--size", metavar="WxH|SCENE", type=nonempty_size,
                   help="frame size (default: the configured camera's, source.camera_width x "
                   "camera_height, else 1280x720), 'default' or a scene folder")
    e.add_argument("--json", action="store_true", help="print the estimate as JSON")
    e.add_argument("--energy", metavar="FILE", type=nonempty_path,
                   help="energy table (TOML) for the energy and power (default: stereosim's "
                   "45 nm table; docs/energy.md)")
    add_config_options(e)
    e.set_defaults(func=cmd_estimate)

    def cmd_sweep(args) -> int:
        if args.target_fps is not None and not args.target_fps > 0:
            raise InputError(f"--target-fps must be above 0; got {args.target_fps:g}")
        if args.workers is not None and args.workers < 1:
            raise InputError(f"--workers must be at least 1; got {args.workers}")
        if args.max_points is not None and args.max_points < 1:
            raise InputError(f"--max-points must be at least 1; got {args.max_points}")
        sweep = load_sweep(args.sweep_file, max_points=args.max_points or MAX_POINTS)
        workers = args.workers or min(2, os.cpu_count() or 1)
        out = Path(args.out)
        counts = run_sweep(sweep, out, scheduler=args.scheduler, workers=workers,
                           progress=not args.quiet, verbose=args.verbose)
        rows = read_rows(out / CSV_NAME)
        plots = sweep_plots(rows, sweep.axes, out, target_fps=args.target_fps)
        print(f"{counts['tasks']} runs ({len(sweep.points)} points x {len(sweep.scenes)} scenes): "
              f"{counts['skipped']} already done, {counts['ok']} ok, {counts['error']} failed")
        planned = {t.point_id for t in sweep.tasks}
        mine = [r for r in rows if r.get("point_id") in planned]
        for line in sweep_summary(mine, sweep.axes, args.target_fps):
            print(line)
        n_columns = len(rows[0]) if rows else 0
        print(f"wrote {out / CSV_NAME} ({n_columns} columns: {GUIDE_NAME} beside it says what "
              "each is)" + "".join(f", {p.name}" for p in plots))
        failed = [r for r in mine if r.get("status") != "ok"]
        for r in failed[:5]:
            print(f"  point {r['point']} {r['scene']}: {r['error']}")
        if failed:
            raise UserError(
                f"{len(failed)} of {counts['tasks']} runs failed: read why in the 'error' column "
                f"of {out / CSV_NAME}"
            )
        return 0

    s = sub.add_parser("sweep", help="run a grid of configurations x scenes in parallel (Dask)")
    s.add_argument("sweep_file", type=nonempty_path,
                   help="sweep TOML: [grid], optional [zip] and [set], scenes, mode")
    s.add_argument("--scheduler", metavar="ADDRESS",
                   help="an existing Dask scheduler, e.g. tcp://host:8786 (default: a local "
                   "cluster of worker processes)")
    s.add_argument("--workers", type=int, metavar="N",
                   help="local worker processes (default: min(2, CPUs))")
    s.add_argument("--out", default="sweep", type=nonempty_path,
                   help="output folder (default: sweep)")
    s.add_argument("--max-points", type=int, metavar="N",
                   help=f"refuse a sweep of more than N points (grid x zip; default "
                   f"{MAX_POINTS:,})")
    s.add_argument("--target-fps", type=finite_float, metavar="FPS",
                   help="the frame rate a point must reach: the Pareto plot draws it and boxes "
                   "the least SRAM that reaches it (default: the camera's rate the rows carry, "
                   "throughput.camera_fps)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.add_argument("--verbose", action="store_true",
                   help="let Dask's own log and warnings through to stderr")
    s.set_defaults(func=cmd_sweep)

    def cmd_plot(args) -> int:
        path = Path(args.results)
        if not path.is_file():
            raise InputError(f"results file {path} not found: give a sweep's results.csv")
        rows = read_rows(path)
        if args.pareto:  # a cost (SRAM bits, area_mm2, power_mw) against a frame rate
            pareto_plot(rows, args.png, sram=args.x, fps=args.y, source=str(path))
        else:
            plot_xy(rows, args.x, args.y, args.png, hue=args.hue, title=args.title,
                    source=str(path), logx=args.logx, logy=args.logy)
        print(f"wrote {args.png}")
        return 0

    p = sub.add_parser("plot", help="plot one column of a sweep's results.csv against another")
    p.add_argument("results", type=nonempty_path, help="a sweep's results.csv")
    p.add_argument("--x", required=True, metavar="COLUMN")
    p.add_argument("--y", required=True, metavar="COLUMN")
    p.add_argument("--hue", metavar="COLUMN", help="one line per value of this column")
    p.add_argument("--title")
    p.add_argument("--png", required=True, metavar="OUT.png", type=nonempty_path)
    p.add_argument("--logx", action="store_true", help="logarithmic x axis (positive values)")
    p.add_argument("--logy", action="store_true", help="logarithmic y axis (positive values)")
    p.add_argument("--pareto", action="store_true",
                   help="a Pareto view instead: --x a cost (sram_bits, area_mm2 or power_mw), "
                   "--y a frame rate; the Pareto-optimal points ringed")
    p.set_defaults(func=cmd_plot)
