"""The files of a single-frame ``stereosim run``: the report that names the set it belongs to,
and the set a run that stopped early publishes.

A run that completes publishes its disparity maps, report.json and traces (:mod:`sim.cli`). A
cycle run that stops (``--max-cycles``, the automatic budget, a deadlock, a camera's overflow)
publishes what there is to inspect -- report.json marked ``stopped`` with every block's and
FIFO's state, and the trace up to the stop when ``--vcd`` or ``--timeline`` asked for one --
and removes, in the same set, every other file the run would have written, so that no file in
``--out`` looks like this run's output without being it (docs/reliability.md). The command
exits with the stop's line and status 2 (the frame's outputs are not there); a stop the user
asked for (``--max-cycles N``) is a :class:`StopAsked`, whose line says so and is no error of
the chip's.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from stereosim.core.errors import ConfigError, UserError
from stereosim.core.outputs import json_text, publish
from stereosim.sim.cycle.contract import RunStopped
from stereosim.sim.tracing import TraceRequest, trace_files


class StopAsked(UserError):
    """The line of a run that stopped where the user asked it to (``--max-cycles N``,
    ``sim.max_cycles``): the run did what it was told, so the line is not an error the chip
    made; the command still exits 2, as every run whose frame is not complete does, and its
    report is published as any stop's."""


def with_report(out_dir: Path, report: dict, blobs: dict) -> dict:
    """``blobs`` (path -> bytes) and the report, which lists the SHA-256 of every other file
    of the set, so a reader can tell the files belong together."""
    report["files"] = {
        os.path.relpath(p, out_dir): hashlib.sha256(data).hexdigest() for p, data in blobs.items()
    }
    blobs[out_dir / "report.json"] = json_text(report).encode()
    return blobs


def publish_stop(stop: RunStopped, request: TraceRequest | None, out_dir: Path, planned: list,
                 scene: dict) -> UserError:
    """Publish a stopped run's set: ``stop.report`` (:func:`sim.api.stopped_report`, with
    ``scene``) as report.json and the trace up to the stop (``stop.trace``, written as the
    ``request`` says), and remove every other existing file of ``planned`` (``(path, label)``:
    everything the run would have written). Returns the one line the command exits with: the
    stop's, and where to look -- a :class:`StopAsked` for a stop at the user's
    ``--max-cycles``."""
    stop.report["scene"] = scene
    blobs, waves, refused = {}, [], ""
    if request is not None and stop.trace is not None:
        try:
            blobs = {Path(p): data for p, data in trace_files(stop.trace, request).items()}
            waves = [p for p in (request.vcd, request.timeline) if p]
        except ConfigError as exc:  # above --trace-limit: the report alone, and why
            stop.report["trace"]["refused"] = str(exc)
            refused = f" (no trace: {exc})"
    blobs = with_report(out_dir, stop.report, blobs)
    stale = {Path(p): None for p, _ in planned if Path(p) not in blobs and Path(p).exists()}
    publish(blobs | stale, manifest=out_dir / "report.json")
    also = f" and the trace up to the stop in {', '.join(waves)}" if waves else refused
    kind = StopAsked if stop.report["stopped"]["reason"] == "max_cycles" else UserError
    return kind(f"{stop}; see {out_dir / 'report.json'} for every block's and FIFO's "
                f"state{also}")
