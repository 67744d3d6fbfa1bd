"""The least-squares fits of the technology model, each to a table of cited data points.

Three forms, all solved with numpy's linear least squares (no iteration, no starting guess):

- :func:`power_law`: ``y = k * x1^p1 * x2^p2 ...`` in log space -- the SRAM macros' area, energy
  and leakage against words and width (CACTI-style scaling: the bit array grows with words x
  width, a bitline's energy with its length).
- :func:`alpha_power`: Sakurai and Newton's alpha-power law (T. Sakurai, A. R. Newton,
  "Alpha-power law MOSFET model and its applications to CMOS inverter delay and other
  formulas", IEEE JSSC 25(2), 1990): a gate's delay ``t = K * V / (V - Vt)^alpha``. For each
  ``Vt`` on a 1 mV grid the log form is linear in ``log K`` and ``alpha``; the ``Vt`` with the
  least squared error wins.
- :func:`exponential`: ``y = y0 * exp(k * V)`` in log space -- leakage power against the supply
  (subthreshold leakage rises exponentially with V through drain-induced barrier lowering).

Each returns its coefficients and its relative errors at the data points, which the tests and
``python -m stereosim.core.tech`` print and check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class Fit:
    """A fit's coefficients and its relative errors (predicted / datum - 1) at its points."""

    coefficients: tuple[float, ...]
    errors: tuple[float, ...]

    @property
    def max_error(self) -> float:
        """The largest relative error, in absolute value."""
        return float(np.max(np.abs(self.errors)))

    @property
    def rms_error(self) -> float:
        """The root-mean-square relative error."""
        return float(np.sqrt(np.mean(np.square(self.errors))))


def power_law(xs: list[np.ndarray], y: np.ndarray) -> Fit:
    """``y = k * prod(x_i^p_i)``: coefficients ``(k, p_1, ...)``, least squares in log y."""
    a = np.column_stack([np.ones(len(y)), *[np.log(np.asarray(x, float)) for x in xs]])
    c, *_ = np.linalg.lstsq(a, np.log(y), rcond=None)
    pred = np.exp(a @ c)
    return Fit((float(np.exp(c[0])), *map(float, c[1:])), tuple(map(float, pred / y - 1)))


def power_law_eval(fit: Fit, *xs: float) -> float:
    """The value of a :func:`power_law` fit at ``xs``."""
    k, *ps = fit.coefficients
    return float(k * np.prod([x**p for x, p in zip(xs, ps, strict=True)]))


def alpha_power(v: np.ndarray, delay: np.ndarray) -> Fit:
    """``delay = K * V / (V - Vt)^alpha``: coefficients ``(K, Vt, alpha)``, ``Vt`` searched
    on a 1 mV grid below the lowest voltage, least squares in log delay."""
    v = np.asarray(v, float)
    best = None
    for vt in np.arange(0.0, float(v.min()) - 0.01, 0.001):
        a = np.column_stack([np.ones(len(v)), -np.log(v - vt)])
        c, *_ = np.linalg.lstsq(a, np.log(delay / v), rcond=None)
        sse = float(np.sum((a @ c - np.log(delay / v)) ** 2))
        if best is None or sse < best[0]:
            best = (sse, vt, c)
    _, vt, c = best
    pred = np.exp(c[0]) * v / (v - vt) ** c[1]
    return Fit((float(np.exp(c[0])), float(vt), float(c[1])), tuple(map(float, pred / delay - 1)))


def exponential(v: np.ndarray, y: np.ndarray) -> Fit:
    """``y = y0 * exp(k * V)``: coefficients ``(y0, k)``, least squares in log y."""
    a = np.column_stack([np.ones(len(v)), np.asarray(v, float)])
    c, *_ = np.linalg.lstsq(a, np.log(y), rcond=None)
    pred = np.exp(a @ c)
    return Fit((float(np.exp(c[0])), float(c[1])), tuple(map(float, pred / y - 1)))
