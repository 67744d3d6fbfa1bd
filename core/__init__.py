"""The core, ``stereosim.core``: what every other folder imports and nothing above it -- the
user's errors (:mod:`core.errors`), the configuration (:mod:`core.config`), the numba kernel
cache (:mod:`core.kernel_cache`), files in and out (:mod:`core.io`, :mod:`core.outputs`,
:mod:`core.npz`, :mod:`core.datasets`), signals and progress. It imports no other folder of the
project (docs/architecture.md, "Layers")."""
