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
and :mod:`stereosim.sim` (the cycle model and the application). The names come from
``stereosim.sim``, which imports only the core: the API's names resolve on first use (PEP 562,
by ``stereosim.sim``'s own resolution), as ``read_pfm`` / ``write_pfm`` do, so that
``import stereosim.nna.census_unit.census`` does not load the whole application.
"""

from stereosim.sim import (
    API,
    ChipConfig,
    ConfigError,
    InputError,
    UserError,
    load_config,
)
from stereosim.sim import __getattr__ as _api_name

#: the Middlebury PFM files' reader and writer (:mod:`stereosim.core.io`), resolved on first use
IO = ("read_pfm", "write_pfm")
__all__ = ["ChipConfig", "ConfigError", "InputError", "UserError", "load_config", *API, *IO]


def __getattr__(name):
    if name in API:
        return _api_name(name)
    if name in IO:
        from stereosim.core import io

        return getattr(io, name)
    raise AttributeError(f"module 'stereosim' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
