"""Speed of the SVA row kernels and of the fused streaming pipeline against OpenCV's SGBM.

The frame: the motorcycle pair of scikit-image in grey, resized to 1280 x 720 with cv2.resize,
11x3 census descriptors (pinned: the default descriptor is now the CNN). The SVA runs D = 128,
box 5, 4 paths, equiangular sub-pixel (F = 4), LR check, no median (BENCH_CONFIG), the rest
default. OpenCV runs StereoSGBM (D = 128, block 5, P1 = 200, P2 = 800, single-pass SGBM mode)
single-threaded in the same process, alternating with the SVA run so both see the same
machine state (timings on a shared machine vary by tens of percent: compare the ratio).

Per-stage lines time each stage's kernel alone over 720 rows of real data (the same row of the
frame again and again, so the data stays realistic while the loops stay per-row like the
stream); their sum is not the fused time, which shares caches between the stages. The "sgm"
line's pixel step also finds WTA's winner and runs the right view's diagonal search (the fused
stream's d-loop does both), the "wta" and "right disparity" lines time the volume kernels, and
the median line the 5x5 median of a frame of the middle row's output words (the fused line
has no median: BENCH_CONFIG).

    python benchmarks/bench_sva_kernels.py [--repeat 9] [--write-result]
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np
import skimage.data
from machine import describe, result_file

from stereosim.core.config import load_config
from stereosim.core.kernel_cache import njit
from stereosim.nna.descriptor import compute_descriptor, descriptor_bits
from stereosim.sva.box.aggregation import box_filter, box_start, box_step
from stereosim.sva.hamming.cost import cost_parts, cost_row_update, hamming_cost, reverse_row
from stereosim.sva.lr.lr_check import lr_check_row, new_diagonal_buffers, right_disparity_row
from stereosim.sva.median.median import median
from stereosim.sva.pipeline.pipeline import sva_stream
from stereosim.sva.sgm.sgm import new_path_buffers, sgm, sgm_params, sgm_pixel, sgm_row_start
from stereosim.sva.wta.wta import disparity_index, subpixel_mode_code, wta, wta_pixel

WIDTH, HEIGHT = 1280, 720
# pinned so the figures do not move with the defaults; the rest (penalties, register widths,
# uniqueness) comes from the defaults and barely changes the speed. The median post-filter
# runs outside the fused kernel and is off here.
BENCH_CONFIG = {
    "sva.disparities": 128,
    "sva.box_size": 5,
    "sva.paths": 4,
    "sva.lr_check": True,
    "sva.subpixel": "equiangular",
    "sva.subpixel_bits": 4,
    "sva.median": 0,
}
CENSUS = load_config(overrides={"nna.descriptor": "census"}).nna  # as measured before
BITS = descriptor_bits(CENSUS)


def frame():
    left, right, _ = skimage.data.stereo_motorcycle()
    grey = [
        cv2.resize(
            cv2.cvtColor(im, cv2.COLOR_RGB2GRAY), (WIDTH, HEIGHT), interpolation=cv2.INTER_AREA
        )
        for im in (left, right)
    ]
    desc = [compute_descriptor(g, CENSUS) for g in grey]
    return grey[0], grey[1], desc[0], desc[1]


@njit(cache=True)
def _bench_cost_vertical(desc_l, desc_r, dn, k, cost):
    h, w = desc_l.shape
    r = k // 2
    colsum = np.zeros((w, dn), np.uint16)
    rev_in = np.empty(w, desc_r.dtype)
    rev_out = np.empty(w, desc_r.dtype)
    for y in range(1, h):
        y_in = min(y + r, h - 1)
        y_out = max(y - 1 - r, 0)
        reverse_row(desc_r[y_in], rev_in)
        reverse_row(desc_r[y_out], rev_out)
        cost_row_update(desc_l[y_in], rev_in, desc_l[y_out], rev_out, cost, colsum)
    return colsum


@njit(cache=True)
def _bench_box_horizontal(colsum, k, cap, rows):
    w, dn = colsum.shape
    r = k // 2
    hacc = np.empty(dn, np.uint16)
    out = np.empty(dn, np.uint16)
    total = 0
    for _ in range(rows):
        box_start(colsum, k, hacc)
        for x in range(w):
            box_step(hacc, colsum[min(x + r + 1, w - 1)], colsum[max(x - r, 0)], cap, out)
            total += out[0]
    return total


@njit(cache=True)
def _bench_sgm(agg_row, img, state, params, rows):
    w, dn = agg_row.shape
    s = np.empty(dn, np.uint16)
    scratch = np.empty(w + dn - 1, np.uint16)  # the diagonal search the pixel step feeds
    total = 0
    for y in range(rows):
        img_row = img[y]
        img_prev = img[y - 1] if y > 0 else img[0]
        sgm_row_start(y, img_row, img_prev, state, params)
        for x in range(w):
            s1, _ = sgm_pixel(agg_row[x], x, y, state, params, s, (scratch, scratch, w - 1 - x))
            total += s1
    return total


@njit(cache=True)
def _bench_wta(s_row, uniqueness, mode, frac_bits, rows):
    w, dn = s_row.shape
    idx = disparity_index(dn)
    s1 = np.empty(w, np.uint16)
    for x in range(w):
        s1[x] = s_row[x].min()  # the SGM step hands WTA the minimum
    total = 0
    for _ in range(rows):
        for x in range(w):
            q, d = wta_pixel(s_row[x], s1[x], idx, uniqueness, mode, frac_bits)
            total += q + d
    return total


@njit(cache=True)
def _bench_lr(s_row, q_row, dint_row, max_diff, diag, rows):
    w = s_row.shape[0]
    dr = np.empty(w, np.int32)
    q = q_row.copy()
    for _ in range(rows):
        right_disparity_row(s_row, diag, dr)
        q[:] = q_row
        lr_check_row(q, dint_row, dr, max_diff)
    return q


def best_of(fn, repeat):
    fn()  # compile / warm up
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times), float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument("--write-result", action="store_true",
                        help="also append the output to "
                             "benchmarks/results/<script>-<date>-<cpu>.md")
    args = parser.parse_args()
    with result_file("bench_sva_kernels", args.write_result):
        measure(args)


def measure(args) -> None:
    print(f"machine: {describe()}")
    cv2.setNumThreads(1)
    grey_l, grey_r, desc_l, desc_r = frame()
    cfg = load_config(overrides=BENCH_CONFIG).sva
    dn, k = cfg.disparities, cfg.box_size

    # real rows from a strip of the frame: the middle row of each stage's output
    strip = slice(HEIGHT // 2 - 16, HEIGHT // 2 + 16)
    agg = box_filter(hamming_cost(desc_l[strip], desc_r[strip], dn, BITS), k, cfg.cost_bits)
    s = sgm(
        agg,
        p1=cfg.p1,
        p2=cfg.p2,
        paths=cfg.paths,
        path_bits=cfg.path_bits,
        sum_bits=cfg.sum_bits,
        img=grey_l[strip],
        p2_adaptive=cfg.p2_adaptive,
        p2_slope=cfg.p2_slope,
    )
    q, dint = wta(s, uniqueness=cfg.uniqueness, subpixel=cfg.subpixel, frac_bits=cfg.subpixel_bits)
    mid = 16
    agg_row = np.minimum(agg[mid], (1 << cfg.path_bits) - 1)
    regs = cost_parts(BITS).registers(desc_l.dtype)
    colsum = _bench_cost_vertical(desc_l[strip], desc_r[strip], dn, k, regs)
    mode = subpixel_mode_code(cfg.subpixel)
    params = sgm_params(
        cfg.paths, cfg.p1, cfg.p2, cfg.p2_adaptive, cfg.p2_slope, cfg.path_bits, cfg.sum_bits
    )

    words = np.repeat(q[mid:mid + 1], HEIGHT, 0)  # a frame of output words for the median
    stages = {
        "cost + vertical box (per row)": lambda: _bench_cost_vertical(desc_l, desc_r, dn, k, regs),
        "horizontal box (per pixel)": lambda: _bench_box_horizontal(
            colsum, k, np.uint16((1 << cfg.cost_bits) - 1), HEIGHT
        ),
        f"sgm, {cfg.paths} paths (per pixel)": lambda: _bench_sgm(
            agg_row, grey_l, new_path_buffers(WIDTH, dn), params, HEIGHT
        ),
        "wta + uniqueness + sub-pixel (per pixel)": lambda: _bench_wta(
            s[mid], cfg.uniqueness, mode, cfg.subpixel_bits, HEIGHT
        ),
        "right disparity + LR check (per row)": lambda: _bench_lr(
            s[mid], q[mid], dint[mid], cfg.lr_max_diff, new_diagonal_buffers(WIDTH, dn), HEIGHT
        ),
        # the output words of the middle row repeated over the frame (5 x 5, in uint16)
        "median 5x5 (whole frame)": lambda: median(words, 5),
    }
    print(cfg)
    print(
        f"SVA row kernels, {WIDTH}x{HEIGHT}, D={dn}, box {k}, {cfg.paths} paths "
        f"(best / median of {args.repeat}):"
    )
    for name, fn in stages.items():
        best, med = best_of(fn, args.repeat)
        print(f"  {name:<42} {best:6.3f} s  {med:6.3f} s")

    sgbm = cv2.StereoSGBM_create(
        0,
        dn,
        5,
        P1=200,
        P2=800,
        disp12MaxDiff=1,
        uniquenessRatio=10,
        mode=cv2.STEREO_SGBM_MODE_SGBM,
    )
    # the fused pipeline and OpenCV alternate, so both see the same (noisy) machine state
    def run_sva():
        return sva_stream(desc_l, desc_r, grey_l, cfg, BITS)

    def run_cv():
        return sgbm.compute(grey_l, grey_r)

    run_sva()
    run_cv()
    times = {"sva": [], "cv": []}
    for _ in range(args.repeat):
        for key, fn in (("sva", run_sva), ("cv", run_cv)):
            t = time.perf_counter()
            fn()
            times[key].append(time.perf_counter() - t)
    fused = min(times["sva"]), float(np.median(times["sva"]))
    opencv = min(times["cv"]), float(np.median(times["cv"]))
    print(f"fused sva_stream (1 thread)                  {fused[0]:6.3f} s  {fused[1]:6.3f} s")
    print(f"OpenCV StereoSGBM (cv2.setNumThreads(1))     {opencv[0]:6.3f} s  {opencv[1]:6.3f} s")
    print(
        f"ratio sva_stream / OpenCV: best {fused[0] / opencv[0]:.2f}, "
        f"median {fused[1] / opencv[1]:.2f}"
    )


if __name__ == "__main__":
    main()
