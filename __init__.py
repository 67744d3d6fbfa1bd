"""stereosim: a cycle-accurate simulator of an edge stereo-vision SoC (NNA descriptor + SGM
stereo accelerator).

``stereosim.run(left, right, mode=..., config=..., overrides=...)`` simulates one frame and
``stereosim.run_stream(pairs, ...)`` a stream of them (:mod:`stereosim.sim.api`);
``stereosim.load_scene(folder)`` reads a scene (images, ground truth, masks, calibration) and
``stereosim.read_pfm`` / ``write_pfm`` read and write disparity maps as the Middlebury PFM
specification has them (:mod:`stereosim.core.io`). The command line is ``stereosim``
(:mod:`stereosim.sim.cli`).

This one top-level package holds the project's folders as sub-packages (``pyproject.toml`` maps
them), bottom up: :mod:`stereosim.core` (errors, configuration, files, the kernel cache),
:mod:`stereosim.quant` (the integer arithmetic and the quantizer), :mod:`stereosim.nna`
and :mod:`stereosim.sva` (the two accelerators' stages), :mod:`stereosim.traces` (waveforms)
and :mod:`stereosim.sim` (the cycle model and the application). Like ``stereosim.sim``,
it imports only the core here: the API's names resolve on first use (PEP 562), so that
``import stereosim.nna.census`` does not load the whole application.
"""

from stereosim.core.config import ChipConfig, load_config
from stereosim.core.errors import ConfigError, InputError, UserError

__all__ = ["ChipConfig", "ConfigError", "FrameOutput", "InputError", "Result", "Stream",
           "UserError", "load_config", "load_scene", "read_pfm", "run", "run_stream",
           "write_pfm"]
_API = ("run", "Result", "run_stream", "Stream", "FrameOutput", "load_scene")
_IO = ("read_pfm", "write_pfm")


def __getattr__(name):
    if name in _API:
        from stereosim.sim import api

        return getattr(api, name)
    if name in _IO:
        from stereosim.core import io

        return getattr(io, name)
    raise AttributeError(f"module 'stereosim' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
