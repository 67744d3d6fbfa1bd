"""The mechanics of a long training run: CPU threads, checkpoints and resuming.

Threads. torch's CPU kernels run on an OpenMP pool whose threads spin while they wait for each
other. When the machine has no idle core for every thread (two cores shared with other jobs),
a step waits for the slowest, descheduled thread, and the run gets many times slower than on
one thread: ``--threads 2`` measured ~9x slower than 1 on a loaded 2-core machine. The
default, ``auto`` (0), takes 1 thread up to 2 CPUs, else half the CPUs and at most 4
(:func:`pick_threads`); the small convolutions of the shipped recipe gain little beyond that.
stereosim's numba kernels are serial (no ``parallel=True``), so numba adds no threads.

Checkpoints. Every ``checkpoint_every`` steps the run writes, atomically, everything the next
step depends on: the network, the learnt temperature, the Adam state, the learning-rate
schedule, the step, the finished epochs' losses and the running loss of the current one, the
numpy and torch random states, the settings and the scene list. Resuming from it gives the same
final weights, bit for bit, as the run that was never stopped (same machine and thread count).
The file is ``OUT.ckpt.pt`` beside the output (:func:`checkpoint_path`); a run that finishes
removes it. torch is imported only inside the functions that need it.
"""

from __future__ import annotations

import argparse
import io
import os
import pickle
import zipfile
from pathlib import Path

from stereosim.sim.errors import ConfigError, InputError
from stereosim.sim.outputs import atomic_write_bytes, path_text

CHECKPOINT_FORMAT = "stereosim-train-checkpoint-v1"
# Settings that do not change the computed weights (they may differ on resume).
NOT_COMPARED = ("threads",)


def cpu_count() -> int:
    """CPUs this process may run on (its affinity mask, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def pick_threads(requested: int, cpus: int | None = None) -> int:
    """The torch thread count for ``requested`` (0 = auto: 1 up to 2 CPUs, else
    ``min(4, cpus // 2)``); an explicit count is kept."""
    if requested > 0:
        return requested
    cpus = cpu_count() if cpus is None else cpus
    return 1 if cpus <= 2 else min(4, cpus // 2)


def parse_threads(text: str) -> int:
    """argparse type of ``--threads``: ``auto`` (0) or a whole number >= 1."""
    if text.strip().lower() == "auto":
        return 0
    if not text.strip().isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be 'auto' or a whole number >= 1")
    return int(text)


def threads_line(threads: int, requested: int, cpus: int | None = None) -> str:
    """What the run says about its threads, e.g. ``training on 1 CPU thread (of 2; --threads N
    to change)``."""
    cpus = cpu_count() if cpus is None else cpus
    how = "auto" if requested == 0 else "--threads"
    plural = "" if threads == 1 else "s"
    return (f"training on {threads} CPU thread{plural} (of {cpus}, {how}; --threads N to "
            "change)")


def use_threads(threads: int) -> None:
    """Set torch's intra-op threads to ``threads`` and its inter-op pool to one thread (the
    inter-op pool can be sized only before its first use; later calls keep it)."""
    import torch

    torch.set_num_threads(threads)
    if torch.get_num_interop_threads() != 1:
        try:
            torch.set_num_interop_threads(1)
        except RuntimeError:  # already started in this process
            pass


def checkpoint_path(out) -> Path:
    """The checkpoint of a run writing ``out``: ``OUT.ckpt.pt`` (``m.npz`` -> ``m.ckpt.pt``)."""
    out = Path(out)
    return out.with_name(f"{out.stem}.ckpt.pt")


def check_checkpoint_option(path: Path, resume: bool) -> None:
    """Before a run: ``--resume`` needs the checkpoint, a fresh run must not silently replace
    one left by an interrupted run."""
    exists = path.is_file()
    if resume and not exists:
        raise InputError(f"no checkpoint {path_text(path)} to resume: run without --resume "
                         "to start training")
    if not resume and exists:
        raise InputError(f"checkpoint {path_text(path)} exists from an interrupted run: add "
                         "--resume to continue it, or delete it to start over")


def snapshot(net, log_temp, opt, sched, rng) -> dict:
    """The state of a run's parts: network, learnt temperature, optimizer, learning-rate
    schedule, numpy generator and torch's random state."""
    import torch

    return {"net": net.state_dict(), "log_temp": log_temp.detach().clone(),
            "optimizer": opt.state_dict(), "schedule": sched.state_dict(),
            "numpy_rng": rng.bit_generator.state, "torch_rng": torch.get_rng_state()}


def restore(saved: dict, net, log_temp, opt, sched, rng) -> None:
    """Put a :func:`snapshot` back into freshly built parts of the same run."""
    import torch

    net.load_state_dict(saved["net"])
    with torch.no_grad():
        log_temp.copy_(saved["log_temp"])
    opt.load_state_dict(saved["optimizer"])
    sched.load_state_dict(saved["schedule"])
    rng.bit_generator.state = saved["numpy_rng"]
    torch.set_rng_state(saved["torch_rng"])


def _identity(config: dict, scenes) -> dict:
    return {"config": {k: v for k, v in sorted(config.items()) if k not in NOT_COMPARED},
            "scenes": list(scenes)}


def save_checkpoint(path, state: dict, config: dict, scenes) -> None:
    """Write ``state`` (step, modules, optimizer, RNG states, ...) with the run's settings,
    atomically: a run killed while writing keeps the previous checkpoint."""
    import torch

    buf = io.BytesIO()
    torch.save({"format": CHECKPOINT_FORMAT, **_identity(config, scenes), **state}, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path, config: dict, scenes) -> dict:
    """Read a checkpoint written by :func:`save_checkpoint` for a run with these settings and
    scenes; a file of another run, or not a checkpoint, raises a one-line error."""
    import torch

    name = path_text(Path(path))
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except OSError as err:
        raise InputError(f"cannot read checkpoint {name}: {err.strerror or err}") from None
    except (RuntimeError, pickle.UnpicklingError, zipfile.BadZipFile, EOFError, ValueError):
        raise InputError(f"{name} is not a readable training checkpoint: delete it and run "
                         "without --resume") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        raise InputError(f"{name} is not a stereosim training checkpoint ({CHECKPOINT_FORMAT})")
    want = _identity(config, scenes)
    if data["scenes"] != want["scenes"]:
        raise ConfigError(f"checkpoint {name} was trained on other scenes: resume with the "
                          "same --data, or delete it to start over")
    diff = sorted(k for k in set(want["config"]) | set(data["config"])
                  if want["config"].get(k) != data["config"].get(k))
    if diff:
        shown = ", ".join(f"{k}={data['config'].get(k)!r} (now {want['config'].get(k)!r})"
                          for k in diff[:3])
        raise ConfigError(f"checkpoint {name} has other settings: {shown}; resume with the "
                          "same options, or delete it to start over")
    return data
