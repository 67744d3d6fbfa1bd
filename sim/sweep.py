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
``data:NAME`` is NAME inside the shared data folder (:func:`sim.datasets.shared_data_dir`), and a
NAME that resolves outside that folder (``data:../..``, an absolute path, a symbolic link out of
it) is refused. Relative paths are relative to the sweep file. A Middlebury scene's D comes from
its ``calib.txt`` unless the sweep sets ``sva.disparities``.

A sweep has at most :data:`MAX_POINTS` points (the product of the [grid] list lengths times the
[zip] length, counted before anything is expanded); ``max_points`` (``--max-points N``) raises
the cap. Every key and value is checked before anything runs; an unreadable sweep or config file
and a point given twice (the same overrides on the same scene) are one-line errors.

Every point x scene is one task on a Dask cluster: a ``LocalCluster`` of worker processes on the
loopback interface by default, or an existing cluster (``scheduler="tcp://host:8786"``) -- the
same code path. The results go to ``results.csv`` in the output folder: one row per point x
scene, in plan order whatever the completion order, with every override, every report figure
(nested keys flattened with dots; FIFO occupancy histograms left out), the analytic estimate
(``estimate.*``) and, when the scene has GT, the accuracy (``metrics.<mask>.<metric>``). The file
is rewritten atomically after every finished task, so an interrupted sweep leaves a valid CSV,
and a rerun skips every row already there with ``status`` ok (failed rows are retried). A failing
task is recorded with ``status`` error and a one-line ``error`` without stopping the others.
"""

from __future__ import annotations

import csv
import hashlib
import io
import itertools
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.api import prepare_pair, run
from sim.config import load_config
from sim.cycle.estimate import estimate
from sim.datasets import (
    default_scene,
    find_scene,
    find_scenes,
    legal_disparities,
    load_scene,
    shared_data_dir,
)
from sim.errors import ConfigError, InputError, UserError
from sim.outputs import atomic_write_bytes, describe_os_error

MODES = ("cycle", "functional", "estimate")
SWEEP_KEYS = ("mode", "scenes", "config", "set", "grid", "zip")
LEAD_COLUMNS = ("point", "scene", "status", "error", "point_id")
CSV_NAME = "results.csv"
MAX_POINTS = 10_000  # default cap on a sweep's points (grid x zip); max_points / --max-points


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


def _read_toml(p: Path, what: str, error: type[UserError]) -> dict:
    """A TOML file as a tree; every way it cannot be read is one ``error`` line."""
    if p.is_dir():
        raise error(f"{what} {p} is a folder: give the path of a TOML file")
    if not p.is_file():
        raise error(f"{what} {p} not found: give the path of a TOML file")
    try:
        text = p.read_text()
    except OSError as exc:
        raise error(f"cannot read {what} {p} ({describe_os_error(exc)}): check the file and "
                    "its permissions") from None
    except UnicodeDecodeError:
        raise error(f"{what} {p} is not UTF-8 text: give a TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {p} is not valid TOML: {exc}") from None


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
    tree = _read_toml(p, "sweep file", InputError)
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
        sva = _read_toml(Path(config_path), "config file", ConfigError).get("sva", {})
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
    h, w = left.shape
    if cfg.sva.disparities >= w:
        raise ConfigError(
            f"sva.disparities={cfg.sva.disparities} is not smaller than the image width {w}"
        )
    est = estimate(cfg, (h, w))
    if task.mode == "estimate":
        report = dict(est)
        report.pop("paper")
    else:
        report = run(left, right, mode=task.mode, config=cfg, gt=data.get("gt"),
                     masks=data.get("masks")).report
    flat = flatten(report)
    flat["sram_bits"] = sum(est["sram_bits_total"][k] for k in ("nna_stereo", "sva", "fifos"))
    for key in ("throughput.fps", "throughput.bottleneck", "latency.first_output_ms",
                "latency.frame_ms"):
        flat[f"estimate.{key}"] = flatten(est)[key]
    return flat


# ----------------------------------------------------------------------------------------------
# the CSV


def read_rows(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        return []
    try:
        with path.open(newline="") as f:
            return list(csv.DictReader(f))
    except (OSError, csv.Error, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from None


def _cell(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def write_rows(path: Path, rows: list[dict], axes: list[str]) -> None:
    """All rows, atomically, with a deterministic column order: the lead columns, the swept
    keys, then every other column sorted."""

    seen = set()
    for row in rows:
        seen.update(row)
    lead = [c for c in LEAD_COLUMNS] + [a for a in axes if a not in LEAD_COLUMNS]
    columns = lead + sorted(seen - set(lead))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({c: _cell(row[c]) if c in row else "" for c in columns})
    atomic_write_bytes(path, buf.getvalue().encode())


# ----------------------------------------------------------------------------------------------
# running


def _cluster(scheduler: str | None, workers: int):
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="15s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
    cluster = LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None, silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster


def run_sweep(sweep: Sweep, out_dir: str | Path, *, scheduler: str | None = None,
              workers: int = 2, progress: bool = True, client=None) -> dict[str, int]:
    """Run every task not already finished in ``out_dir/results.csv``; returns counts.

    ``client``: an existing ``distributed.Client`` to use (else one is made from
    ``scheduler``/``workers`` and closed at the end).
    """
    from distributed import as_completed
    from tqdm import tqdm

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {out}: {exc.strerror}") from None
    csv_path = out / CSV_NAME
    previous = read_rows(csv_path)
    done = {r.get("point_id"): r for r in previous if r.get("status") == "ok"}
    planned = {t.point_id for t in sweep.tasks}
    extra = [r for r in previous if r.get("point_id") not in planned]
    results: dict[int, dict] = {}
    todo = []
    for task in sweep.tasks:
        if task.point_id in done:
            results[task.index] = done[task.point_id]
        else:
            todo.append(task)

    def save():
        rows = [results[i] for i in sorted(results)] + extra
        write_rows(csv_path, rows, sweep.axes)

    counts = {"tasks": len(sweep.tasks), "skipped": len(sweep.tasks) - len(todo), "ok": 0,
              "error": 0}
    if not todo:
        save()
        return counts
    own = client is None
    cluster = None
    if own:
        client, cluster = _cluster(scheduler, workers)
    try:
        futures = {client.submit(run_task, t, pure=False, key=f"stereosim-{t.point_id}-{t.index}"):
                   t for t in todo}
        bar = tqdm(total=len(todo), desc="sweep", unit="run", disable=not progress or None)
        for fut in as_completed(futures):
            task = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 -- a worker died: record it
                row = {"point": task.point, "scene": task.scene, "point_id": task.point_id,
                       **task.overrides, "status": "error",
                       "error": f"{type(exc).__name__}: {' '.join(str(exc).split())}"}
            results[task.index] = row
            counts[row["status"]] += 1
            save()
            bar.update(1)
        bar.close()
    finally:
        if own:
            client.close()
            if cluster is not None:
                cluster.close()
    return counts
