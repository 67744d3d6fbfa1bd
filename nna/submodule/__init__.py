"""The NNA submodule: line buffers collecting input rows and, per layer, a MAC array with its
share of the MACs, requantisation between layers and the sign at the end. Its timing rule
(timing: the plan's layer stages, the line buffers' banks) and its RTL (nna_submodule.sv); the
network it runs is :mod:`nna.conv`, the census it may compute :mod:`nna.census_unit`."""
