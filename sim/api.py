"""Public Python interface: ``stereosim.run(left, right, ...) -> Result`` for one stereo frame,
``stereosim.run_stream(pairs, ...) -> Stream`` for a stream of them."""

from __future__ import annotations

import dataclasses
import os
import platform
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numba
import numpy as np

from stereosim.core.config import ChipConfig, check_config, config_to_dict, load_config
from stereosim.core.config.backend import BACKEND_KEYS
from stereosim.core.config.loader import tuned_backend
from stereosim.core.datasets import default_scene, find_scene, parse_calib
from stereosim.core.datasets import load_scene as read_scene
from stereosim.core.errors import ConfigError, InputError
from stereosim.core.heap import keep_freed_memory
from stereosim.core.io import MAX_PIXELS, check_gt_values, pixel_cap, to_grey
from stereosim.core.progress import compile_notice
from stereosim.nna.conv.weights import SHIPPED_WEIGHTS
from stereosim.nna.descriptor import compute_descriptor
from stereosim.sim.cycle.area import chip_area
from stereosim.sim.cycle.contract import RunStopped, stop_report
from stereosim.sim.cycle.energy import energy_report, energy_table
from stereosim.sim.cycle.figures import architecture_report
from stereosim.sim.cycle.frames import FrameSupply, check_frame_count, functional_words
from stereosim.sim.cycle.lent import lent_report
from stereosim.sim.cycle.plan import ChipPlan, build_plan
from stereosim.sim.cycle.power import power_report
from stereosim.sim.cycle.report import power_basis
from stereosim.sim.cycle.simulate import simulate
from stereosim.sim.cycle.spec import resolve_chip
from stereosim.sim.formats import read_calibration
from stereosim.sim.metrics import check_truth, evaluate, mean_metrics, undefined_metrics
from stereosim.sim.tracing import run_traced, trace_section
from stereosim.sva.hamming.noise import band_rows
from stereosim.sva.pipeline.pipeline import frame_cost, sva_stream
from stereosim.sva.wta.wta import to_float

MODES = ("functional", "cycle")
# report.json's layout: 2 names every unit and fps kind in its keys; 3 names a stream's span
# apart from its frames' latencies and gives a stream's accuracy per frame (docs/report.md)
REPORT_VERSION = 3
VERSION = "0.1.0"  # the one place (pyproject.toml reads it: [tool.setuptools.dynamic])

# frame after frame, the arrays of a frame reuse the last one's pages (core.heap)
keep_freed_memory()


def version_text() -> str:
    """What ``stereosim --version`` prints: stereosim's version and the versions that decide
    its numbers (Python, NumPy, Numba, OpenCV)."""
    return (f"stereosim {VERSION} (Python {platform.python_version()}, NumPy {np.__version__}, "
            f"Numba {numba.__version__}, OpenCV {cv2.__version__})")


@dataclass(frozen=True)
class Result:
    """What one simulated frame produced.

    ``disparity``: float32 (H, W), pixels, ``inf`` where invalid. ``disparity_fixed``: the chip's
    output words, int32 with ``subpixel_bits`` fractional bits, -1 where invalid. ``report``: the
    dict written as report.json. ``config``: the effective configuration. ``trace``: the
    :class:`traces.log.TraceLog` of a traced cycle run, else None.
    """

    disparity: np.ndarray
    disparity_fixed: np.ndarray
    report: dict
    config: ChipConfig
    trace: Any = None


def prepare_pair(left, right, max_pixels: int | None = MAX_PIXELS) -> tuple[np.ndarray, np.ndarray]:
    """Validate a stereo pair and return both views as grey uint8 (H, W).

    RGB (H, W, 3) views are converted with the integer BT.601 formula of :func:`core.io.to_grey`.
    A pair of more than ``max_pixels`` pixels per view is refused; None or 0 mean no cap, as
    ``--max-pixels 0`` does (:func:`core.io.pixel_cap`).
    """
    for name, img in (("left", left), ("right", right)):
        if not isinstance(img, np.ndarray):
            raise InputError(f"the {name} image must be a numpy array, got {type(img).__name__}")
    gl, gr = to_grey(left), to_grey(right)
    if gl.shape != gr.shape:
        raise InputError(
            f"left and right images differ in size ({gl.shape[1]}x{gl.shape[0]} vs "
            f"{gr.shape[1]}x{gr.shape[0]}): give a rectified pair of equal size"
        )
    h, w = gl.shape
    if h < 1 or w < 2:
        raise InputError(
            f"the images are {w}x{h}: a stereo pair needs at least 2 columns and 1 row")
    cap = pixel_cap(max_pixels)
    if h * w > cap:
        raise InputError(
            f"the images are {w}x{h} ({h * w / 1e6:.1f} M pixels), above the cap of "
            f"{cap / 1e6:.1f} M pixels: downsample them or raise the cap (--max-pixels, "
            "max_pixels=)"
        )
    return gl, gr


def resolve_config(config: ChipConfig | str | None, overrides: dict[str, Any] | None) -> ChipConfig:
    """The checked configuration of ``run``'s ``config``/``overrides``: a :class:`ChipConfig`
    (however built, it passes :func:`core.config.check_config`, once: the run's entry), a TOML
    path or None. The run then resolves it (:func:`~sim.cycle.spec.resolve_chip`) into the
    spec its plan carries down."""
    if isinstance(config, ChipConfig):
        if overrides:
            raise ConfigError("give either a ChipConfig object or overrides, not both")
        return check_config(config)
    if config is not None and not isinstance(config, (str, os.PathLike)):
        raise ConfigError(
            f"config must be a ChipConfig, the path of a TOML file or None; got "
            f"{type(config).__name__}"
        )
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(
            f"overrides must be a dict of dotted keys, e.g. {{'sva.p1': 10}}; got "
            f"{type(overrides).__name__}"
        )
    return load_config(config, overrides)


def load_scene(folder, *, gt_scale: float | None = None,
               max_pixels: int | None = MAX_PIXELS) -> dict:
    """A scene folder as arrays, as ``stereosim run FOLDER`` reads it: Middlebury 2014
    (``im0.png``, ``im1.png``, ``disp0GT.pfm``, ``mask0nocc.png``, ``calib.txt``), 2005/2006 and
    2003 layouts (:mod:`core.datasets`), or ``"default"`` for the embedded scene.

    Returns a dict: ``name``; ``left``, ``right`` (uint8, grey or RGB); ``gt`` (float32
    disparities in pixels, ``inf`` unknown; None without GT; ``gt_scale``: the value per
    pixel of a PNG GT of a non-standard size); ``masks`` (``nonocc`` and/or ``all``, boolean);
    ``ndisp`` (calib.txt's, or None); ``calibration`` (a :class:`sim.formats.Calibration` from
    calib.txt when it has the camera's keys, else None) and ``note``. Every problem raises a
    :class:`core.errors.UserError` with one line."""
    if isinstance(folder, str) and folder == "default":
        data = default_scene()
        data["calibration"] = None
        return data
    if not isinstance(folder, (str, os.PathLike)):
        raise InputError(f"folder must be a path or 'default'; got {type(folder).__name__}")
    scene = find_scene(folder, gt_scale=gt_scale)
    data = read_scene(scene, max_pixels=pixel_cap(max_pixels))
    calib = Path(folder) / "calib.txt"
    keys = parse_calib(calib) if calib.is_file() else {}
    data["calibration"] = read_calibration(calib) if "cam0" in keys else None
    return data


def run(
    left,
    right,
    *,
    mode: str = "cycle",
    config: ChipConfig | str | None = None,
    overrides: dict[str, Any] | None = None,
    gt: np.ndarray | None = None,
    masks: dict[str, np.ndarray] | None = None,
    trace=None,
    max_pixels: int | None = MAX_PIXELS,
    energy: str | os.PathLike | None = None,
) -> Result:
    """Simulate one stereo frame.

    ``mode="cycle"`` (the default, as in ``stereosim run``, ``eval`` and sweeps) runs the clocked
    chip (sources, NNA submodules, FIFOs, SVA, sink) -- the same output words plus cycle
    counts, latency, throughput, bottleneck and FIFO statistics -- on the engine ``sim.engine``
    selects (:mod:`sim.cycle.simulate`; the report's ``engine`` says which ran).
    ``mode="functional"`` runs the bit-exact integer model alone: the same words, no timing.

    ``left``/``right``: 2-D uint8 arrays (or RGB, converted to grey). ``config``: a
    :class:`ChipConfig`, a TOML path or None (defaults); ``overrides``: dotted keys such as
    ``{"sva.disparities": 128, "nna.descriptor": "census"}``. With ``gt`` (float32, inf unknown)
    the report gains ``metrics`` over ``masks`` (default: every pixel with known GT).
    ``trace``: a :class:`sim.tracing.TraceRequest` (cycle mode only): the result carries the
    recorded :class:`traces.log.TraceLog` (files are written by :func:`sim.tracing.trace_files`).
    ``max_pixels``: refuse larger views (default :data:`core.io.MAX_PIXELS`; None or 0: no cap).
    ``energy``: an energy table (TOML, :mod:`sim.cycle.energy`) for the cycle report's
    ``energy`` section instead of stereosim's 45 nm default.
    Every mistake raises a :class:`core.errors.UserError` before any kernel runs. A cycle run
    that stops early (``sim.max_cycles``, the automatic budget, a deadlock, a camera's
    overflow) raises a :class:`~sim.cycle.contract.RunStopped` whose ``report`` is the stopped
    run's report (:func:`stopped_report`) and whose ``trace`` is the log up to the stop (with
    ``trace``; None otherwise or when the window starts after the stop).
    """
    if mode not in MODES:
        raise ConfigError(f"mode must be one of {', '.join(MODES)}; got {mode!r}")
    table = _energy_table(energy, mode)
    cfg = resolve_config(config, overrides)
    gl, gr = prepare_pair(left, right, max_pixels)
    masks = check_ground_truth(gt, masks, gl.shape)
    # the chip resolved once (the network loaded, the widths derived) and handed down in the
    # plan, which refuses a chip that cannot be built, in every mode
    plan = build_plan(resolve_chip(cfg, checked=True), gl.shape)
    spec = plan.spec
    log = None
    if trace is not None and mode != "cycle":
        raise ConfigError("traces need the cycle model: use mode='cycle' (--mode cycle)")
    if mode == "cycle":
        try:
            if trace is not None:
                frame, log = run_traced(plan, gl, gr, trace)
            else:
                frame = simulate(plan, gl, gr)
        except RunStopped as stop:
            stop.report = stopped_report(plan, stop)
            raise
        fixed, cycle_report = frame.words, frame.report
    else:
        with compile_notice():
            desc_l = compute_descriptor(gl, spec.nna)
            desc_r = compute_descriptor(gr, spec.nna)
            fixed = sva_stream(desc_l, desc_r, gl, spec.sva, plan.part_bits)
    disp = to_float(fixed, cfg.sva.subpixel_bits)
    report = build_report(plan, mode, fixed, cycle_report["area"] if mode == "cycle" else None)
    if plan.hybrid:
        report["descriptor"]["frame"] = frame_cost_report(plan, gl)
    if mode == "cycle":
        report.update(cycle_report)
        if table is not None:
            _reprice(report, plan, frame, table)
    if gt is not None:
        report["metrics"] = evaluate(disp, gt, masks)
        notes = undefined_metrics(report["metrics"])
        if notes:
            report["metrics_undefined"] = notes
    return Result(disparity=disp, disparity_fixed=fixed, report=report, config=cfg, trace=log)


def check_ground_truth(gt, masks, shape: tuple[int, int]) -> dict | None:
    """The masks to score a map of ``shape`` with ``gt`` (given ``masks``, or every pixel of
    known GT), None without GT; the GT and masks are checked before any run, not after it."""
    if gt is None and masks:
        raise InputError("masks need ground truth: give gt= too")
    if gt is None:
        return None
    masks = check_truth(gt, {} if masks is None else masks, shape)[1]
    check_gt_values(np.asarray(gt, dtype=np.float64), "the gt= array")
    return masks or {"all": np.isfinite(gt)}


def _reprice(report: dict, plan, frame, table) -> None:
    """The cycle report's ``energy`` and ``power`` sections priced with the user's energy table
    ``table`` (the engines built them with the default)."""
    report["energy"] = energy_report(plan, frame.stats,
                                     *power_basis(report["throughput"], report["stream"]), table)
    report["power"] = power_report(plan, frame.stats, report["energy"], frame.frame_times,
                                   report["area"])


def _energy_table(path, mode: str):
    """The energy table of ``path`` (checked before any run), or None for the default."""
    if path is None:
        return None
    if mode != "cycle":
        raise ConfigError("an energy table needs the cycle model: use mode='cycle' (--mode "
                          "cycle)")
    return energy_table(path)


def part_report(cfg: ChipConfig, kind: str, bits: int) -> dict:
    """One part of the descriptor as the report gives it: its kind and bits, the census's
    window, kind and stride."""
    out = {"kind": kind, "bits": bits}
    if kind == "census":
        c = cfg.nna.census
        out.update(window=list(c.window), census_kind=c.kind, stride=c.stride)
    return out


def frame_cost_report(plan: ChipPlan, left: np.ndarray) -> dict:
    """The cost a hybrid frame whose left view is ``left`` is matched with: its weights [cnn,
    census], its largest cost, and with automatic weights the noise statistic that chose them
    (:func:`sva.pipeline.pipeline.frame_cost`, the rule the SVA applies)."""
    cost, noise = frame_cost(plan.part_bits, plan.cfg.sva, left)
    out = {"weights": list(cost.weights), "cost_max": cost.top}
    if noise is not None:
        out["noise"] = noise
    return out


def descriptor_report(plan: ChipPlan) -> dict:
    """The report's ``descriptor``: its kind and bits; for the CNN the network (its file, name
    and layers); and the SVA back end it runs with (:data:`~core.config.backend.BACKEND_KEYS`),
    what it was tuned with (the weight file's own back end, else the descriptor's defaults) and
    which keys the configuration changed from that."""
    cfg = plan.cfg
    out = {"kind": cfg.nna.descriptor, "bits": plan.descriptor_bits,
           "parts": [part_report(cfg, kind, bits) for kind, bits in plan.descriptor_parts],
           "cost_max": plan.cost_max, "cost_bits": cfg.sva.cost_bits}
    if plan.hybrid:
        s = cfg.sva
        out["weights"] = {"mode": s.weight_mode, "cost_weights": list(s.cost_weights)}
        if s.weight_mode == "auto":
            out["weights"].update(noisy_weights=list(s.noisy_weights),
                                  noise_threshold=s.noise_threshold,
                                  noise_gradient=s.noise_gradient,
                                  band_rows=band_rows(s, plan.shape[0]))
    if cfg.nna.descriptor in ("cnn", "hybrid"):
        weights = cfg.nna.cnn.weights
        path = SHIPPED_WEIGHTS if weights == "default" else weights
        layers = plan.blocks_of("nna")[0].layers
        out["network"] = {
            "file": weights, "name": Path(path).name.removesuffix(".npz"),
            "layers": [f"{2 * lay.half + 1}x{2 * lay.half + 1}x{lay.channels_in}x"
                       f"{lay.channels_out}" for lay in layers],
            "macs_per_pixel": sum(lay.macs_per_pixel for lay in layers)}
    tuned, carried = tuned_backend({"nna": dataclasses.asdict(cfg.nna)})
    values = {k: getattr(cfg.sva, k) for k in BACKEND_KEYS}
    out["backend"] = {
        **values,
        "tuned_with": ("the network's weight file" if carried
                       else f"the {cfg.nna.descriptor} descriptor's defaults"),
        "changed": [k for k in BACKEND_KEYS if tuned.get(k) != values[k]],
    }
    return out


def build_report(plan: ChipPlan, mode: str, fixed: np.ndarray | None,
                 area: dict | None = None) -> dict:
    """The report's sections every run has -- a frame's, a stream's (which adds ``frames``), a
    stopped run's -- and the ``output`` words' (``fixed``; None: a stream or a stopped run has
    no one frame's output). ``area``: the chip's area and leakage by block at ``power.node``
    (:func:`~sim.cycle.area.chip_area`, from the plan) -- a cycle run's report has it already
    (``area``), else it is worked out here."""
    cfg = plan.cfg
    h, w = plan.shape
    report = {
        "architecture": architecture_report(plan),
        "report_version": REPORT_VERSION,
        "stereosim": VERSION,
        "mode": mode,
        "image": {"width": w, "height": h},
        "descriptor": descriptor_report(plan),
        "config": config_to_dict(cfg),
        "area": chip_area(plan, cfg.power.node) if area is None else area,
    }
    if plan.lent is not None:
        report["lent_network"] = lent_report(plan.lent, plan.dram, h * w)
    if fixed is not None:
        valid = int(np.count_nonzero(fixed >= 0))
        report["output"] = {
            "valid_pixels": valid,
            "invalid_percent": round(100.0 * (h * w - valid) / (h * w), 4),
            "fractional_bits": cfg.sva.subpixel_bits,
        }
    return report


def stopped_report(plan: ChipPlan, stop: RunStopped) -> dict:
    """The report of a cycle run that stopped: what every run reports of itself, the engine,
    the ``stopped`` section (:func:`sim.cycle.contract.stop_report`: the reason, the instant, the
    cycles per clock domain, every FIFO's and block's state) and, for a traced run, the
    ``trace`` section -- and nothing that belongs to a complete frame (no output, metrics,
    throughput or fps)."""
    report = build_report(plan, "cycle", None)
    report["engine"] = stop.engine
    report["stopped"] = stop_report(stop, plan)
    if stop.trace is not None:
        report["trace"] = trace_section(stop.trace, stop.outputs_in_window)
    return report


# ---- streams of frames ---------------------------------------------------------------------------


@dataclass(frozen=True)
class FrameOutput:
    """One frame of a stream: its index (the camera frame of the stream), ``disparity``
    (float32, inf invalid) and ``disparity_fixed`` (the chip's words); with camera pairs
    sharing the chip (``sva.pairs``) its ``pair`` and that pair's frame ``pair_frame`` (the
    input frame it shows); with ground truth its ``metrics`` (as ``run``'s report gives them:
    ``{mask: {metric: value}}``), else None."""

    index: int
    disparity: np.ndarray
    disparity_fixed: np.ndarray
    pair: int
    pair_frame: int
    metrics: dict | None = None

    @property
    def invalid_percent(self) -> float:
        valid = int(np.count_nonzero(self.disparity_fixed >= 0))
        return round(100.0 * (self.disparity_fixed.size - valid) / self.disparity_fixed.size, 4)


class Stream:
    """A simulated stream of stereo pairs (:func:`run_stream`). ``report``: the stream's report
    -- architecture, configuration and, in cycle mode, the cycle report of the whole stream
    (``stream``: frames, sustained fps, each frame's latency, the stream's span;
    ``throughput``: the work bound) -- known before any frame's words. Iterating yields a
    :class:`FrameOutput` per frame the chip took (a camera's dropped frames have none), in
    order, each computed when it is asked for: a stream of any length takes the memory of a
    few frames. With ``sva.pairs`` = P camera pairs every pair sees the input stream: P outputs
    per input frame. With ground truth each frame carries its metrics, and once every frame has
    been iterated the report gains ``metrics_per_frame`` and their mean, ``metrics_mean``."""

    def __init__(self, report: dict, config: ChipConfig, plan: ChipPlan, supply: FrameSupply,
                 words: dict | None = None, truth: tuple | None = None):
        self.report = report
        self.config = config
        self._plan = plan
        self._supply = supply
        self._words = words  # the readable kernel's words, when it ran
        self._truth = truth  # (gt, masks) that score every frame, or None

    def _taken(self) -> list[int]:
        dropped = set(self.report.get("stream", {}).get("dropped_frames", ()))
        return [f for f in range(self._plan.frames) if f not in dropped]

    def __len__(self) -> int:
        return len(self._taken())

    @property
    def plan(self) -> ChipPlan:
        """The chip plan of the stream (its frames and frame shape)."""
        return self._plan

    @property
    def supply(self) -> FrameSupply:
        """The stream's frames, grey, read on demand."""
        return self._supply

    def __iter__(self):
        plan = self._plan
        pairs = plan.pairs
        bits = plan.cfg.sva.subpixel_bits
        # the input frame last computed, its words, metrics and (the hybrid) cost
        shown = (-1, None, None, None)
        scored = []
        for f in self._taken():
            i = f // pairs
            new = shown[0] != i
            # the pair is read once: for its words (functional) and the hybrid's weights
            pair = (self._supply.pair(i) if new and (self._words is None or plan.hybrid)
                    else None)
            if self._words is not None:
                fixed = self._words.pop(f)
            elif not new:
                fixed = shown[1]
            else:
                fixed = functional_words(plan.spec, plan.part_bits, *pair)
            disparity = to_float(fixed, bits)
            metrics = None
            if self._truth is not None:  # pairs showing one input frame share its words
                metrics = evaluate(disparity, *self._truth) if new else shown[2]
                scored.append({"frame": f, "metrics": metrics})
            cost = None
            if plan.hybrid:  # the weights each frame was matched with
                cost = frame_cost_report(plan, pair[0]) if new else shown[3]
                self.report["descriptor"].setdefault("frames", []).append({"frame": f, **cost})
            shown = (i, fixed, metrics, cost)
            yield FrameOutput(f, disparity, fixed, f % pairs, i, metrics)
        if self._truth is not None:
            self._score(scored)

    def _score(self, scored: list[dict]) -> None:
        """The report's accuracy of a stream: every frame's metrics and their mean."""
        self.report["metrics_per_frame"] = scored
        self.report["metrics_mean"] = mean_metrics([s["metrics"] for s in scored])
        notes = undefined_metrics(self.report["metrics_mean"])
        self.report.pop("metrics_undefined", None)
        if notes:
            self.report["metrics_undefined"] = notes


def stream_supply(pairs, max_pixels: int | None = MAX_PIXELS,
                  camera_pairs: int = 1) -> FrameSupply:
    """A :class:`FrameSupply` of grey pairs from a sequence of (left, right) images (anything
    with ``len`` and indexing, read on demand) or an existing supply; every pair checked as
    :func:`prepare_pair` checks one, and a stream of more than
    :data:`~sim.cycle.frames.MAX_FRAMES` camera frames (seen by ``camera_pairs`` pairs, as
    ``sva.pairs`` says) refused before any frame is read."""
    if isinstance(pairs, FrameSupply):
        count, read = pairs.count, pairs.pair
    else:
        if (not hasattr(pairs, "__len__") or not hasattr(pairs, "__getitem__")
                or isinstance(pairs, (Mapping, str, bytes))):  # a dict would give its keys
            raise InputError(
                f"pairs must be a sequence of (left, right) images or a FrameSupply; got "
                f"{type(pairs).__name__}")
        try:
            count = len(pairs)
        except (TypeError, ValueError, OverflowError) as exc:  # a __len__ below 0, say
            raise InputError(f"pairs has no usable length (len() raised {exc}): give a "
                             "sequence of (left, right) images") from None

        def read(f):
            item = pairs[f]
            if not isinstance(item, (tuple, list)) or len(item) != 2:
                raise InputError(f"pair {f} of the stream is not a (left, right) pair")
            return item
    if count < 1:
        raise InputError("the stream has no frames: give at least one (left, right) pair")
    check_frame_count(count, camera_pairs)
    first = prepare_pair(*read(0), max_pixels)
    return FrameSupply(count, first[0].shape,
                       lambda f: first if f == 0 else prepare_pair(*read(f), max_pixels))


def run_stream(pairs, *, mode: str = "cycle", config: ChipConfig | str | None = None,
               overrides: dict[str, Any] | None = None, gt: np.ndarray | None = None,
               masks: dict[str, np.ndarray] | None = None, sink_stall=None,
               max_pixels: int | None = MAX_PIXELS,
               energy: str | os.PathLike | None = None, progress=None) -> Stream:
    """Simulate a stream of stereo pairs of one size, back to back through the chip.

    ``pairs``: a sequence of (left, right) images (a list, or any object with ``len`` and
    indexing that reads frames on demand) or a :class:`~sim.cycle.frames.FrameSupply`, at
    most :data:`~sim.cycle.frames.MAX_FRAMES` frames (times ``sva.pairs``).
    ``mode="cycle"`` (default) times the whole stream first -- frames overlap in the pipeline
    as the blocks allow -- and reports the measured sustained frame rate and each frame's
    latency beside the work bound; the frames' words then come one by one as the returned
    :class:`Stream` is iterated. ``mode="functional"``: the words alone. ``gt`` and ``masks``
    (as :func:`run` takes them) score every frame -- the ground truth of a pair repeated, or of
    a scene that does not move. ``sink_stall``: the sink's pattern -- periodic ``(period,
    allowed_phase)`` or a script of 0/1 (:func:`~sim.cycle.rules.sink_pattern`). Mistakes
    raise a :class:`core.errors.UserError` before any kernel runs (a frame of another size,
    when it is read). A stream that stops early raises
    :class:`~sim.cycle.contract.RunStopped` as :func:`run` does (its ``report`` adds ``frames``;
    its ``plan`` and ``supply`` let :func:`sim.tracing.run_traced` trace it up to the stop).
    ``progress(frames)``: how many frames the compiled engine's timing pass has finished, said
    now and then while it runs."""
    if mode not in MODES:
        raise ConfigError(f"mode must be one of {', '.join(MODES)}; got {mode!r}")
    table = _energy_table(energy, mode)
    cfg = resolve_config(config, overrides)
    supply = stream_supply(pairs, max_pixels, cfg.sva.pairs)
    masks = check_ground_truth(gt, masks, supply.shape)
    plan = build_plan(resolve_chip(cfg, checked=True), supply.shape, supply.count)
    words, cycle_report = None, {}
    if mode == "cycle":
        try:
            if cfg.sim.engine == "readable":
                words = {}
                frame = simulate(plan, supply, sink_stall=sink_stall,
                                 on_frame=lambda f, fixed: words.__setitem__(f, fixed.copy()))
            else:
                frame = simulate(plan, supply, sink_stall=sink_stall, words=False,
                                 progress=progress)
        except RunStopped as stop:
            stop.report = stopped_report(plan, stop) | {"frames": supply.count}
            stop.plan, stop.supply = plan, supply  # to trace it up to the stop
            raise
        cycle_report = frame.report
    report = build_report(plan, mode, None, cycle_report.get("area")) | {"frames": supply.count}
    report.update(cycle_report)
    if table is not None:
        _reprice(report, plan, frame, table)
    return Stream(report, cfg, plan, supply, words, None if gt is None else (gt, masks))
