"""The SVA's Semi-Global Matching: 1, 2 or 4 path units (P1, P2, the adaptive P2) and the path
sum. Its reference and kernels (sgm), its timing rule (timing: the plan's ``sgm`` and
``path_sum`` stages, the left path's recurrence, the previous-row banks) and its RTL
(sva_sgm.sv)."""
