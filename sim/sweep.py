"""Architecture what-if sweeps: a grid of configurations x scenes, run in parallel on Dask.

A sweep file (TOML) names the points and the scenes::

    mode = "cycle"                 # cycle (default), functional or estimate
    scenes = ["default", "1280x720", "data:middlebury2014_trainingQ"]
    config = "base.toml"           # optional, relative to the sweep file
    [set]                          # optional: overrides shared by every point
    "nna.descriptor" = "cnn"
    [grid]                         # cartesian product, the last key varying fastest
    "sva.disparities" = [64, 128]
    "sva.paths" = [2, 4]
    [zip]                          # optional: equal-length lists taken together (one axis)
    "fifo.nna_to_sva_depth" = [8, 64]
    "fifo.source_to_nna_depth" = [8, 16]

Scenes: ``default`` (the embedded Motorcycle pair, with GT), ``WxH`` (a synthetic pair for
timing only: deterministic random texture, the right view the left shifted by min(8, W // 8)
pixels, no GT), a Middlebury scene folder, or a folder of scenes (every scene in it, sorted);
``data:NAME`` is NAME inside the shared data folder (:func:`core.datasets.shared_data_dir`), and a
NAME that resolves outside that folder (``data:../..``, an absolute path, a symbolic link out of
it) is refused. Relative paths are relative to the sweep file. A Middlebury scene's D comes from
its ``calib.txt`` unless the sweep sets ``sva.disparities``.

A sweep has at most :data:`MAX_POINTS` points (the product of the [grid] list lengths times the
[zip] length, counted before anything is expanded); ``max_points`` (``--max-points N``) raises
the cap. Every key and value is checked before anything runs; an unreadable sweep or config file
and a point given twice (the same overrides on the same scene) are one-line errors.

Every point x scene is one task on a Dask cluster: a ``LocalCluster`` of worker processes on the
loopback interface by default, or an existing cluster (``scheduler="tcp://host:8786"``) -- the
same code path. The local cluster has no dashboard, and its worker processes start with SIGINT
ignored, so a Ctrl-C at the terminal reaches only the sweep, which shuts them down (one pressed
during the second the cluster takes to start is not seen). At most
:data:`IN_FLIGHT_PER_WORKER` tasks per worker thread are submitted and not yet written, so memory
stays bounded however long the sweep. Dask's own log and warnings are kept off stderr unless
``verbose``.

The results go to ``results.csv`` in the output folder (:mod:`sim.sweep_results`: rows appended
under the folder's lock as tasks finish, put in a fixed order once at the end; a rerun skips
every point already ok). An interrupted sweep (Ctrl-C) cancels its tasks, closes the cluster
within seconds and leaves every finished row. A failing task is recorded with ``status`` error
and a one-line ``error`` without stopping the others; the command then exits with status 2.
While the tasks run, a progress bar counts them on stderr, only when stderr is a terminal
(:mod:`core.progress`; ``progress=False``, the command's ``--quiet``: none).
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import logging
import math
import signal
import threading
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from stereosim.core.config import load_config, read_toml
from stereosim.core.datasets import (
    default_scene,
    find_scene,
    find_scenes,
    legal_disparities,
    load_scene,
    shared_data_dir,
)
from stereosim.core.errors import ConfigError, InputError, UserError
from stereosim.core.outputs import describe_os_error
from stereosim.core.progress import progress_bar
from stereosim.sim.api import prepare_pair, run
from stereosim.sim.cycle.area import chip_area
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.sweep_results import CSV_NAME, append_rows, done_point_ids, finish_results

MODES = ("cycle", "functional", "estimate")
SWEEP_KEYS = ("mode", "scenes", "config", "set", "grid", "zip")
MAX_POINTS = 10_000  # default cap on a sweep's points (grid x zip); max_points / --max-points
IN_FLIGHT_PER_WORKER = 4  # tasks submitted and not yet written, per worker thread
CLOSE_TIMEOUT_S = 3.0  # closing the client and the local cluster, also after Ctrl-C
DASK_LOGGERS = ("distributed", "tornado", "asyncio", "bokeh")
_SILENT = logging.CRITICAL + 10  # above every level Dask logs at


@dataclass(frozen=True)
class Task:
    """One point x scene: everything a worker needs (plain data, picklable)."""

    index: int
    point: int
    scene: str  # the label written to the CSV
    scene_spec: str  # what the worker loads: default, WxH or a folder path
    overrides: dict[str, Any]
    config_path: str | None
    mode: str
    config_sets_d: bool = False  # the config file sets sva.disparities (a calib.txt does not)

    @property
    def point_id(self) -> str:
        text = json.dumps([self.scene, self.mode, sorted(self.overrides.items())], default=str)
        return hashlib.sha1(text.encode()).hexdigest()[:16]


@dataclass
class Sweep:
    path: Path
    mode: str
    config_path: str | None
    fixed: dict[str, Any]
    axes: list[str]  # the keys that vary, in file order (grid, then zip)
    points: list[dict[str, Any]]
    scenes: list[tuple[str, str]]  # (label, spec)
    tasks: list[Task] = field(default_factory=list)


# ----------------------------------------------------------------------------------------------
# the sweep file


def _synthetic_size(text: str) -> tuple[int, int] | None:
    parts = text.lower().split("x")
    if len(parts) == 2 and all(p.isdigit() for p in parts):
        w, h = int(parts[0]), int(parts[1])
        if w < 2 or h < 1 or w * h > 1 << 26:
            raise InputError(f"synthetic scene {text!r}: give at least 2x1 and at most 64 M pixels")
        return h, w
    return None


def _data_folder(entry: str) -> Path:
    """The folder of a ``data:NAME`` scene, refused unless it lies inside the shared data
    folder once every ``..`` and symbolic link is resolved."""
    root = shared_data_dir()
    if root is None:
        raise InputError(
            f"scene {entry!r} needs the shared data folder, which is absent (set STEREOSIM_DATA)"
        )
    folder = (root / entry[5:]).resolve()
    if not folder.is_relative_to(root):
        raise InputError(
            f"scene {entry!r} resolves to {folder}, outside the shared data folder {root}: "
            "name a folder inside it"
        )
    return folder


def _expand_scene(entry, base: Path) -> list[tuple[str, str]]:
    """A scenes entry -> [(label, spec)]."""

    if not isinstance(entry, str) or not entry:
        raise ConfigError(f"sweep scenes must be strings; got {entry!r}")
    if entry == "default" or _synthetic_size(entry):
        return [(entry, entry)]
    if entry.startswith("data:"):
        folder = _data_folder(entry)
    else:
        folder = Path(entry) if Path(entry).is_absolute() else base / entry
    if not folder.is_dir():
        raise InputError(f"sweep scene {entry!r}: folder {folder} not found")
    try:
        find_scene(folder)
        return [(entry, str(folder))]
    except InputError:
        scenes = find_scenes(folder)
    return [(f"{entry}/{s.left.parent.name}", str(s.left.parent)) for s in scenes]


def _check_lists(table: dict, name: str) -> None:
    for key, values in table.items():
        if not isinstance(values, list) or not values:
            raise ConfigError(
                f"sweep [{name}] key '{key}' must be a non-empty list, e.g. \"{key}\" = [1, 2]"
            )


def count_points(grid: dict[str, list], zipped: dict[str, list]) -> int:
    """The number of points of a sweep: the product of the [grid] lengths times the [zip]
    length (computed, not expanded)."""
    zip_len = len(next(iter(zipped.values()))) if zipped else 1
    return math.prod(len(v) for v in grid.values()) * zip_len


def load_sweep(path: str | Path, *, max_points: int = MAX_POINTS) -> Sweep:
    """Parse and check a sweep file; every key and value is validated before anything runs.

    A sweep of more than ``max_points`` points is refused before its grid is expanded.
    """
    p = Path(path)
    tree = read_toml(p, "sweep file", InputError)
    unknown = sorted(set(tree) - set(SWEEP_KEYS))
    if unknown:
        raise ConfigError(
            f"sweep file {p}: unknown entry '{unknown[0]}' (known: {', '.join(SWEEP_KEYS)}; "
            "config keys go in [grid], [zip] or [set])"
        )
    mode = tree.get("mode", "cycle")
    if mode not in MODES:
        raise ConfigError(f"sweep mode must be one of {', '.join(MODES)}; got {mode!r}")
    base = p.resolve().parent
    config_path = tree.get("config")
    config_sets_d = False
    if config_path is not None:
        if not isinstance(config_path, str):
            raise ConfigError(f"sweep 'config' must be a path string; got {config_path!r}")
        config_path = str(base / config_path)
        sva = read_toml(config_path, "config file").get("sva", {})
        config_sets_d = isinstance(sva, dict) and "disparities" in sva
    fixed = tree.get("set", {})
    grid = tree.get("grid", {})
    zipped = tree.get("zip", {})
    for name, table in (("set", fixed), ("grid", grid), ("zip", zipped)):
        if not isinstance(table, dict):
            raise ConfigError(f"sweep [{name}] must be a table of dotted config keys")
    _check_lists(grid, "grid")
    _check_lists(zipped, "zip")
    if not grid and not zipped:
        raise ConfigError(f"sweep file {p}: the grid is empty; give [grid] (or [zip]) lists")
    lengths = {k: len(v) for k, v in zipped.items()}
    if len(set(lengths.values())) > 1:
        shown = ", ".join(f"{k}: {n}" for k, n in lengths.items())
        raise ConfigError(f"sweep [zip] lists must have equal lengths ({shown})")
    n_points = count_points(grid, zipped)
    if n_points > max_points:
        sizes = [str(len(v)) for v in grid.values()]
        sizes += [f"{len(next(iter(zipped.values())))} [zip]"] if zipped else []
        shape = " x ".join(sizes)
        raise ConfigError(
            f"sweep file {p} has {n_points:,} points ({shape}), more than the cap of "
            f"{max_points:,}: split it, or raise the cap with --max-points {n_points}"
        )
    both = sorted((set(grid) | set(zipped)) & set(fixed)) or sorted(set(grid) & set(zipped))
    if both:
        raise ConfigError(f"sweep key '{both[0]}' is given twice ([set], [grid], [zip])")
    # every key known and every value legal on its own (combinations fail per point)
    load_config(config_path, fixed)
    for key, values in itertools.chain(grid.items(), zipped.items()):
        for v in values:
            load_config(config_path, {**fixed, key: v})
    axes = list(grid) + list(zipped)
    zip_rows = [dict(zip(zipped, row)) for row in zip(*zipped.values())] or [{}]
    points = [
        {**dict(zip(grid, combo)), **zrow}
        for combo in itertools.product(*grid.values())
        for zrow in zip_rows
    ]
    scene_entries = tree.get("scenes", ["default"])
    if not isinstance(scene_entries, list) or not scene_entries:
        raise ConfigError("sweep 'scenes' must be a non-empty list, e.g. scenes = [\"default\"]")
    scenes = [s for entry in scene_entries for s in _expand_scene(entry, base)]
    sweep = Sweep(p, mode, config_path, fixed, axes, points, scenes)
    sweep.tasks = [
        Task(i * len(scenes) + j, i, label, spec, {**fixed, **pt}, config_path, mode,
             config_sets_d)
        for i, pt in enumerate(points)
        for j, (label, spec) in enumerate(scenes)
    ]
    first: dict[str, Task] = {}
    for task in sweep.tasks:
        earlier = first.setdefault(task.point_id, task)
        if earlier is not task:
            raise ConfigError(
                f"sweep file {p}: point {task.point} on scene {task.scene!r} repeats point "
                f"{earlier.point} on scene {earlier.scene!r}: give each value and scene once"
            )
    return sweep


# ----------------------------------------------------------------------------------------------
# one task (runs on a worker)


def synthetic_pair(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """A deterministic textured pair of size WxH: the right view is the left shifted by
    min(8, W // 8) pixels (timing studies only: cycle counts do not depend on the pixels)."""
    rng = np.random.default_rng(h * 100003 + w)
    shift = min(8, w // 8)
    wide = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return np.ascontiguousarray(wide[:, shift:]), np.ascontiguousarray(wide[:, :w])


def load_scene_spec(spec: str) -> dict:
    if spec == "default":
        return default_scene()
    size = _synthetic_size(spec)
    if size is not None:
        left, right = synthetic_pair(*size)
        return {"left": left, "right": right, "gt": None, "masks": {}, "ndisp": None}
    return load_scene(find_scene(spec))


def flatten(tree, prefix: str = "", out: dict | None = None) -> dict[str, Any]:
    """Nested dicts -> {"a.b.c": value}; lists as JSON text; FIFO histograms left out."""
    out = {} if out is None else out
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if key == "occupancy_histogram":
            continue
        if isinstance(value, dict):
            flatten(value, name + ".", out)
        elif isinstance(value, (list, tuple)):
            out[name] = json.dumps(list(value))
        elif value is None:
            out[name] = ""
        else:
            out[name] = value
    return out


def area_columns(area: dict, power: dict | None = None) -> dict[str, Any]:
    """A row's silicon columns: ``area_mm2`` (the chip; "" where the node has no SRAM
    figure), ``logic_mm2`` and ``sram_mm2`` (:func:`~sim.cycle.area.chip_area`'s totals); and
    ``power_mw``, the average power (``average_power_mw``), where the report has a ``power``
    section giving it (:mod:`sim.cycle.power`)."""
    t = area["totals"]
    out = {"area_mm2": t["chip_mm2"], "logic_mm2": t["logic_mm2"], "sram_mm2": t["sram_mm2"]}
    if power and power.get("average_power_mw") is not None:
        out["power_mw"] = power["average_power_mw"]
    return {k: "" if v is None else v for k, v in out.items()}


def _one_line(exc: BaseException) -> str:
    message = " ".join(str(exc).split()) or type(exc).__name__
    return message if isinstance(exc, UserError) else f"{type(exc).__name__}: {message}"


def _error_row(task: Task, message: str) -> dict[str, Any]:
    return {"point": task.point, "scene": task.scene, "point_id": task.point_id,
            **task.overrides, "status": "error", "error": message}


def run_task(task: Task) -> dict[str, Any]:
    """Run one point x scene; never raises: a failure becomes a row with its error."""
    row: dict[str, Any] = {"point": task.point, "scene": task.scene, "point_id": task.point_id}
    row.update(task.overrides)
    try:
        row.update(_run(task))
        row["status"], row["error"] = "ok", ""
    except Exception as exc:  # noqa: BLE001 -- recorded, the sweep goes on
        return _error_row(task, _one_line(exc))
    return row


def _run(task: Task) -> dict[str, Any]:
    data = load_scene_spec(task.scene_spec)
    over = dict(task.overrides)
    if data.get("ndisp") and "sva.disparities" not in over and not task.config_sets_d:
        over["sva.disparities"] = legal_disparities(data["ndisp"])
    cfg = load_config(task.config_path, over)
    left, right = prepare_pair(data["left"], data["right"])
    est = estimate(cfg, left.shape)  # the plan refuses a chip it cannot build (D not below W)
    if task.mode == "estimate":
        report = dict(est)
        report.pop("paper")
    else:
        report = run(left, right, mode=task.mode, config=cfg, gt=data.get("gt"),
                     masks=data.get("masks")).report
    area = report.pop("area", None) or chip_area(build_plan(cfg, left.shape), cfg.power.node)
    power = report.pop("power", None)  # hundreds of per-block figures: the row keeps power_mw
    flat = flatten(report)
    flat.update(area_columns(area, power))
    flat["sram_bits"] = sum(est["sram_bits_total"][k] for k in ("nna_stereo", "sva", "fifos"))
    for key in ("throughput.fps_bound", "throughput.bottleneck", "throughput.merge_depth_needed",
                "throughput.camera_fps", "latency.first_output_us", "latency.frame_ms"):
        flat[f"estimate.{key}"] = flatten(est)[key]
    return flat


# ----------------------------------------------------------------------------------------------
# running


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored (in the main thread only): worker processes started meanwhile inherit
    the ignore, so a Ctrl-C at the terminal reaches only this process, which shuts them down;
    also keeps a second Ctrl-C from cutting the shutdown short."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def _dask_quiet(verbose: bool) -> Iterator[None]:
    """Dask's log (and tornado's, asyncio's, bokeh's) and warnings kept off stderr while the
    sweep runs, unless ``verbose``."""
    if verbose:
        yield
        return
    names = set(DASK_LOGGERS) | {
        name for name in logging.root.manager.loggerDict if name.split(".")[0] in DASK_LOGGERS
    }
    saved = [(lg, lg.level) for lg in map(logging.getLogger, sorted(names))]
    try:
        for lg, _ in saved:
            lg.setLevel(_SILENT)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", module=r"(distributed|tornado|bokeh)(\.|$)")
            yield
    finally:
        for lg, level in saved:
            lg.setLevel(level)


@contextlib.contextmanager
def _dask_client(scheduler: str | None, workers: int, verbose: bool) -> Iterator[Any]:
    """A client of ``scheduler``, else of a new local cluster; both closed with short
    timeouts at the end (also after Ctrl-C)."""
    from distributed import Client, LocalCluster

    client = cluster = None
    try:
        if scheduler:
            try:
                client = Client(scheduler, timeout="15s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(
                    f"cannot reach the Dask scheduler {scheduler}: {_one_line(exc)}"
                ) from None
        else:
            with _sigint_ignored():
                try:
                    cluster = LocalCluster(
                        n_workers=workers, threads_per_worker=1, processes=True,
                        host="127.0.0.1", dashboard_address=None,
                        # the scheduler's HTTP routes on a free loopback port: no dashboard, and
                        # no "port 8787 is already in use" when another cluster has it
                        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                        silence_logs=logging.INFO if verbose else _SILENT,
                    )
                    client = Client(cluster)
                except (OSError, TimeoutError) as exc:
                    raise InputError(
                        f"cannot start a local Dask cluster: {_one_line(exc)}"
                    ) from None
        yield client
    finally:
        with _sigint_ignored():
            for closing in (client, cluster):
                if closing is not None:
                    with contextlib.suppress(Exception):
                        closing.close(timeout=CLOSE_TIMEOUT_S)


def _worker_threads(client, workers: int) -> int:
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001 -- a client without nthreads(): the requested count
        return max(1, workers)


def _run_bounded(client, todo: list[Task], in_flight: int, on_row) -> None:
    """Submit ``todo`` with at most ``in_flight`` tasks submitted and not yet handed to
    ``on_row(task, row)`` (called in completion order); if anything stops the loop (Ctrl-C, a
    write error), the outstanding tasks are cancelled."""
    from distributed import as_completed

    queue = iter(todo)
    outstanding: dict[str, tuple[Any, Task]] = {}
    finished = as_completed()

    def submit_next() -> None:
        task = next(queue, None)
        if task is not None:
            fut = client.submit(run_task, task, pure=False,
                                key=f"stereosim-{task.point_id}-{task.index}")
            outstanding[fut.key] = (fut, task)
            finished.add(fut)

    try:
        for _ in range(in_flight):
            submit_next()
        for fut in finished:
            _, task = outstanding.pop(fut.key)
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 -- a worker died or the task was cancelled
                row = _error_row(task, _one_line(exc))
            fut.release()
            on_row(task, row)
            submit_next()
    finally:
        if outstanding:
            with contextlib.suppress(Exception):
                client.cancel([fut for fut, _ in outstanding.values()], force=True)


def run_sweep(sweep: Sweep, out_dir: str | Path, *, scheduler: str | None = None,
              workers: int = 2, progress: bool = True, client=None, verbose: bool = False,
              in_flight: int | None = None) -> dict[str, int]:
    """Run every task not already finished in ``out_dir/results.csv``; returns counts.

    ``client``: an existing ``distributed.Client`` to use (else one is made from
    ``scheduler``/``workers`` and closed at the end). ``in_flight``: the most tasks submitted
    and not yet written (default :data:`IN_FLIGHT_PER_WORKER` per worker thread). A Ctrl-C
    (KeyboardInterrupt) cancels the outstanding tasks, closes the cluster and propagates; the
    CSV then holds every row finished so far.
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {out}: {describe_os_error(exc)}"
                         ) from None
    csv_path = out / CSV_NAME
    done = done_point_ids(csv_path)
    todo = [t for t in sweep.tasks if t.point_id not in done]
    counts = {"tasks": len(sweep.tasks), "skipped": len(sweep.tasks) - len(todo), "ok": 0,
              "error": 0}
    if todo:
        with contextlib.ExitStack() as stack:
            stack.enter_context(_dask_quiet(verbose))
            if client is None:
                client = stack.enter_context(_dask_client(scheduler, workers, verbose))
            limit = in_flight or IN_FLIGHT_PER_WORKER * _worker_threads(client, workers)
            # on stderr, and only when it is a terminal (core/progress.py)
            bar = stack.enter_context(progress_bar(len(todo), "sweep", "run",
                                                   quiet=not progress))

            def on_row(task: Task, row: dict) -> None:
                append_rows(csv_path, [row], sweep.axes)
                counts[row["status"]] += 1
                bar.update(1)

            _run_bounded(client, todo, max(1, limit), on_row)
    finish_results(csv_path, sweep.tasks, sweep.axes)
    return counts
