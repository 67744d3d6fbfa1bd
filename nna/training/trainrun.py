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
final weights, bit for bit, as the run that was never stopped (same machine, thread count and
device). A GPU run (``--device cuda``) resumes on the CPU and back: a checkpoint is read onto
the CPU and its tensors follow the network to its device. The file is ``OUT.ckpt.pt`` beside the
output (:func:`checkpoint_path`); a run that finishes removes it. A checkpoint is read with
``weights_only=True`` and its contents are checked before any is used (:func:`load_checkpoint`,
:func:`restore`): a damaged or crafted file, or one whose weights went NaN, is one line. torch
is imported only inside the functions that need it.
"""

from __future__ import annotations

import argparse
import io
import math
import os
import pickle
import warnings
import zipfile
from pathlib import Path

from stereosim.core.errors import ConfigError, InputError
from stereosim.core.outputs import atomic_write_bytes, path_text
from stereosim.nna.training.trainconfig import box_range

CHECKPOINT_FORMAT = "stereosim-train-checkpoint-v1"
# Settings that change how the weights are computed, not the recipe: a run may resume with
# others (the same weights bit for bit only with the same ones, on the same machine).
NOT_COMPARED = ("threads", "device")


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
    """argparse type of ``--threads``: ``auto`` (0) or a whole number from 1 to the CPUs this
    process may run on (:func:`cpu_count`; more threads than CPUs only wait for each other)."""
    if text.strip().lower() == "auto":
        return 0
    if not text.strip().isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be 'auto' or a whole number >= 1")
    cpus = cpu_count()
    if int(text) > cpus:
        raise argparse.ArgumentTypeError(f"{text!r} is more threads than the {cpus} CPU"
                                         f"{'' if cpus == 1 else 's'} this process may run on: "
                                         f"give 1..{cpus} or auto")
    return int(text)


def box_width(text: str) -> int:
    """argparse type of ``train --box`` and ``--aggregate``: the window stands in the loss for
    the chip's box filter, so it may be as wide as ``sva.box_size`` allows
    (:func:`nna.training.trainconfig.box_range`; odd is checked with the other settings, by
    TrainConfig)."""
    lo, hi = box_range()
    value = int(text) if text.strip().isdigit() else 0
    if not lo <= value <= hi:
        raise argparse.ArgumentTypeError(f"{text!r} is not a window the chip's box filter has: "
                                         f"give an odd K in {lo}..{hi} (sva.box_size's range)")
    return value


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


def training_device(name: str):
    """The torch device of a run, with torch's deterministic algorithms switched on: ``cpu``
    (a run is reproducible from its seed, bit for bit on the same machine and thread count), or
    ``cuda`` (torch's current GPU) when torch sees one, else a one-line InputError. On a GPU,
    cuBLAS is given the workspace its deterministic mode needs (``CUBLAS_WORKSPACE_CONFIG``,
    before its first use), and an op without a deterministic GPU kernel warns instead of
    stopping the run."""
    import torch

    if name != "cpu":
        if not torch.cuda.is_available():
            raise InputError(f"--device {name}: this torch sees no CUDA GPU; train with "
                             "--device cpu (the default)")
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    torch.use_deterministic_algorithms(True, warn_only=name != "cpu")
    return torch.device(name)


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


def restore(saved: dict, net, log_temp, opt, sched, rng, source) -> None:
    """Put a :func:`snapshot` (checked by :func:`load_checkpoint`) back into freshly built parts
    of the same run; a part that does not fit them (a crafted or damaged file from ``source``)
    raises a one-line InputError naming it."""
    import torch

    def temperature(value):
        with torch.no_grad():
            log_temp.copy_(value)

    name = path_text(Path(source))
    _check_fits(saved, opt, sched, name)
    parts = (("net", net.load_state_dict), ("log_temp", temperature),
             ("optimizer", opt.load_state_dict), ("schedule", sched.load_state_dict),
             ("numpy_rng", lambda state: setattr(rng.bit_generator, "state", state)),
             ("torch_rng", torch.set_rng_state))
    for part, put in parts:
        try:
            put(saved[part])
        except (KeyError, TypeError, ValueError, RuntimeError, IndexError, AttributeError) as exc:
            reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:120]
            raise _damaged(name, f"its {part} does not fit this run ({reason})") from None


def _fits(saved, fresh) -> bool:
    """``saved`` has the structure of ``fresh``: the same keys and lengths, tensors of the same
    shapes, the same flags and names, finite numbers where ``fresh`` has numbers."""
    import torch

    if isinstance(fresh, dict):
        return isinstance(saved, dict) and saved.keys() == fresh.keys() \
            and all(_fits(saved[k], v) for k, v in fresh.items())
    if isinstance(fresh, (list, tuple)):
        return isinstance(saved, (list, tuple)) and len(saved) == len(fresh) \
            and all(_fits(a, b) for a, b in zip(saved, fresh))
    if isinstance(fresh, torch.Tensor):
        return isinstance(saved, torch.Tensor) and saved.shape == fresh.shape
    if isinstance(fresh, (bool, str)) or fresh is None:
        return type(saved) is type(fresh) and saved == fresh
    return _finite_number(saved)


def _check_fits(saved: dict, opt, sched, name: str) -> None:
    """The optimizer's and the schedule's states are those of this run at the saved step (torch
    loads them without looking; a crafted one would break a later step, or train silently
    with another learning rate)."""
    import torch

    fresh_opt, fresh_sched, step = opt.state_dict(), sched.state_dict(), saved["step"]
    params = [p for group in opt.param_groups for p in group["params"]]
    adam = {i: {"step": torch.zeros(()), "exp_avg": p, "exp_avg_sq": p}
            for i, p in enumerate(params)}
    groups = saved["optimizer"].get("param_groups") if isinstance(saved["optimizer"], dict) \
        else None
    if not (_fits(saved["optimizer"], {"state": adam if step else {}, "param_groups":
                                       fresh_opt["param_groups"]})
            and all({k: v for k, v in a.items() if k != "lr"}
                    == {k: v for k, v in b.items() if k != "lr"}
                    for a, b in zip(groups, fresh_opt["param_groups"]))):
        raise _damaged(name, "its optimizer state is not that of this run")
    sched_state = saved["schedule"]
    if not (_fits(sched_state, fresh_sched) and sched_state["last_epoch"] == step
            and sched_state["base_lrs"] == fresh_sched["base_lrs"]):
        raise _damaged(name, "its learning-rate schedule is not that of this run at its step")


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
        # torch warns on stderr about what it reads (a pickle protocol other than its own, a
        # TorchScript archive): the contents are checked below, and a refusal is one line
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = torch.load(path, map_location="cpu", weights_only=True)
    except OSError as err:
        raise InputError(f"cannot read checkpoint {name}: {err.strerror or err}") from None
    except (RuntimeError, pickle.UnpicklingError, zipfile.BadZipFile, EOFError, ValueError,
            KeyError, TypeError, IndexError, AttributeError):  # damaged or crafted
        raise InputError(f"{name} is not a readable training checkpoint: delete it and run "
                         "without --resume") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        raise InputError(f"{name} is not a stereosim training checkpoint ({CHECKPOINT_FORMAT})")
    if not isinstance(data.get("config"), dict) or not isinstance(data.get("scenes"), list):
        raise _damaged(name, "it lacks the settings and scenes of its run")
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
    _check_contents(data, config, name)
    return data


# What a checkpoint holds besides its identity: snapshot()'s parts and the run's progress.
CONTENTS = ("net", "log_temp", "optimizer", "schedule", "numpy_rng", "torch_rng", "step",
            "history", "running")


def _damaged(name: str, what: str) -> InputError:
    return InputError(f"checkpoint {name} is damaged: {what}; delete it and run without "
                      "--resume")


def _finite_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _tensors(obj, prefix: str):
    """``(name, tensor)`` of every tensor in nested dicts and lists."""
    if isinstance(obj, dict):
        for key, value in obj.items():
            yield from _tensors(value, f"{prefix}.{key}")
    elif isinstance(obj, (list, tuple)):
        for i, value in enumerate(obj):
            yield from _tensors(value, f"{prefix}.{i}")
    elif hasattr(obj, "is_floating_point"):
        yield prefix, obj


def _check_contents(data: dict, config: dict, name: str) -> None:
    """A checkpoint's contents before they are trusted: every part there, the step inside the
    run, one finished loss per finished epoch, and every number finite (a run that diverged
    must not resume silently into a NaN model)."""
    import torch

    missing = [k for k in CONTENTS if k not in data]
    if missing:
        raise _damaged(name, f"it lacks {', '.join(missing)}")
    per_epoch = config["steps_per_epoch"]
    step, history = data["step"], data["history"]
    if type(step) is not int or not 0 <= step < config["epochs"] * per_epoch:
        raise _damaged(name, f"its step {step!r} is not a step of this run")
    if not isinstance(history, list) or len(history) != step // per_epoch \
            or not all(_finite_number(h) for h in history) \
            or not _finite_number(data["running"]):
        raise _damaged(name, "its losses do not match its step")
    for part in ("net", "log_temp", "optimizer"):
        for tensor_name, tensor in _tensors(data[part], part):
            if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
                raise _damaged(name, f"{tensor_name} holds NaN or infinite values (the run "
                               "it saved had diverged)")
