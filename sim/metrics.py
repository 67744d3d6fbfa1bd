"""Accuracy of a disparity map against ground truth (Middlebury SDK metrics and the paper's KPIs).

For each mask, the evaluated pixels are ``mask & isfinite(gt)`` (their count is ``n``). A
disparity that is not finite (NaN or inf) is *invalid*; every other disparity is *valid* and has
the error ``|d - gt|``. All thresholds are in pixels **of the GT's resolution**: evaluating a
quarter-resolution (MiddEval3 trainingQ) result against the quarter-resolution GT counts quarter-
resolution pixels, whereas the Middlebury online table upsamples results to full resolution, where
the same error is 4x larger. See ``docs/metrics.md`` for every definition.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from stereosim.core.errors import InputError

BAD_THRESHOLDS = (0.5, 1.0, 2.0, 4.0)
T_THRESHOLDS = (0.125, 0.25, 0.5, 0.75, 1.0, 2.0, 4.0)
M_THRESHOLDS = (0.125, 0.25, 0.5, 0.75)
F_THRESHOLDS = (0.5, 0.75, 1.0)


def _tag(t: float) -> str:
    """0.5 -> '0.5', 1.0 -> '1', 0.125 -> '0.125'."""
    return f"{t:g}"


BAD_KEYS = tuple(f"bad{_tag(t)}" for t in BAD_THRESHOLDS)
T_KEYS = tuple(f"T{_tag(t)}" for t in T_THRESHOLDS)
M_KEYS = tuple(f"M{_tag(t)}" for t in M_THRESHOLDS)
F_KEYS = ("F0.5", "F0.75", "F1.0")

#: The metrics also computed on the densified map (:func:`fill_invalid`), as ``dense_<key>``.
DENSE_KEYS = ("bad0.5", "bad1", "bad2", "bad4", "avgerr", "rms")

#: Every key of a per-mask result, in a sensible column order.
METRIC_KEYS = (
    ("n",)
    + BAD_KEYS
    + ("invalid", "totbad", "avgerr", "rms", "fill_factor", "rms_valid")
    + T_KEYS
    + M_KEYS
    + F_KEYS
    + tuple(f"dense_{k}" for k in DENSE_KEYS)
)

#: The columns of the Middlebury table and of the paper's Table (MiddEval3 metrics).
MIDDLEBURY_KEYS = ("bad0.5", "bad1", "bad2", "bad4", "invalid", "totbad", "avgerr", "rms")
#: The paper's development KPIs.
PAPER_KEYS = ("fill_factor", "rms_valid") + M_KEYS + T_KEYS + F_KEYS


def _percent(count: int, total: int) -> float:
    return 100.0 * count / total if total else math.nan


def _evaluate_mask(disp: np.ndarray, gt: np.ndarray, evaluated: np.ndarray) -> dict[str, float]:
    n = int(np.count_nonzero(evaluated))
    d = disp[evaluated]
    g = gt[evaluated]
    valid = np.isfinite(d)
    err = np.abs(d[valid] - g[valid])  # float64: errors of the valid evaluated pixels
    n_valid = int(err.size)
    n_invalid = n - n_valid

    out: dict[str, float] = {"n": float(n)}
    for key, t in zip(BAD_KEYS, BAD_THRESHOLDS, strict=True):
        out[key] = _percent(int(np.count_nonzero(err > t)), n)
    out["invalid"] = _percent(n_invalid, n)
    out["totbad"] = out["bad2"] + out["invalid"]
    out["avgerr"] = float(err.mean()) if n_valid else math.nan
    out["rms"] = float(np.sqrt(np.mean(err * err))) if n_valid else math.nan
    out["fill_factor"] = _percent(n_valid, n)
    out["rms_valid"] = out["rms"]
    for key, t in zip(T_KEYS, T_THRESHOLDS, strict=True):
        out[key] = _percent(int(np.count_nonzero(err > t)), n_valid)
    near = err[err <= 1.0]
    for key, t in zip(M_KEYS, M_THRESHOLDS, strict=True):
        out[key] = _percent(int(np.count_nonzero(near > t)), int(near.size))
    for key, t in zip(F_KEYS, F_THRESHOLDS, strict=True):
        good = int(np.count_nonzero(err <= t))
        if n_valid == 0:
            out[key] = math.nan  # precision undefined
        elif good == 0:
            out[key] = 0.0
        else:
            precision = good / n_valid
            recall = good / n
            out[key] = 2.0 * precision * recall / (precision + recall)
    return out


def fill_invalid(disp: np.ndarray) -> np.ndarray:
    """The map made dense before scoring, as the Middlebury evaluation treats sparse results:
    along each row, an invalid (non-finite) disparity takes the smaller of the nearest valid
    disparities to its left and to its right -- the background, since an invalid pixel is most
    often occluded -- or the one there is at a row's ends. A row without any valid disparity
    stays invalid. (The same rule as the KITTI devkit's background interpolation.)"""
    d = np.asarray(disp, dtype=np.float64)
    valid = np.isfinite(d)
    h, w = d.shape
    cols = np.broadcast_to(np.arange(w), (h, w))
    left = np.maximum.accumulate(np.where(valid, cols, -1), axis=1)
    right = np.minimum.accumulate(np.where(valid, cols, w)[:, ::-1], axis=1)[:, ::-1]
    from_left = np.where(left >= 0, np.take_along_axis(d, np.clip(left, 0, w - 1), 1), np.inf)
    from_right = np.where(right < w, np.take_along_axis(d, np.clip(right, 0, w - 1), 1), np.inf)
    return np.where(valid, d, np.minimum(from_left, from_right))


def _dense_metrics(filled: np.ndarray, gt: np.ndarray, evaluated: np.ndarray) -> dict:
    """``dense_<key>`` for :data:`DENSE_KEYS`: the sparse metrics of the filled map."""
    dense = _evaluate_mask(filled, gt, evaluated)
    return {f"dense_{k}": dense[k] for k in DENSE_KEYS}


def evaluate(
    disp: np.ndarray, gt: np.ndarray, masks: Mapping[str, np.ndarray]
) -> dict[str, dict[str, float]]:
    """Metrics of ``disp`` against ``gt`` for each mask: ``{mask name: {metric: value}}``.

    ``disp`` and ``gt`` are 2-D disparity maps in pixels of the same shape; non-finite ``disp``
    means invalid, non-finite ``gt`` unknown. Each mask is a boolean (or 0/non-zero) array of the
    same shape. Percentages are in 0..100, F-scores in 0..1, errors in pixels; a value with an
    empty denominator is NaN. Keys: see :data:`METRIC_KEYS` and ``docs/metrics.md``.
    """
    d = np.asarray(disp)
    if d.ndim != 2:
        raise InputError(f"disparity map has shape {d.shape}: a 2-D (H, W) map is needed")
    if not (np.issubdtype(d.dtype, np.floating) or np.issubdtype(d.dtype, np.integer)):
        raise InputError(f"disparity map has dtype {d.dtype}: give a float32 array")
    g, masks = check_truth(gt, masks, d.shape)
    d = d.astype(np.float64)
    g = g.astype(np.float64)
    known = np.isfinite(g)
    filled = fill_invalid(d)
    return {name: {**_evaluate_mask(d, g, m & known), **_dense_metrics(filled, g, m & known)}
            for name, m in masks.items()}


def check_truth(gt, masks, shape: tuple[int, int]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Check ground truth and masks for maps of ``shape``: ``(gt, {name: boolean mask})``."""
    if not isinstance(gt, np.ndarray):
        raise InputError(f"the GT must be a numpy array (H, W), got {type(gt).__name__}")
    if not (np.issubdtype(gt.dtype, np.floating) or np.issubdtype(gt.dtype, np.integer)):
        raise InputError(f"GT has dtype {gt.dtype}: give a float32 array")
    if gt.shape != tuple(shape):
        raise InputError(
            f"disparity map is {tuple(shape)} but GT is {gt.shape}: evaluate at the GT's size"
        )
    if not isinstance(masks, Mapping):
        raise InputError(
            f"masks must be a dict of name -> boolean (H, W) array, got {type(masks).__name__}"
        )
    checked = {}
    for name, mask in masks.items():
        m = np.asarray(mask)
        if m.shape != tuple(shape):
            raise InputError(
                f"mask '{name}' is {m.shape} but the disparity map is {tuple(shape)}: "
                "use the masks of the same scene and size"
            )
        if not (m.dtype == bool or np.issubdtype(m.dtype, np.integer)):
            raise InputError(f"mask '{name}' has dtype {m.dtype}: give a boolean array")
        checked[str(name)] = m != 0
    return gt, checked


def undefined_metrics(results: Mapping[str, Mapping[str, float]]) -> dict[str, str]:
    """Why a mask's metrics are undefined (NaN in Python, null in JSON), per mask that has any:
    no evaluated pixel, or no valid disparity among them."""
    notes = {}
    for mask, m in results.items():
        if not m.get("n"):
            notes[mask] = ("the mask selects no pixel with known ground truth: every metric is "
                           "undefined (null)")
        elif math.isnan(m.get("avgerr", 0.0)):
            notes[mask] = ("no valid disparity among the evaluated pixels: the error metrics "
                           "are undefined (null)")
    return notes


def mean_metrics(
    results: Sequence[Mapping[str, Mapping[str, float]]],
) -> dict[str, dict[str, float]]:
    """Plain (unweighted) mean over scenes of :func:`evaluate` results, per mask and per key.

    A mask or key missing from some scenes is averaged over the scenes that have it. NaN values
    propagate, so an undefined metric in any scene makes its mean NaN.
    """
    sums: dict[str, dict[str, list[float]]] = {}
    for result in results:
        for mask, metrics in result.items():
            per_mask = sums.setdefault(mask, {})
            for key, value in metrics.items():
                per_mask.setdefault(key, []).append(float(value))
    return {
        mask: {key: float(np.mean(values)) for key, values in per_mask.items()}
        for mask, per_mask in sums.items()
    }


def _cell(key: str, value: float | str | None) -> str:
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if key == "n" and math.isfinite(value) and float(value).is_integer():
        return str(int(value))
    return f"{value:.3f}"


def _numbers(rows, key: str) -> list[float]:
    return [float(m[key]) for _, m in rows
            if isinstance(m.get(key), (int, float)) and not isinstance(m.get(key), bool)]


def format_table(rows: Iterable[tuple[str, Mapping[str, float | str | None]]],
                 keys: Sequence[str], *, totals: Sequence[str] = ()) -> str:
    """An aligned text table: one row per ``(name, {key: value})``, one column per key, a
    ``MEAN`` row with the plain mean of each column (over the rows that have a number there)
    and, when ``totals`` names columns, a ``TOTAL`` row with their sums.

    Values print with 3 decimals (``n`` as an integer), text as it is; a missing key (or a
    column of text, in the MEAN and TOTAL rows) prints ``-``.
    """
    rows = list(rows)
    header = ["scene", *keys]
    lines = [[name, *(_cell(k, metrics.get(k)) for k in keys)] for name, metrics in rows]
    summary = []
    if rows:
        mean_row = ["MEAN"]
        for k in keys:
            values = _numbers(rows, k)
            mean_row.append(_cell(k, float(np.mean(values)) if values else None))
        summary.append(mean_row)
    if rows and totals:
        summary.append(["TOTAL", *(_cell(k, float(sum(_numbers(rows, k))))
                                   if k in totals else "-" for k in keys)])
    table = [header, *lines, *summary]
    widths = [max(len(r[i]) for r in table) for i in range(len(header))]

    def fmt(row: list[str]) -> str:
        cells = [row[0].ljust(widths[0])]
        cells += [cell.rjust(w) for cell, w in zip(row[1:], widths[1:], strict=True)]
        return "  ".join(cells).rstrip()

    out = [fmt(header), "  ".join("-" * w for w in widths)]
    out += [fmt(r) for r in lines]
    if summary:
        out.append("  ".join("-" * w for w in widths))
        out += [fmt(r) for r in summary]
    return "\n".join(out) + "\n"
