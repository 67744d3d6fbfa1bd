"""stereosim: a simulator of an edge stereo-vision SoC (NNA descriptor + SGM stereo accelerator).

``sim.run(left, right, mode=..., config=..., overrides=...)`` simulates one frame; see
:mod:`sim.api`. The command line is ``stereosim`` (:mod:`sim.cli`).

``run`` and ``Result`` are loaded on first use, so that the stage packages (``nna``, ``sva``)
can import ``sim.errors`` and ``sim.config`` without pulling in the whole API (no import cycle).
"""

from sim.config import ChipConfig, load_config
from sim.errors import ConfigError, InputError, UserError

__all__ = ["ChipConfig", "ConfigError", "InputError", "Result", "UserError", "load_config", "run"]


def __getattr__(name):
    if name in ("run", "Result"):
        from sim import api

        return getattr(api, name)
    raise AttributeError(f"module 'sim' has no attribute {name!r}")
