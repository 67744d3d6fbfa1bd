"""Public Python interface: ``sim.run(left, right, ...) -> Result``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from nna.descriptor import compute_descriptor
from sim.config import ChipConfig, check_config, config_to_dict, load_config
from sim.cycle.plan import ChipPlan, architecture_report, build_plan
from sim.cycle.simulate import simulate
from sim.errors import ConfigError, InputError
from sim.io import MAX_PIXELS, check_gt_values, to_grey
from sim.metrics import check_truth, evaluate, undefined_metrics
from sim.tracing import run_traced
from sva.pipeline import sva_stream
from sva.wta import to_float

MODES = ("functional", "cycle")
VERSION = "0.1.0"


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

    RGB (H, W, 3) views are converted with the integer BT.601 formula of :func:`sim.io.to_grey`.
    A pair of more than ``max_pixels`` pixels per view is refused (None: no cap).
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
        raise InputError(f"the images are {w}x{h}: a stereo pair needs at least 2 columns and 1 row")
    if max_pixels is not None and h * w > max_pixels:
        raise InputError(
            f"the images are {w}x{h} ({h * w / 1e6:.1f} M pixels), above the cap of "
            f"{max_pixels / 1e6:.1f} M pixels: downsample them or raise the cap (--max-pixels, "
            "max_pixels=)"
        )
    return gl, gr


def resolve_config(config: ChipConfig | str | None, overrides: dict[str, Any] | None) -> ChipConfig:
    """The checked configuration of ``run``'s ``config``/``overrides``: a :class:`ChipConfig`
    (however built, it passes :func:`sim.config.check_config`), a TOML path or None."""
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


def run(
    left,
    right,
    *,
    mode: str = "functional",
    config: ChipConfig | str | None = None,
    overrides: dict[str, Any] | None = None,
    gt: np.ndarray | None = None,
    masks: dict[str, np.ndarray] | None = None,
    trace=None,
    max_pixels: int | None = MAX_PIXELS,
) -> Result:
    """Simulate one stereo frame.

    ``mode="functional"`` runs the bit-exact integer model; ``mode="cycle"`` runs the clocked
    chip (sources, NNA submodules, FIFOs, SVA, sink) -- the same output words plus cycle
    counts, latency, throughput, bottleneck and FIFO statistics -- on the engine ``sim.engine``
    selects (:mod:`sim.cycle.simulate`; the report's ``engine`` says which ran).

    ``left``/``right``: 2-D uint8 arrays (or RGB, converted to grey). ``config``: a
    :class:`ChipConfig`, a TOML path or None (defaults); ``overrides``: dotted keys such as
    ``{"sva.disparities": 128, "nna.descriptor": "census"}``. With ``gt`` (float32, inf unknown)
    the report gains ``metrics`` over ``masks`` (default: every pixel with known GT).
    ``trace``: a :class:`sim.tracing.TraceRequest` (cycle mode only): the result carries the
    recorded :class:`traces.log.TraceLog` (files are written by :func:`sim.tracing.trace_files`).
    ``max_pixels``: refuse larger views (default :data:`sim.io.MAX_PIXELS`; None = no cap).
    Every mistake raises a :class:`sim.errors.UserError` before any kernel runs.
    """
    if mode not in MODES:
        raise ConfigError(f"mode must be one of {', '.join(MODES)}; got {mode!r}")
    cfg = resolve_config(config, overrides)
    gl, gr = prepare_pair(left, right, max_pixels)
    if gt is None and masks:
        raise InputError("masks need ground truth: give gt= too")
    if gt is not None:  # checked before the run, not after it
        masks = check_truth(gt, {} if masks is None else masks, gl.shape)[1]
        check_gt_values(np.asarray(gt, dtype=np.float64), "the gt= array")
        masks = masks or {"all": np.isfinite(gt)}
    plan = build_plan(cfg, gl.shape)  # refuses a chip that cannot be built, in every mode
    log = None
    if trace is not None and mode != "cycle":
        raise ConfigError("traces need the cycle model: use mode='cycle' (--mode cycle)")
    if mode == "cycle" and trace is not None:
        frame, log = run_traced(plan, gl, gr, trace)
        fixed, cycle_report = frame.words, frame.report
    elif mode == "cycle":
        frame = simulate(plan, gl, gr)
        fixed, cycle_report = frame.words, frame.report
    else:
        desc_l = compute_descriptor(gl, cfg.nna)
        desc_r = compute_descriptor(gr, cfg.nna)
        fixed = sva_stream(desc_l, desc_r, gl, cfg.sva, plan.descriptor_bits)
    disp = to_float(fixed, cfg.sva.subpixel_bits)
    report = build_report(plan, mode, fixed)
    if mode == "cycle":
        report.update(cycle_report)
    if gt is not None:
        report["metrics"] = evaluate(disp, gt, masks)
        notes = undefined_metrics(report["metrics"])
        if notes:
            report["metrics_undefined"] = notes
    return Result(disparity=disp, disparity_fixed=fixed, report=report, config=cfg, trace=log)


def build_report(plan: ChipPlan, mode: str, fixed: np.ndarray) -> dict:
    cfg = plan.cfg
    bits = plan.descriptor_bits
    h, w = fixed.shape
    valid = int(np.count_nonzero(fixed >= 0))
    return {
        "architecture": architecture_report(plan),
        "stereosim": VERSION,
        "mode": mode,
        "image": {"width": w, "height": h},
        "descriptor": {"kind": cfg.nna.descriptor, "bits": bits},
        "output": {
            "valid_pixels": valid,
            "invalid_percent": round(100.0 * (h * w - valid) / (h * w), 4),
            "fractional_bits": cfg.sva.subpixel_bits,
        },
        "config": config_to_dict(cfg),
    }
