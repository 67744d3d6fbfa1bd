"""stereosim: a simulator of an edge stereo-vision SoC (NNA descriptor + SGM stereo accelerator).

``sim.run(left, right, mode=..., config=..., overrides=...)`` simulates one frame; see
:mod:`sim.api`. The command line is ``stereosim`` (:mod:`sim.cli`).
"""

from sim.api import Result, run
from sim.config import ChipConfig, load_config
from sim.errors import ConfigError, InputError, UserError

__all__ = ["ChipConfig", "ConfigError", "InputError", "Result", "UserError", "load_config", "run"]
