"""``stereosim run`` on a stream of frames: ``--frames N`` (the pair repeated), or a pair of
videos (``--left-video`` / ``--right-video``, at most ``--frames`` of them).

The cycle model times the whole stream first -- frames overlap in the pipeline as the blocks
allow -- and the summary gives the measured figures (sustained frame rate, every frame's
latency, the stream's span) beside the work bound; then the frames' disparities are computed
one after another and written as they come, every ``--save-every`` K-th into ``OUT/frames/``,
so memory does not grow with the number of frames (a stream is capped at
:data:`~sim.cycle.frames.MAX_FRAMES`: the timing pass and the report keep a few figures per
frame). A repeated pair with ground truth (a scene's, or ``--gt``/``--mask``) is scored frame by
frame. On a terminal (and not with ``--json``) a bar on stderr follows the timing pass and
then the frames. The output set (the last frame's ``disparity.pfm`` and
``.png``, the saved frames, ``report.json`` with the SHA-256 of every file) is published as
one set at the end; until then the frames wait in a staging folder inside ``OUT``, removed if
the run fails.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import time
from pathlib import Path

from stereosim.core.errors import InputError
from stereosim.core.io import disparity_to_colour, encode_png, pfm_bytes
from stereosim.core.outputs import check_outputs, json_text, new_stage, publish
from stereosim.core.progress import progress_bar
from stereosim.sim.api import run_stream
from stereosim.sim.cycle.contract import RunStopped
from stereosim.sim.cycle.frames import check_frame_count
from stereosim.sim.run_files import publish_stop
from stereosim.sim.summary import print_summary
from stereosim.sim.tracing import run_traced, trace_files, trace_paths, trace_section
from stereosim.sim.video import VideoPair


class RepeatedPair:
    """One (left, right) pair as a stream of ``count`` frames, without a list of them."""

    def __init__(self, pair: tuple, count: int):
        self.pair = pair
        self.count = count

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, f: int) -> tuple:
        if not 0 <= f < self.count:
            raise IndexError(f"frame {f} of a stream of {self.count}")
        return self.pair


def stream_pairs(args, data: dict | None):
    """(pairs, name, source) of the run: a pair of videos, or ``data``'s pair repeated
    ``--frames`` times."""
    if args.left_video or args.right_video:
        if not (args.left_video and args.right_video):
            raise InputError("give both --left-video and --right-video")
        pairs = VideoPair(args.left_video, args.right_video, limit=args.frames)
        return pairs, Path(args.left_video).stem, f"{args.left_video} + {args.right_video}"
    return RepeatedPair((data["left"], data["right"]), args.frames), data["name"], data["source"]


def _frame_names(f: int, pair: int, pairs: int) -> tuple[str, str]:
    """The saved files of frame f (of camera pair ``pair`` when several share the chip)."""
    stem = f"disparity_{f:05d}" if pairs == 1 else f"pair{pair}_disparity_{f:05d}"
    return f"{stem}.pfm", f"{stem}.png"


def _frame_files(names: tuple[str, str], disparity, dmax: float) -> dict[str, bytes]:
    return {names[0]: pfm_bytes(disparity),
            names[1]: encode_png(disparity_to_colour(disparity, dmax))}


def _publish_stop(stop: RunStopped, request, out_dir: Path, planned: list, scene: dict):
    """A stream that stopped early publishes what a single frame's stop does
    (:func:`sim.run_files.publish_stop`): its report marked ``stopped`` and, when asked for, the
    trace up to the stop (a second, traced pass of the same stream stops at the same cycle);
    returns the one line the command exits with."""
    if request is not None:
        try:
            run_traced(stop.plan, stop.supply, None, request)
        except RunStopped as traced:
            stop.trace, stop.outputs_in_window = traced.trace, traced.outputs_in_window
            if traced.trace is not None:
                stop.report["trace"] = trace_section(traced.trace, traced.outputs_in_window)
    return publish_stop(stop, request, out_dir, planned, scene)


def config_sources(args) -> dict:
    """Where a run's configuration came from, for its report: the ``--config`` files in the
    order they were layered (a later file's keys win) and the ``--set`` options after them."""
    return {"files": [str(Path(p).resolve()) for p in args.config or ()],
            "set": list(args.set or ())}


def cmd_run_stream(args, request, data: dict | None, cfg, inputs: list = ()) -> int:
    """``stereosim run`` on a stream; ``inputs``: ``(path, label)`` of every file the run reads
    (no output, the saved frames included, may replace one)."""
    out_dir = Path(args.out)
    save_every = args.save_every
    planned = [(out_dir / name, f"--out {name}") for name in
               ("disparity.pfm", "disparity.png", "report.json")]
    pairs, name, source = stream_pairs(args, data)
    n = len(pairs)
    check_frame_count(n, cfg.sva.pairs)  # before the frames' files are planned
    if save_every:
        planned += [(out_dir / "frames" / nm, "--save-every")
                    for f in range(0, n, save_every) for p in range(cfg.sva.pairs)
                    for nm in _frame_names(f, p, cfg.sva.pairs)]
    if request is not None:
        planned += trace_paths(request)
    check_outputs(planned, inputs)  # before any work, none an input
    out_dir.mkdir(parents=True, exist_ok=True)
    staging = new_stage(out_dir)
    try:
        t0 = time.perf_counter()
        gt, masks = (None, None) if data is None else (data.get("gt"), data.get("masks"))
        try:
            with progress_bar(n * cfg.sva.pairs, "timing pass", "frame",
                              quiet=args.json or args.mode != "cycle") as bar:
                stream = run_stream(pairs, mode=args.mode, config=cfg,
                                    max_pixels=args.max_pixels or None, energy=args.energy,
                                    gt=gt, masks=masks,
                                    progress=lambda done: bar.update(done - bar.n))
                bar.update(bar.total - bar.n)
        except RunStopped as stop:
            stop.report["config_sources"] = config_sources(args)
            raise _publish_stop(stop, request, out_dir, planned,
                                {"name": name, "source": source}) from None
        dmax = float(cfg.sva.disparities)
        files: dict[Path, object] = {}
        digests: dict[str, str] = {}
        last = None
        with progress_bar(len(stream), "frames", "frame", quiet=args.json) as bar:
            for frame in stream:
                bar.update()
                last = frame
                if save_every and frame.pair_frame % save_every == 0:
                    names = _frame_names(frame.pair_frame, frame.pair, cfg.sva.pairs)
                    for nm, blob in _frame_files(names, frame.disparity, dmax).items():
                        tmp = staging / nm
                        tmp.write_bytes(blob)
                        files[out_dir / "frames" / nm] = tmp
                        digests[os.path.join("frames", nm)] = hashlib.sha256(blob).hexdigest()
        report = stream.report
        report["scene"] = {"name": name, "source": source}
        report["config_sources"] = config_sources(args)
        report["output"] = {"last_frame_invalid_percent": last.invalid_percent,
                            "saved_every": save_every}
        traces, log = {}, None
        if request is not None:
            _, log = run_traced(stream.plan, stream.supply, None, request)
            traces = trace_files(log, request)
        seconds = time.perf_counter() - t0
        last_files = {out_dir / "disparity.pfm": pfm_bytes(last.disparity),
                      out_dir / "disparity.png": encode_png(disparity_to_colour(last.disparity,
                                                                                dmax))}
        last_files.update((Path(p), blob) for p, blob in traces.items())
        for p, blob in last_files.items():
            digests[os.path.relpath(p, out_dir)] = hashlib.sha256(blob).hexdigest()
        report["files"] = dict(sorted(digests.items()))
        blobs = {**last_files, **files, out_dir / "report.json": json_text(report).encode()}
        publish(blobs, manifest=out_dir / "report.json")
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        if hasattr(pairs, "close"):
            pairs.close()
    if args.json:
        sys.stdout.write(json_text(report))
    else:
        print_summary(report, seconds)
        saved = f", {len(files) // 2} frames in {out_dir}/frames" if files else ""
        print(f"wrote {out_dir}/disparity.pfm, disparity.png (the last frame), "
              f"report.json{saved}")
        if traces:
            print(f"wrote {', '.join(traces)} ({log.n_changes} value changes)")
    return 0
