"""Voltage scaling: clock frequency, dynamic energy and leakage against the supply, as ratios to
the node's nominal supply.

- **frequency**: the alpha-power law (T. Sakurai, A. R. Newton, IEEE JSSC 25(2), 1990): a gate's
  delay is proportional to ``V / (V - Vt)^alpha``, so ``f(V) / f(Vnom) = ((V - Vt)^alpha / V) /
  ((Vnom - Vt)^alpha / Vnom)``. ``Vt`` and ``alpha`` are fitted (:func:`fits.alpha_power`) to
  the FO4 delay of the node's inverter at one process corner and temperature over several
  supplies (130 nm: sky130_fd_sc_hd__inv_1 at ss_n40C, 1.28 to 1.76 V).
- **dynamic energy**: ``(V / Vnom)^2`` (a switched capacitance's ``C V^2``).
- **leakage power**: ``exp(k (V - Vnom))``, ``k`` fitted (:func:`fits.exponential`) to the same
  cells' leakage over the same supplies.

The fits are at the slow corner and -40 C and are applied as ratios around the typical corner's
nominal supply: the shape is the library's, not a typical-corner measurement. A node whose
libraries give no same-corner voltage series (45 nm, 7 nm: their corners change process and
temperature with the voltage) accepts only its nominal supply. A voltage outside the node's
range raises ConfigError.
"""

from __future__ import annotations

import math

from stereosim.core.errors import ConfigError
from stereosim.core.tech.nodes import Node


def check_voltage(node: Node, v: float) -> None:
    """Raise ConfigError unless ``v`` lies in the node's fitted range."""
    lo, hi = node.v_range
    if not (lo - 1e-9 <= v <= hi + 1e-9):
        why = (f"its fitted range is {lo:g} to {hi:g} V" if node.alpha is not None
               else f"no voltage series is cited for it: only its nominal {hi:g} V")
        raise ConfigError(f"supply {v:g} V is outside what the {node.name} model covers ({why})")


def frequency_scale(node: Node, v: float) -> float:
    """f(v) / f(nominal) by the alpha-power law (1 at the nominal supply)."""
    check_voltage(node, v)
    if node.alpha is None:
        return 1.0

    def speed(x: float) -> float:
        return (x - node.vt_v) ** node.alpha / x

    return speed(v) / speed(node.vdd_v)


def dynamic_energy_scale(node: Node, v: float) -> float:
    """E(v) / E(nominal) = (v / nominal)^2."""
    check_voltage(node, v)
    return (v / node.vdd_v) ** 2


def leakage_scale(node: Node, v: float) -> float:
    """P_leak(v) / P_leak(nominal) = exp(k (v - nominal))."""
    check_voltage(node, v)
    if node.leakage_k_per_v is None:
        return 1.0
    return math.exp(node.leakage_k_per_v * (v - node.vdd_v))
