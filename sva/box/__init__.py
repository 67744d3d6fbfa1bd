"""The SVA's box filter: the k x k sum of the matching costs (column sums slid by a row, then a
row sum, capped). Its reference and kernels (aggregation), its timing rule (timing: the plan's
``box_filter`` stage and the column-sum banks) and its RTL (sva_box.sv)."""
