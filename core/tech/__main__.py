"""``python -m stereosim.core.tech``: print the technology model's tables (docs/energy.md)."""

from __future__ import annotations

from stereosim.core.tech.nodes import NODES, cite, raw, vf_fits
from stereosim.core.tech.sram import port_factors, sram_fits

_FIELDS = (
    ("vdd_v", "nominal supply (V)", "{:.2f}"),
    ("ge_area_um2", "gate-equivalent (NAND2) area (um^2)", "{:.4g}"),
    ("ge_leakage_nw", "leakage per GE (nW)", "{:.4g}"),
    ("ge_toggle_fj", "energy per GE output toggle (fJ)", "{:.4g}"),
    ("gate_delay_ps", "gate delay, NAND2 FO4 (ps)", "{:.1f}"),
    ("fo4_inverter_ps", "FO4 inverter delay (ps)", "{:.1f}"),
    ("ff_area_ge", "flip-flop area (GE)", "{:.3g}"),
    ("ff_leakage_nw", "flip-flop leakage (nW)", "{:.4g}"),
    ("ff_clock_fj", "flip-flop clock energy per cycle (fJ)", "{:.4g}"),
    ("ff_clk_to_q_ps", "flip-flop clock-to-Q (ps)", "{:.1f}"),
    ("ff_setup_ps", "flip-flop setup (ps)", "{:.1f}"),
    ("dram_pj_per_bit", "DRAM energy per bit (pJ)", "{:.1f}"),
)


def node_tables() -> list[str]:
    """One markdown table per node: figure, value, source."""
    out = []
    for node in NODES.values():
        logic = raw(node.name)["logic"]
        libs = {cite(logic["library"]): "[logic library]",
                cite(logic["flop_library"]): "[flop library]"}
        out += [f"### {node.name}: {node.description}", ""]
        out += [f"- {tag}: {lib}" for lib, tag in libs.items()]
        out += ["", "| figure | value | source |", "|---|---|---|"]
        for key, label, fmt in _FIELDS:
            src = node.sources[key]
            for lib, tag in libs.items():
                src = src.replace(lib, tag)
            out.append(f"| {label} | {fmt.format(getattr(node, key))} | {src} |")
        if node.alpha is not None:
            vt = (f"Vt {node.vt_v:.3f} V, alpha {node.alpha:.3f}, "
                  f"leakage k {node.leakage_k_per_v:.3f} /V")
            out.append(f"| voltage model | {vt}; {node.v_range[0]:g} to {node.v_range[1]:g} V "
                       f"| {node.sources['vt_v']} |")
        else:
            out.append(f"| voltage model | nominal only | {node.sources['vt_v']} |")
        out.append("")
    return out


def fit_tables() -> list[str]:
    """The SRAM and voltage fits with their errors."""
    out = ["### SRAM fits: value = k words^p width^q (1rw macros)", "",
           "| node | quantity | k | p | q | rms error | max error | macros | words | width |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    units = {"area": "um^2", "energy": "pJ", "leakage": "uW"}
    for name in NODES:
        fits = sram_fits(name)
        if fits is None:
            out.append(f"| {name} | none | | | | | | | | |")
            continue
        for q in ("area", "energy", "leakage"):
            f = getattr(fits, q)
            k, p, w = f.coefficients
            out.append(f"| {name} | {q} ({units[q]}) | {k:.4g} | {p:.3f} | {w:.3f} | "
                       f"{f.rms_error:.1%} | {f.max_error:.1%} | {len(f.errors)} | "
                       f"{fits.words[0]}-{fits.words[1]} | {fits.width[0]}-{fits.width[1]} |")
    pf = port_factors()
    out += ["", f"Second port (1rw1r / 1rw, mean of {pf['pairs']} 130 nm pairs): area x "
            f"{pf['area']:.3f}, energy per port access x {pf['energy']:.3f}, leakage x "
            f"{pf['leakage']:.3f}.", "", "### Voltage fits", "",
            "| node | delay fit K, Vt, alpha | max error | leakage fit k (/V) | max error "
            "| points |",
            "|---|---|---|---|---|---|"]
    for name in NODES:
        fits = vf_fits(name)
        if fits is None:
            out.append(f"| {name} | none | | | | 0 |")
            continue
        d, lk = fits
        out.append(f"| {name} | {d.coefficients[0]:.4g} ns, {d.coefficients[1]:.3f} V, "
                   f"{d.coefficients[2]:.3f} | {d.max_error:.1%} | {lk.coefficients[1]:.3f} | "
                   f"{lk.max_error:.1%} | {len(d.errors)} ({raw(name)['vf']['corner']}) |")
    return out


def main() -> None:
    """Print the tables."""
    print("\n".join(node_tables() + fit_tables()))


if __name__ == "__main__":
    main()
