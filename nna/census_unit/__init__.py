"""The NNA's census unit: the hand-crafted binary descriptor (and the hybrid's census part).
Its reference and kernels (census); its timing is the plan's ``census_unit`` stage, one cycle
a descriptor (:mod:`nna.submodule.timing`)."""
