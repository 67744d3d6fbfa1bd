"""The simulator's application package, ``stereosim.sim``: the cycle model and the application
of stereosim.

``stereosim.run(left, right, mode=..., config=..., overrides=...)`` (also ``stereosim.sim.run``)
simulates one frame and ``run_stream(pairs, ...)`` a stream of them; see :mod:`sim.api`. The
command line is ``stereosim`` (:mod:`sim.cli`).

The package holds the top two layers of the project (docs/architecture.md, "Layers"): the
cycle model (:mod:`sim.cycle`: the chip plan, the readable kernel, the compiled engine, the
estimate) and over it the application (:mod:`sim.api`, :mod:`sim.cli`, sweeps, tracing, metrics,
reports); the core below every folder is :mod:`stereosim.core`. Python runs this file before any
module of the package, so it imports only the core; ``run`` and ``Result`` (and the stream's
names, ``load_scene``) are resolved on first use (PEP 562) -- importing the API here would make
every ``import stereosim.sim.tracing`` load the whole application. stereosim's root package
exports the same names: its ``__init__`` takes them, and their resolution, from here.
"""

from stereosim.core.config import ChipConfig, load_config
from stereosim.core.errors import ConfigError, InputError, UserError

#: the application's names (:mod:`sim.api`), resolved on first use
API = ("FrameOutput", "Result", "Stream", "load_scene", "run", "run_stream")
__all__ = ["ChipConfig", "ConfigError", "InputError", "UserError", "load_config", *API]


def __getattr__(name):
    if name in API:
        from stereosim.sim import api

        return getattr(api, name)
    raise AttributeError(f"module 'stereosim.sim' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
