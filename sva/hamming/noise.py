"""The hybrid descriptor's automatic weights: a noise statistic of the frame, and the rule that
picks the frame's weights from it (``sva.weight_mode = "auto"``).

Definition (the chip's). The statistic is taken over the **first b rows of the left view**,
b = min(H, r + m + 1) with r the box radius and m the median radius
(:func:`sva.geometry.row_lookahead`), rows the SVA's descriptor-row buffers (k + 2 rows) hold
at once; the SVA's first slot of a frame (the column sums' first pass, its first matching
costs) waits for row b - 1 (:func:`sim.cycle.rules.sva_first_slot_row`), so every cost of the
frame is computed after the statistic is complete. The intensities arrive with the
descriptors (the 8 bits the adaptive P2 reads), so no other block is involved.

For every pixel (x, y) with 1 <= y <= b - 2 and 1 <= x <= W - 2:

* the Laplacian of Immerkaer's noise estimator, the 3x3 mask [1 -2 1; -2 4 -2; 1 -2 1]:
  ``L = sum_{i,j} M[i][j] I(y + i - 1, x + j - 1)`` (zero on any linear ramp);
* the gradient ``g = |I(y, x + 1) - I(y, x - 1)| + |I(y + 1, x) - I(y - 1, x)|``;
* a pixel with ``g <= sva.noise_gradient`` counts: ``S += |L|``, ``N += 1`` (edges and texture
  are left out: they are not noise).

The frame is **noisy** when ``S > T N``, T = ``sva.noise_threshold`` (no division: a compare of
S with the product). A noisy frame uses ``sva.noisy_weights``, any other ``sva.cost_weights``.
Gaussian noise of sigma s gives E|L| = 6 s sqrt(2 / pi) = 4.79 s on a flat image.

Hardware: per pixel of the band, the 3x3 window of the line the SVA already buffers, 8 adds of
at most 12 bits, two absolute values, a compare; two accumulators (S, N) and one multiply and
compare per frame (:func:`noise_unit_bits`).
"""

from __future__ import annotations

import numpy as np

from stereosim.core.config import SvaConfig
from stereosim.core.kernel_cache import njit
from stereosim.sva.geometry import row_lookahead

#: The Laplacian mask of the statistic (Immerkaer 1996).
MASK = ((1, -2, 1), (-2, 4, -2), (1, -2, 1))


def band_rows(cfg: SvaConfig, height: int) -> int:
    """b: the rows of the left view the statistic reads, min(H, r + m + 1)."""
    return min(height, row_lookahead(cfg) + 1)


def noise_statistic_ref(img: np.ndarray, rows: int, gradient: int) -> tuple[int, int]:
    """(S, N) of the module docstring over the first ``rows`` rows, written as it reads."""
    h, w = img.shape
    pix = img.astype(np.int64).tolist()
    s = n = 0
    for y in range(1, min(rows, h) - 1):
        for x in range(1, w - 1):
            lap = sum(MASK[i][j] * pix[y + i - 1][x + j - 1] for i in range(3) for j in range(3))
            g = abs(pix[y][x + 1] - pix[y][x - 1]) + abs(pix[y + 1][x] - pix[y - 1][x])
            if g <= gradient:
                s += abs(lap)
                n += 1
    return s, n


@njit(cache=True)
def _statistic(img, rows, gradient):
    h, w = img.shape
    s = np.int64(0)
    n = np.int64(0)
    for y in range(1, min(rows, h) - 1):
        a, b, c = img[y - 1], img[y], img[y + 1]
        for x in range(1, w - 1):
            lap = (np.int64(a[x - 1]) - 2 * np.int64(a[x]) + np.int64(a[x + 1])
                   - 2 * np.int64(b[x - 1]) + 4 * np.int64(b[x]) - 2 * np.int64(b[x + 1])
                   + np.int64(c[x - 1]) - 2 * np.int64(c[x]) + np.int64(c[x + 1]))
            g = (abs(np.int64(b[x + 1]) - np.int64(b[x - 1]))
                 + abs(np.int64(c[x]) - np.int64(a[x])))
            if g <= gradient:
                s += abs(lap)
                n += 1
    return s, n


def noise_statistic(img: np.ndarray, rows: int, gradient: int) -> tuple[int, int]:
    """(S, N) of the module docstring, compiled (:func:`noise_statistic_ref` is the
    definition)."""
    s, n = _statistic(np.ascontiguousarray(img), int(rows), int(gradient))
    return int(s), int(n)


def frame_weights(cfg: SvaConfig, img_l: np.ndarray) -> tuple[tuple[int, int], dict | None]:
    """The weights of a hybrid frame whose left view is ``img_l`` (at least its first
    :func:`band_rows` rows filled), and what chose them: None with ``weight_mode`` fixed, else
    ``{"sum": S, "count": N, "mean": S / N, "threshold": T, "noisy": bool}``."""
    if cfg.weight_mode != "auto":
        return tuple(cfg.cost_weights), None
    s, n = noise_statistic(img_l, band_rows(cfg, img_l.shape[0]), cfg.noise_gradient)
    noisy = s > cfg.noise_threshold * n
    return (tuple(cfg.noisy_weights if noisy else cfg.cost_weights),
            {"sum": s, "count": n, "mean": s / n if n else 0.0,
             "threshold": cfg.noise_threshold, "noisy": bool(noisy)})


def noise_unit_bits(cfg: SvaConfig, width: int) -> int:
    """Bits of the noise unit's accumulators: N of at most (b - 2)(W - 2) pixels (b the band's
    rows, :func:`band_rows`, at most r + m + 1), S of at most 1020 N, and the product T N of
    10 more bits than N that S is compared with."""
    pixels = max(1, (row_lookahead(cfg) - 1) * max(1, width - 2))
    count = pixels.bit_length()
    return count + (1020 * pixels).bit_length() + count + 10
