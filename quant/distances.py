"""Quantisation losses: distances between the scaled float output and the integer output.

Each function takes ``float_out`` (the scaled float output ``S * Gamma(X)``) and ``int_out`` (the
integer output ``Gamma_dot(X_dot)`` of the quantised layer fed with the quantised input) of the
same shape, and reduces over axis 0 (the samples). Any further axes are kept, so a 2-D input
(samples, candidates) gives one distance per candidate scale in one call -- the quantizer's search
evaluates a block of candidate scales at once this way. Inputs are converted to float64.

Sample-wise distances (the paper's section "Quantization loss"; n = number of samples):

* ``hamming``: ``sum_i [f_i > 0] xor [q_i > 0]`` -- the number of sign bits that disagree (the
  descriptor bit is ``value > 0``, so 0 counts as the bit 0).
* ``l1``: ``(1/n) sum_i |f_i - q_i|``.
* ``rms``: ``sqrt((1/n) sum_i (f_i - q_i)**2)``. The paper prints its "RMS" as
  ``(1/n) sum sqrt((f - q)**2)``, which is the same as its l1; we use the conventional root mean
  square so the two choices differ.

Histogram distances (paper eq. kld and rms, after TensorRT's calibration):

* Binning: for each column the two arrays share one range ``[lo, hi]`` with
  ``lo = min(min f, min q)`` and ``hi = max(max f, max q)``, split into ``bins`` equal bins
  (default 2048); value v goes to bin ``floor((v - lo) / (hi - lo) * bins)``, the top edge into the
  last bin. If ``hi == lo`` every value is in bin 0. Counts are divided by n.
* ``kl``: ``D_KL(H || H_dot) = sum_i H_i log2(H_i / H_dot_i)`` with H from ``float_out`` and
  ``H_dot`` from ``int_out``. Empty bins: ``eps`` (default 1e-10) is added to every bin of both
  histograms, which are then renormalised to sum 1, so the log is always finite; identical
  histograms give exactly 0.
* ``hist_rms``: ``sqrt((1/bins) sum_i (H_i - H_dot_i)**2)`` on the normalised histograms (again
  the conventional RMS; the paper's printed formula is the mean absolute bin difference).
"""

from __future__ import annotations

import numpy as np

from stereosim.core.errors import ConfigError

DEFAULT_BINS = 2048
DEFAULT_EPS = 1e-10


def _pair(float_out, int_out) -> tuple[np.ndarray, np.ndarray]:
    f64 = np.asarray(float_out, dtype=np.float64)
    q64 = np.asarray(int_out, dtype=np.float64)
    if f64.shape != q64.shape:
        raise ValueError(f"float_out and int_out must have the same shape, got {f64.shape} and "
                         f"{q64.shape}")
    if f64.ndim == 0 or f64.shape[0] == 0:
        raise ValueError("distances need at least one sample along axis 0")
    return f64, q64


def hamming(float_out, int_out) -> np.ndarray:
    """Number of samples (axis 0) whose sign bits ``value > 0`` differ."""
    f64, q64 = _pair(float_out, int_out)
    return np.count_nonzero((f64 > 0) != (q64 > 0), axis=0).astype(np.float64)


def l1(float_out, int_out) -> np.ndarray:
    """Mean absolute difference over axis 0."""
    f64, q64 = _pair(float_out, int_out)
    return np.mean(np.abs(f64 - q64), axis=0)


def rms(float_out, int_out) -> np.ndarray:
    """Root mean square difference over axis 0."""
    f64, q64 = _pair(float_out, int_out)
    return np.sqrt(np.mean((f64 - q64) ** 2, axis=0))


def histograms(float_out, int_out, bins=DEFAULT_BINS) -> tuple[np.ndarray, np.ndarray]:
    """The two normalised histograms (bins, ...) on a common range per column (module docstring)."""
    f64, q64 = _pair(float_out, int_out)
    n = f64.shape[0]
    tail = f64.shape[1:]
    f2 = f64.reshape(n, -1)
    q2 = q64.reshape(n, -1)
    lo = np.minimum(f2.min(axis=0), q2.min(axis=0))
    hi = np.maximum(f2.max(axis=0), q2.max(axis=0))
    width = hi - lo
    safe = np.where(width > 0, width, 1.0)
    n_cols = f2.shape[1]
    col_base = np.arange(n_cols) * bins
    out = []
    for values in (f2, q2):
        idx = np.floor((values - lo) / safe * bins).astype(np.int64)
        idx = np.clip(idx, 0, bins - 1)
        idx[:, width <= 0] = 0
        counts = np.bincount((idx + col_base).ravel(), minlength=n_cols * bins)
        out.append((counts.reshape(n_cols, bins).T / n).reshape((bins,) + tail))
    return out[0], out[1]


def kl(float_out, int_out, bins=DEFAULT_BINS, eps=DEFAULT_EPS) -> np.ndarray:
    """KL divergence (base 2) of the int-output histogram from the float-output histogram."""
    h_f, h_q = histograms(float_out, int_out, bins)
    p = h_f + eps
    q = h_q + eps
    p /= p.sum(axis=0)
    q /= q.sum(axis=0)
    return np.sum(p * np.log2(p / q), axis=0)


def hist_rms(float_out, int_out, bins=DEFAULT_BINS) -> np.ndarray:
    """RMS difference between the two normalised histograms, per column."""
    h_f, h_q = histograms(float_out, int_out, bins)
    return np.sqrt(np.mean((h_f - h_q) ** 2, axis=0))


DISTANCES = {"hamming": hamming, "rms": rms, "l1": l1, "kl": kl, "hist_rms": hist_rms}


def get_distance(name: str):
    """The distance function called ``name``; :class:`ConfigError` if there is none."""
    try:
        return DISTANCES[name]
    except (KeyError, TypeError):
        raise ConfigError(
            f"unknown distance {name!r}; choose one of {', '.join(DISTANCES)}"
        ) from None
