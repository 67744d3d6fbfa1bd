"""The process nodes: one :class:`Node` per node, every figure read from a cited library table.

A node's raw figures sit in ``core/tech/data/<library>.json`` (the library cells' values in the
library's own units, each table with its repository, commit and path); :func:`_load` converts
them to the units below and records, field by field, where each came from (``Node.sources``).
Nothing here is typed in by hand: the JSON holds what the liberty files say, this module only
converts units and adds the switched load (``0.5 C V^2``) that a liberty internal energy leaves
out.

Definitions (the same for every node):

- **gate-equivalent (GE)**: the area of the library's smallest two-input NAND.
- **gate delay**: that NAND driving four of its own inputs (FO4), its input slew its own output
  slew -- the rule ``sim/rtl_synth.py`` uses for fmax (45 nm: 28.9 ps there and here).
- **energy per GE toggle**: the NAND's internal energy per output transition (mean of rise and
  fall over its arcs) at that load and slew, plus ``0.5 C_load V^2`` for charging the load.
- **flip-flop clock energy**: one clock cycle (the clock pin's rise + fall internal energy with
  D equal to Q, plus ``C_clk V^2`` for the clock pin): what a clocked register that does not
  change costs.
- **DRAM**: per bit moved, the figure of ``sim/energy.toml`` (Horowitz, ISSCC 2014) at every node.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.tech.fits import Fit, alpha_power, exponential

DATA = Path(__file__).resolve().parent / "data"
# node name -> its data file
FILES = {"130nm": "sky130.json", "45nm": "nangate45.json", "7nm": "asap7.json"}

# the library units -> ps, nW, fF, fJ
_TIME_PS = {"ns": 1000.0, "ps": 1.0}
_POWER_NW = {"nW": 1.0, "pW": 1e-3}
_CAP_FF = {"fF": 1.0, "pF": 1000.0}
_ENERGY_FJ = {"fJ": 1.0, "pJ": 1000.0}


@dataclass(frozen=True, slots=True)
class Node:
    """One process node's logic, DRAM and voltage figures (units in the names)."""

    name: str
    nm: int
    description: str
    vdd_v: float
    ge_area_um2: float
    ge_leakage_nw: float
    ge_toggle_fj: float
    gate_delay_ps: float
    fo4_inverter_ps: float
    ff_area_ge: float
    ff_leakage_nw: float
    ff_clock_fj: float
    ff_clk_to_q_ps: float
    ff_setup_ps: float
    dram_pj_per_bit: float
    # alpha-power law (vf.py); None where the node has no same-corner voltage series
    vt_v: float | None
    alpha: float | None
    leakage_k_per_v: float | None
    v_range: tuple[float, float]
    sources: dict[str, str] = field(repr=False)


def cite(src: dict) -> str:
    """One line: repository @ commit: path (what)."""
    return f"{src['repository']}@{src['commit'][:7]}: {src['path']} ({src['what']})"


@functools.cache
def _raw_text(name: str) -> str:
    """The node's data file's text."""
    return (DATA / FILES[name]).read_text()


def raw(name: str) -> dict:
    """The node's data file as stored (library units): a fresh copy."""
    return json.loads(_raw_text(name))


@functools.cache
def vf_fits(name: str) -> tuple[Fit, Fit] | None:
    """(delay fit, leakage fit) of the node's same-corner voltage series, or None: the
    alpha-power law through the FO4 delays and the exponential through the leakage."""
    vf = raw(name).get("vf")
    if not vf:
        return None
    v = np.array([p["vdd"] for p in vf["points"]])
    delay = np.array([p["inv_fo4_delay_ns"] for p in vf["points"]])
    leak = np.array([p["inv_leakage_nw"] for p in vf["points"]])
    return alpha_power(v, delay), exponential(v, leak)


def _load(name: str) -> Node:
    """Build the node from its data file (units converted, the load's energy added)."""
    d = raw(name)
    lg = d["logic"]
    u = lg["units"]
    t, p, c, e = _TIME_PS[u["time"]], _POWER_NW[u["leakage"]], _CAP_FF[u["capacitance"]], \
        _ENERGY_FJ[u["energy"]]
    vdd = lg["vdd"]
    lib, flop = cite(lg["library"]), cite(lg["flop_library"])
    cells = lg["cells"]
    load_ff = lg["nand2_fo4_load"] * c
    fits = vf_fits(name)
    if fits:
        _, vt, alpha = fits[0].coefficients
        k = fits[1].coefficients[1]
        lo = d["vf"]["range_v"][0]
        vf_src = cite(d["vf"]["source"]) + "; alpha-power law fit (fits.alpha_power)"
    else:
        vt = alpha = k = None
        lo = vdd
        vf_src = "none: " + d["vf_note"]
    nand, inv, ff = cells["nand2"], cells["inv"], cells["flop"]
    src = {
        "vdd_v": f"{lib}: nom_voltage",
        "ge_area_um2": f"{lib}: {nand} area",
        "ge_leakage_nw": f"{lib}: {nand} cell_leakage_power",
        "ge_toggle_fj": f"{lib}: {nand} internal_power at its FO4 load and slew, plus 0.5 C V^2 "
                        f"of that load ({load_ff:.3f} fF)",
        "gate_delay_ps": f"{lib}: {nand} FO4 delay (cell_rise/cell_fall)",
        "fo4_inverter_ps": f"{lib}: {inv} FO4 delay",
        "ff_area_ge": f"{flop}: {ff} area / {nand} area",
        "ff_leakage_nw": f"{flop}: {ff} cell_leakage_power",
        "ff_clock_fj": f"{flop}: {ff} clock pin internal_power (rise + fall, D = Q) plus C_clk V^2",
        "ff_clk_to_q_ps": f"{flop}: {ff} clock-to-Q at the FO4 load",
        "ff_setup_ps": f"{flop}: {ff} setup_rising constraint",
        "dram_pj_per_bit": d["dram"]["source"],
        "vt_v": vf_src, "alpha": vf_src, "leakage_k_per_v": vf_src.replace("alpha-power law",
                                                                            "exponential"),
        "v_range": vf_src,
    }
    return Node(
        name=d["node"], nm=d["nm"], description=d["description"], vdd_v=vdd,
        ge_area_um2=lg["nand2_area_um2"],
        ge_leakage_nw=lg["nand2_leakage"] * p,
        ge_toggle_fj=lg["nand2_internal_energy"] * e + 0.5 * load_ff * vdd**2,
        gate_delay_ps=lg["nand2_fo4_delay"] * t,
        fo4_inverter_ps=lg["inv_fo4_delay"] * t,
        ff_area_ge=lg["flop_area_um2"] / lg["nand2_area_um2"],
        ff_leakage_nw=lg["flop_leakage"] * p,
        ff_clock_fj=lg["flop_clock_internal_energy_per_cycle"] * e
        + lg["flop_clock_cap"] * c * vdd**2,
        ff_clk_to_q_ps=lg["flop_clk_to_q"] * t,
        ff_setup_ps=lg["flop_setup"] * t,
        dram_pj_per_bit=d["dram"]["pj_per_bit"],
        vt_v=vt, alpha=alpha, leakage_k_per_v=k,
        v_range=(lo, vdd),
        sources=src,
    )


NODES: dict[str, Node] = {name: _load(name) for name in FILES}


def node(name: str) -> Node:
    """The node called ``name`` ("45nm", ...); an unknown name raises ConfigError."""
    try:
        return NODES[name]
    except KeyError:
        raise ConfigError(f"unknown technology node {name!r} (known: "
                          f"{', '.join(NODES)})") from None
