"""The SVA's winner-take-all with uniqueness and the sub-pixel step. Its reference and kernels
(wta), its timing rule (timing: the plan's ``wta`` stage) and its RTL (sva_wta.sv)."""
