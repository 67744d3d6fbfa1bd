"""The SVA's median post-filter (3x3 or 5x5) over the output words. Its reference and kernels
(median), its timing rule (timing: the plan's ``median`` stage, its sorting network and row
banks) and its RTL (sva_median.sv)."""
