"""The whole SVA as the functional model: descriptors in, output words out.

Two implementations that must agree bit for bit:

- :func:`sva_ref` composes the naive stage references on whole (H, W, D) volumes -- slow, only
  for small images, and the definition the tests hold everything against;
- :func:`sva_stream` runs the numba kernels of every stage fused in one compiled loop, row by
  row as the chip streams and, inside a row, pixel by pixel with each stage's D-vector in the
  L1 cache: one row of vertical box sums (slid down a row by adding the entering cost row and
  subtracting the leaving one), one row per SGM top path (updated in place), a few D-vectors.
  Memory grows with W x D, not H x W x D.

Each entry point takes the SVA's section as an :class:`~sva.spec.SvaSpec` (resolved where the
run started: trusted) or as a raw :class:`~core.config.schema.SvaConfig` (checked on entry).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereosim.core.config import SvaConfig
from stereosim.core.errors import InputError
from stereosim.core.kernel_cache import njit
from stereosim.quant.vectors import aligned_full
from stereosim.sva.box.aggregation import box_filter, box_filter_ref, box_start
from stereosim.sva.geometry import box_radius, check_disparity_range, median_radius
from stereosim.sva.hamming.cost import (
    CostParts,
    CostRegisters,
    check_descriptor_pair,
    cost_parts,
    cost_row_add,
    cost_row_update,
    hamming_cost_ref,
    reverse_row,
)
from stereosim.sva.hamming.noise import band_rows, frame_weights
from stereosim.sva.lr.lr_check import (
    diagonal_finish,
    diagonal_start,
    lr_check,
    lr_check_ref,
    lr_check_row,
    new_diagonal_buffers,
    right_disparity_ref,
)
from stereosim.sva.median.median import NARROW_MAX, median, median_ref, median_rows
from stereosim.sva.sgm.sgm import (
    new_path_buffers,
    sgm,
    sgm_params,
    sgm_pixel,
    sgm_ref,
    sgm_row_start,
)
from stereosim.sva.spec import SvaSpec, sva_config
from stereosim.sva.wta.wta import disparity_index, subpixel_mode_code, wta, wta_ref, wta_select


def check_inputs(desc_l, desc_r, img_l, cfg: SvaSpec | SvaConfig, bits) -> SvaConfig:
    """The checks of the SVA's entry points before a kernel sees anything: the descriptor pair
    and the left image alike in shape, D below the width, the descriptor's bits (an int, or
    a tuple of its parts' bits: :func:`frame_cost`), and the section's values (returned
    checked: an :class:`~sva.spec.SvaSpec`'s, resolved where the run started, is trusted; a raw
    section is checked here, :func:`~sva.spec.sva_config`)."""
    check_descriptor_pair(desc_l, desc_r)
    h, w = desc_l.shape
    if img_l.shape != (h, w) or img_l.dtype != np.uint8:
        raise InputError(f"the left grey image must be uint8 {h}x{w} like the descriptors")
    cfg = sva_config(cfg)
    check_disparity_range(cfg, w, InputError)
    parts = cost_parts(bits).bits  # one or two parts of 1..64 bits in all
    if 8 * desc_l.dtype.itemsize < sum(parts):
        raise InputError(f"{desc_l.dtype} descriptors cannot hold {sum(parts)} bits")
    return cfg


def frame_cost(bits, cfg: SvaConfig, img_l) -> tuple[CostParts, dict | None]:
    """The cost of a frame: a descriptor of one part (``bits`` an int or a 1-tuple) is matched
    with its Hamming distance; the hybrid's two parts (``bits`` = (CNN bits, census bits))
    with the frame's weights -- ``sva.cost_weights``, or with ``sva.weight_mode = "auto"`` the
    weights the noise statistic of ``img_l``'s first rows picks (:mod:`sva.hamming.noise`; the
    second value says what it found, None when fixed)."""
    parts = cost_parts(bits).bits
    if len(parts) == 1:
        return cost_parts(parts), None
    weights, noise = frame_weights(cfg, img_l)
    return cost_parts(parts, weights), noise


def sva_ref(desc_l, desc_r, img_l, cfg: SvaSpec | SvaConfig, bits) -> np.ndarray:
    """Output words (H, W) int32 (-1 invalid) from the naive references, stage by stage."""
    cfg = check_inputs(desc_l, desc_r, img_l, cfg, bits)
    cost = hamming_cost_ref(desc_l, desc_r, cfg.disparities, frame_cost(bits, cfg, img_l)[0])
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


class BoxParams(NamedTuple):
    """The box filter and the cost it sums, as :func:`stream_rows` reads them: the box
    ``size`` (int64), the ``cost`` of the descriptor's parts (:class:`~sva.hamming.cost.
    CostRegisters`) and ``agg_cap``, the cap of the aggregated cost fed to SGM (uint16)."""

    size: np.int64
    cost: CostRegisters
    agg_cap: np.uint16


class Selection(NamedTuple):
    """WTA, sub-pixel and LR check as :func:`stream_rows` reads them: the ``uniqueness``
    ratio, the sub-pixel ``mode`` code (:func:`sva.wta.wta.subpixel_mode_code`) and its
    ``frac_bits`` (int64); ``lr`` (the LR check on) and ``max_diff`` (int64); ``diag`` the
    right view's diagonal search (:func:`sva.lr.lr_check.new_diagonal_buffers`)."""

    uniqueness: np.int64
    mode: np.int64
    frac_bits: np.int64
    lr: bool
    max_diff: np.int64
    diag: tuple


@njit(cache=True)
def stream_rows(views, img, box, sgm_args, select, out, rows):
    """The fused SVA, row by row and, inside a row, pixel by pixel with every stage's D-vector
    in the L1 cache.

    ``box``: the :class:`BoxParams`, its ``agg_cap`` min(2^cost_bits, 2^path_bits) - 1
    (clamping A to the path cap first is exact: min(A + x, cap) = min(min(A, cap) + x, cap)
    for x >= 0).
    ``sgm_args`` = (state, params) of :func:`sva.sgm.sgm.sgm_pixel`.
    ``select``: the :class:`Selection`.
    ``views`` = (desc_l, desc_r): both views' descriptors; ``img`` the left grey image.
    ``out`` = (q_out, colsum); ``rows`` = (y_start, y_stop).

    Rows ``y_start`` .. ``y_stop - 1`` are processed; ``colsum`` (W, D) uint16 and the buffers in
    ``sgm_args``/``select`` carry the stream's state from one call to the next, so a caller may
    feed the rows as they arrive (the cycle model does). Row y reads descriptor rows up to
    clamp(y + r) only and writes its words to ``q_out[y % len(q_out)]``: ``q_out`` is the
    whole (H, W) frame or a ring of its most recent rows.

    Per row: the vertical box sums slide down one row (the cost row entering the window added,
    the one leaving it subtracted, both recomputed from the descriptors: no ring of cost rows).
    Per pixel: one d-loop for the horizontal box sum's step, every SGM path (the top paths in
    row rings), S, WTA's winner and the diagonal search of the right disparity
    (:func:`sva.sgm.sgm.sgm_pixel`); then the winner's sub-pixel offset. Per row again: the LR
    check.
    """
    desc_l, desc_r = views
    q_out, colsum = out
    y_start, y_stop = rows
    k, cost, agg_cap = box.size, box.cost, box.agg_cap
    state, params = sgm_args
    diag = select.diag
    h, w = desc_l.shape
    dn = colsum.shape[1]
    r = k // 2
    rev_in = np.empty(w, desc_r.dtype)
    rev_out = np.empty(w, desc_r.dtype)
    hacc = np.empty(dn, np.uint16)
    s_two = np.empty((2, dn), np.uint16)
    idx = disparity_index(dn)
    dint = np.empty(w, np.int32)
    dr = np.empty(w, np.int32)
    diag_best, diag_d = diag[0], diag[1]
    diag_base = diag_best.shape[0] - dn  # right pixel x at W - 1 - x
    if y_start == 0:
        for j in range(-r, r + 1):
            yy = min(max(j, 0), h - 1)
            reverse_row(desc_r[yy], rev_in)
            cost_row_add(desc_l[yy], rev_in, cost, colsum)
    for y in range(y_start, y_stop):
        # vertical sums of rows clamp(y - r) .. clamp(y + r): slide down from y - 1
        y_in = min(y + r, h - 1)
        y_out = max(y - 1 - r, 0)
        if y > 0 and y_in != y_out:
            reverse_row(desc_r[y_in], rev_in)
            reverse_row(desc_r[y_out], rev_out)
            cost_row_update(desc_l[y_in], rev_in, desc_l[y_out], rev_out, cost, colsum)
        box_start(colsum, k, hacc)
        img_row = img[y]
        img_prev = img[y - 1] if y > 0 else img[0]
        q_row = q_out[y % q_out.shape[0]]
        diagonal_start(diag)
        sgm_row_start(y, img_row, img_prev, state, params)
        s1, best = np.uint16(0), np.uint16(0)
        for x in range(w + 1):
            # pixel x's d-loop, then pixel x - 1's sub-pixel offset: the two are independent,
            # so the CPU overlaps the one's scalar tail with the other's vectors
            s1_prev, best_prev = s1, best
            if x < w:
                # the SGM's d-loop also slides the horizontal box window (hacc: its cost is
                # min(hacc, agg_cap)), finds WTA's winner and runs the diagonal search of the
                # right disparity, unconditionally (even without the LR check)
                s1, best = sgm_pixel(hacc, x, y, state, params, s_two[x & 1],
                                     (diag_best, diag_d, diag_base - x),
                                     (colsum[min(x + r + 1, w - 1)], colsum[max(x - r, 0)],
                                      agg_cap))
            if x > 0:
                q_row[x - 1], dint[x - 1] = wta_select(s_two[(x - 1) & 1], s1_prev,
                                                       np.int64(best_prev), idx,
                                                       select.uniqueness, select.mode,
                                                       select.frac_bits)
        diagonal_finish(diag, dr)
        if select.lr:
            lr_check_row(q_row, dint, dr, select.max_diff)


# checked rows the median ring takes beyond the 2 m rows the median itself needs: the compiled
# loop runs this many rows per call at most when the median is on
_RING_EXTRA_ROWS = 32


class SvaStream:
    """The fused SVA kept open between calls: feed descriptor rows as they arrive.

    ``advance(rows_in)`` processes every output row whose inputs are among the first ``rows_in``
    descriptor rows (row y needs rows up to clamp(y + r), r = box radius) and returns how many
    output rows are final -- after the median, which needs m = median // 2 checked rows below.
    ``q`` holds the output words; rows below the returned count are final. The arrays
    ``desc_l``/``desc_r``/``img_l`` are read in place, so a caller may fill them row by row.

    Memory: the compiled loop's W x D buffers, the output words ``q`` and, with the median on,
    a ring of 2 m + 32 rows of words before the median (not a second frame).

    The frame's cost (:func:`frame_cost`: a hybrid's weights) is fixed when the first rows are
    computed, from the first :func:`sva.hamming.noise.band_rows` rows of ``img_l`` -- all of them in
    by then (a call that computes with fewer is a model bug, :class:`RuntimeError`).
    ``cost`` and ``noise`` hold it from then on.
    """

    def __init__(self, desc_l, desc_r, img_l, cfg: SvaSpec | SvaConfig, bits):
        cfg = check_inputs(desc_l, desc_r, img_l, cfg, bits)
        self._bits = bits
        self.cost: CostParts | None = None
        self.noise: dict | None = None
        h, w = desc_l.shape
        dn = cfg.disparities
        self.cfg = cfg
        self.height = h
        self.desc_l, self.desc_r, self.img_l = desc_l, desc_r, img_l
        agg_cap = min((1 << cfg.cost_bits) - 1, (1 << cfg.path_bits) - 1)
        params = sgm_params(
            cfg.paths, cfg.p1, cfg.p2, cfg.p2_adaptive, cfg.p2_slope, cfg.path_bits, cfg.sum_bits
        )
        self._agg_cap = agg_cap
        self._sgm = (new_path_buffers(w, dn), params)
        self._select = Selection(
            uniqueness=np.int64(cfg.uniqueness),
            mode=np.int64(subpixel_mode_code(cfg.subpixel)),
            frac_bits=np.int64(cfg.subpixel_bits),
            lr=bool(cfg.lr_check),
            max_diff=np.int64(cfg.lr_max_diff),
            diag=new_diagonal_buffers(w, dn),
        )
        # the box's column sums, one vector-aligned row per column (D is a multiple of 16,
        # so every row starts 32-byte aligned; 64-byte for D a multiple of 32)
        self._colsum = aligned_full((w, dn), np.uint16, 0)
        self._r = box_radius(cfg)
        self._m = median_radius(cfg)
        # the largest output word, (D - 1) << F plus the largest sub-pixel offset 2^(F-1)
        # (sva.wta): with D <= 256 and F <= 8 the median may run in uint16
        top = ((dn - 1) << cfg.subpixel_bits) + ((1 << cfg.subpixel_bits) >> 1)
        self._narrow = top <= NARROW_MAX
        self.q = np.empty((h, w), np.int32)
        # the words after WTA, sub-pixel and the LR check: with the median off they are final
        # and go to q; with it on, to a ring that keeps the rows the median still needs
        ring_rows = min(h, 2 * self._m + _RING_EXTRA_ROWS)
        self._checked = self.q if self._m == 0 else np.empty((ring_rows, w), np.int32)
        self.rows_checked = 0
        self.rows_final = 0

    def _fix_cost(self, rows_in: int) -> None:
        """The frame's cost, from the first rows of the left view (class docstring)."""
        auto = self.cfg.weight_mode == "auto" and len(cost_parts(self._bits).bits) == 2
        if auto and rows_in < band_rows(self.cfg, self.height):
            raise RuntimeError(f"the SVA computed costs with {rows_in} rows of the left view "
                               "in, before its noise statistic's rows (a bug in the model)")
        self.cost, self.noise = frame_cost(self._bits, self.cfg, self.img_l)
        self._box = BoxParams(size=np.int64(self.cfg.box_size),
                              cost=self.cost.registers(self.desc_l.dtype),
                              agg_cap=np.uint16(self._agg_cap))

    def advance(self, rows_in: int) -> int:
        h = self.height
        r = self._r
        m = self._m
        # output row y is computable once rows up to min(y + r, h - 1) are in
        stop = h if rows_in >= h else max(0, rows_in - r)
        if self.cost is None and stop > self.rows_checked:
            self._fix_cost(rows_in)
        ring = self._checked
        while stop > self.rows_checked:
            # the ring must keep checked rows rows_final - m .. for the median of the rows
            # that are not final yet: fill it at most that far, then run the median
            chunk_stop = stop if m == 0 else min(stop, max(0, self.rows_final - m) + len(ring))
            stream_rows((self.desc_l, self.desc_r), self.img_l, self._box, self._sgm,
                        self._select, (ring, self._colsum), (self.rows_checked, chunk_stop))
            self.rows_checked = chunk_stop
            final = h if chunk_stop >= h else max(0, chunk_stop - m)
            if m and final > self.rows_final:
                median_rows(ring, h, self.cfg.median, self.rows_final, final,
                            self.q[self.rows_final:final], self._narrow)
            self.rows_final = max(self.rows_final, final)
        return self.rows_final


def sva_frame(desc_l, desc_r, img_l, cfg: SvaSpec | SvaConfig, bits) -> SvaStream:
    """The compiled streaming pipeline run over a whole frame: its ``q`` holds the output words
    (H, W) int32 (-1 invalid), its ``cost`` and ``noise`` the frame's cost."""
    stream = SvaStream(
        np.ascontiguousarray(desc_l), np.ascontiguousarray(desc_r), np.ascontiguousarray(img_l),
        cfg, bits,
    )
    stream.advance(desc_l.shape[0])
    return stream


def sva_stream(desc_l, desc_r, img_l, cfg: SvaSpec | SvaConfig, bits) -> np.ndarray:
    """Output words (H, W) int32 (-1 invalid) from the compiled streaming pipeline."""
    return sva_frame(desc_l, desc_r, img_l, cfg, bits).q


def sva_cost_volume(cost, img_l, cfg: SvaSpec | SvaConfig) -> np.ndarray:
    """Output words (H, W) int32 (-1 invalid) from a given uint8 cost volume (H, W, D).

    The same back end as :func:`sva_stream` -- box filter, SGM, WTA with sub-pixel fit, LR check,
    median -- composed from each stage's whole-volume numba wrapper, for matching costs that do
    not come from two binary descriptors (the float cosine cost of the ablation,
    ``benchmarks/ablation.py``). Given the Hamming volume of two descriptors it equals
    :func:`sva_stream` bit for bit (tested).
    """
    cfg = sva_config(cfg)
    if not isinstance(cost, np.ndarray) or cost.ndim != 3 or cost.dtype != np.uint8:
        raise InputError("the cost volume must be a uint8 array (H, W, D)")
    h, w, dn = cost.shape
    if dn != cfg.disparities:
        raise InputError(f"the cost volume has {dn} disparities, the config {cfg.disparities}")
    if not isinstance(img_l, np.ndarray) or img_l.shape != (h, w) or img_l.dtype != np.uint8:
        raise InputError(f"the left grey image must be uint8 {h}x{w} like the cost volume")
    agg = box_filter(cost, cfg.box_size, cfg.cost_bits)
    s = sgm(
        agg, p1=cfg.p1, p2=cfg.p2, paths=cfg.paths, path_bits=cfg.path_bits,
        sum_bits=cfg.sum_bits, img=img_l, p2_adaptive=cfg.p2_adaptive, p2_slope=cfg.p2_slope,
    )
    q, dint = wta(s, uniqueness=cfg.uniqueness, subpixel=cfg.subpixel, frac_bits=cfg.subpixel_bits)
    if cfg.lr_check:
        q, _ = lr_check(s, q, dint, cfg.lr_max_diff)
    if cfg.median > 1:
        q = median(q, cfg.median)
    return q
