"""The SVA's single-pass left-right check: the right view's disparities from the diagonal of the
same aggregated volume. Its reference and kernels (lr_check), its timing rule (timing: the
plan's ``lr_check`` stage and its window) and its RTL (sva_lr.sv)."""
