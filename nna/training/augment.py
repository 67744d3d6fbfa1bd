"""What training does to each view so that the descriptor learns to ignore what differs between
two real cameras (:mod:`nna.training.traindata`, :mod:`nna.training.train`).

Every sample of a batch (a patch or a strip crop, shape (rows, cols)) gets its own draw of:

* **defocus**: a Gaussian blur of sigma ~ U(0, ``blur_max``) pixels (none when 0);
* **exposure**: ``gain * (v - 128) + 128 + offset``, gain ~ U(1 - ``gain``, 1 + ``gain``),
  offset ~ U(-``offset``, ``offset``);
* **gamma**: ``255 (v / 255) ** g`` with ``log g ~ U(-gamma, gamma)`` (none when 0);
* **sensor noise**: Gaussian of variance ``s**2 + k v``, s ~ U(0, ``noise_max``) (read noise)
  and k ~ U(0, ``shot_noise``) (the signal-dependent shot noise of a photon count, in grey
  levels);

then rounding and clipping to 0..255, as the camera's ADC would. The geometric change, a small
vertical misalignment of the other view (``vshift_max``), is drawn by :func:`vertical_offsets`
and applied where the crops are cut (:func:`rows_at`).

All draws come from the caller's ``numpy.random.Generator`` in a fixed order, so a run is
reproducible from its seed; with every range at 0 but ``gain``, ``offset`` and ``noise_max``
the draws and results are those of the original recipe.
"""

from __future__ import annotations

import cv2
import numpy as np

#: ``stereosim train --augment NAME``: ``basic`` is TrainConfig's defaults (gain +-20 %, offset
#: +-20, read noise up to sigma 2); ``robust`` adds read noise up to sigma 10 with shot noise,
#: gain +-25 %, gamma x/÷ 1.22, defocus up to sigma 1.2 px and 0.5 px vertical misalignment;
#: ``mild`` half of those ranges (noise up to 6).
RECIPES = {
    "basic": {},
    "robust": {"noise_max": 10.0, "gain": 0.25, "offset": 20.0, "gamma": 0.2,
               "shot_noise": 1.0, "blur_max": 1.2, "vshift_max": 0.5},
    "mild": {"noise_max": 6.0, "gain": 0.2, "offset": 20.0, "gamma": 0.1,
             "shot_noise": 0.5, "blur_max": 0.8, "vshift_max": 0.25},
}


def photometric(patches: np.ndarray, cfg, rng: np.random.Generator,
                shared_axis: bool = False) -> np.ndarray:
    """``patches`` (N, rows, cols) -- or (K, N, rows, cols) with ``shared_axis``, the K crops of
    one sample sharing its draw -- changed as the module docstring says; float32 of uint8
    values."""
    n = patches.shape[1] if shared_axis else patches.shape[0]
    gain = rng.uniform(1.0 - cfg.gain, 1.0 + cfg.gain, n).astype(np.float32)[:, None, None]
    offset = rng.uniform(-cfg.offset, cfg.offset, n).astype(np.float32)[:, None, None]
    sigma = rng.uniform(0.0, cfg.noise_max, n).astype(np.float32)[:, None, None]
    v = patches.astype(np.float32)
    if cfg.blur_max > 0:
        blur = rng.uniform(0.0, cfg.blur_max, n)
        v = _blurred(v, blur, shared_axis)
    v = gain * (v - 128.0) + 128.0 + offset
    if cfg.gamma > 0:
        g = np.exp(rng.uniform(-cfg.gamma, cfg.gamma, n)).astype(np.float32)[:, None, None]
        v = 255.0 * (np.clip(v, 0.0, 255.0) / 255.0) ** g
    scale = sigma
    if cfg.shot_noise > 0:
        k = rng.uniform(0.0, cfg.shot_noise, n).astype(np.float32)[:, None, None]
        scale = np.sqrt(sigma * sigma + k * np.clip(v, 0.0, 255.0))
    noise = rng.standard_normal(patches.shape).astype(np.float32) * scale
    return np.clip(np.rint(v + noise), 0.0, 255.0)


def _blurred(v: np.ndarray, sigmas: np.ndarray, shared_axis: bool) -> np.ndarray:
    """Each sample's crop through a Gaussian of its own sigma (replicated borders)."""
    out = v.copy()
    for i, s in enumerate(sigmas):
        if s < 0.05:  # a blur this small moves no grey level
            continue
        if shared_axis:
            for k in range(v.shape[0]):
                out[k, i] = cv2.GaussianBlur(v[k, i], (0, 0), float(s),
                                             borderType=cv2.BORDER_REPLICATE)
        else:
            out[i] = cv2.GaussianBlur(v[i], (0, 0), float(s), borderType=cv2.BORDER_REPLICATE)
    return out


def vertical_offsets(cfg, rng: np.random.Generator, n: int) -> np.ndarray:
    """The other view's vertical misalignment of each of ``n`` samples, U(-m, m) pixels with
    m = ``vshift_max`` (zeros, and no draw, when 0)."""
    if cfg.vshift_max <= 0:
        return np.zeros(n)
    return rng.uniform(-cfg.vshift_max, cfg.vshift_max, n)


def rows_at(image: np.ndarray, rows: np.ndarray, cols: np.ndarray, dy: float) -> np.ndarray:
    """``image[rows + dy, cols]`` with rows and columns clamped into the image (the chip's
    replicate border) and a fractional ``dy`` interpolated linearly between two rows."""
    h, w = image.shape
    cols = np.clip(cols, 0, w - 1)
    base = np.floor(dy)
    frac = dy - base
    r0 = np.clip(rows + int(base), 0, h - 1)[:, None]
    if frac == 0:
        return image[r0, cols]
    r1 = np.clip(rows + int(base) + 1, 0, h - 1)[:, None]
    return (1.0 - frac) * image[r0, cols] + frac * image[r1, cols]
