"""The whole SVA as the functional model: descriptors in, output words out.

Two implementations that must agree bit for bit:

- :func:`sva_ref` composes the naive stage references on whole (H, W, D) volumes -- slow, only
  for small images, and the definition the tests hold everything against;
- :func:`sva_stream` runs the numba row kernels of every stage in one compiled loop, row by row,
  the way the chip streams: a ring of k cost rows for the box filter, one row of aggregated
  cost, the previous row of each SGM path, one row of S. Memory grows with W x D, not H x W x D.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sim.config import SvaConfig
from sim.errors import InputError
from sva.aggregation import box_filter_ref, horizontal_sum_row, vertical_sum_row
from sva.cost import check_descriptor_pair, cost_row, hamming_cost_ref
from sva.lr_check import lr_check_ref, lr_check_row, right_disparity_ref, right_disparity_row
from sva.median import median, median_ref
from sva.sgm import new_path_buffers, sgm_ref, sgm_row
from sva.wta import subpixel_mode_code, wta_ref, wta_row


def check_inputs(desc_l, desc_r, img_l, cfg: SvaConfig, bits: int) -> None:
    check_descriptor_pair(desc_l, desc_r)
    h, w = desc_l.shape
    if img_l.shape != (h, w) or img_l.dtype != np.uint8:
        raise InputError(f"the left grey image must be uint8 {h}x{w} like the descriptors")
    if cfg.disparities >= w:
        raise InputError(
            f"disparity range D={cfg.disparities} is not smaller than the image width {w}: "
            f"use a wider image or a smaller --disparities"
        )
    if not 1 <= bits <= 64:
        raise InputError(f"descriptor width must be 1..64 bits, got {bits}")


def sva_ref(desc_l, desc_r, img_l, cfg: SvaConfig, bits: int) -> np.ndarray:
    """Output words (H, W) int32 (-1 invalid) from the naive references, stage by stage."""
    check_inputs(desc_l, desc_r, img_l, cfg, bits)
    cost = hamming_cost_ref(desc_l, desc_r, cfg.disparities, bits)
    agg = box_filter_ref(cost, cfg.box_size, cfg.cost_bits)
    s = sgm_ref(
        agg, p1=cfg.p1, p2=cfg.p2, paths=cfg.paths, path_bits=cfg.path_bits,
        sum_bits=cfg.sum_bits, img=img_l, p2_adaptive=cfg.p2_adaptive, p2_slope=cfg.p2_slope,
    )
    q, dint = wta_ref(
        s, uniqueness=cfg.uniqueness, subpixel=cfg.subpixel, frac_bits=cfg.subpixel_bits
    )
    if cfg.lr_check:
        q = lr_check_ref(q, dint, right_disparity_ref(s), cfg.lr_max_diff)
    if cfg.median > 1:
        q = median_ref(q, cfg.median)
    return q


@njit(cache=True)
def _stream(desc_l, desc_r, img, dn, bits, k, cost_cap, paths, p1, p2, adaptive, slope,
            path_cap, sum_cap, uniqueness, mode, frac_bits, lr, max_diff, path_buffers, q_out):
    h, w = desc_l.shape
    r = k // 2
    ring = np.empty((k, w, dn), np.uint8)
    colsum = np.empty((w, dn), np.uint16)
    agg = np.empty((w, dn), np.uint16)
    s_row = np.empty((w, dn), np.uint16)
    prev, cur, prev_min, cur_min, left = path_buffers
    dint = np.empty(w, np.int32)
    dr = np.empty(w, np.int32)
    best = np.empty(w, np.int64)
    next_row = 0
    for y in range(h):
        # the cost rows up to clamp(y + r) must be in the ring (row i lives in slot i % k)
        need = min(y + r, h - 1)
        while next_row <= need:
            cost_row(desc_l[next_row], desc_r[next_row], dn, bits, ring[next_row % k])
            next_row += 1
        vertical_sum_row(ring, k, h, y, colsum)
        horizontal_sum_row(colsum, k, cost_cap, agg)
        img_prev = img[y - 1] if y > 0 else img[0]
        sgm_row(agg, img[y], img_prev, y, prev, prev_min, cur, cur_min, left, paths, p1, p2,
                adaptive, slope, path_cap, sum_cap, s_row)
        prev, cur = cur, prev
        prev_min, cur_min = cur_min, prev_min
        wta_row(s_row, uniqueness, mode, frac_bits, q_out[y], dint)
        if lr:
            right_disparity_row(s_row, best, dr)
            lr_check_row(q_out[y], dint, dr, max_diff)


def sva_stream(desc_l, desc_r, img_l, cfg: SvaConfig, bits: int) -> np.ndarray:
    """Output words (H, W) int32 (-1 invalid) from the compiled streaming pipeline."""
    check_inputs(desc_l, desc_r, img_l, cfg, bits)
    h, w = desc_l.shape
    q = np.empty((h, w), np.int32)
    _stream(
        np.ascontiguousarray(desc_l), np.ascontiguousarray(desc_r), np.ascontiguousarray(img_l),
        cfg.disparities, np.uint8(bits), cfg.box_size, np.uint32((1 << cfg.cost_bits) - 1),
        cfg.paths, cfg.p1, cfg.p2, cfg.p2_adaptive, cfg.p2_slope, (1 << cfg.path_bits) - 1,
        (1 << cfg.sum_bits) - 1, cfg.uniqueness, subpixel_mode_code(cfg.subpixel),
        cfg.subpixel_bits, cfg.lr_check, cfg.lr_max_diff, new_path_buffers(w, cfg.disparities), q,
    )
    if cfg.median > 1:
        q = median(q, cfg.median)
    return q
