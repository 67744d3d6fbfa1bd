"""SRAM macros: area, energy per access and leakage as functions of size, word width and ports.

Each node with a cited macro table (``core/tech/data/<library>.json``, ``sram.macros``) gets
three power laws fitted to its single-port (1rw) macros (:func:`.fits.power_law`)::

    area = k_a * words^p_a * width^q_a        (um^2)
    E    = k_e * words^p_e * width^q_e        (energy of one access, read or write)
    P    = k_l * words^p_l * width^q_l        (leakage)

- **45 nm**: bsg_fakeram's CACTI macros (OpenROAD-flow-scripts ``flow/platforms/nangate45``).
  CACTI sizes a word to whole bytes, so the fit's width is ``8 ceil(width / 8)``; the macros whose
  height the platform tuned by hand for their pins (``area_hand_tuned``) are left out of the
  area fit (kept in the energy and leakage fits). The library gives one energy per access
  (CACTI's write energy on the clock pin): a read is priced as a write.
- **130 nm**: OpenRAM's sky130 macros; one energy per clock edge of a port, read or write.
- **7 nm**: no cited table (see ``asap7.json``'s ``sram_note``): :func:`sram_macro` refuses.

**Ports**: the 130 nm OpenRAM library has 1rw and 1rw1r macros of the same words and width
(32 x 256, 512, 1024); the mean ratios 1rw1r / 1rw of area, energy per port access and leakage
over those pairs (:func:`port_factors`) price a second port at every node. ``"1r1w"`` is priced
as the 1rw1r macro (its read port and its read-write port are the same dual-port bitcell);
``"2rw"`` likewise -- no library here offers a true dual-port macro, so 2rw is a lower bound.

**Outside the table**: a macro wider or deeper than the table's largest is built from tiles
(``ceil(words / max_words) x ceil(width / max_width)`` macros of equal size, an access reading
one row of tiles); a smaller one costs the table's smallest words or width (a macro compiler's
floor).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from stereosim.core.errors import ConfigError
from stereosim.core.tech.fits import Fit, power_law, power_law_eval
from stereosim.core.tech.nodes import FILES, raw

PORTS = ("1rw", "1r1w", "2rw")
_ENERGY_PJ = {"fJ": 1e-3, "pJ": 1.0}
_LEAK_UW = {"nW": 1e-3, "mW": 1e3}


@dataclass(frozen=True, slots=True)
class SramMacro:
    """One macro (or a tiled group of them): area, energy of one access of one port, leakage."""

    area_mm2: float
    read_pj: float
    write_pj: float
    leakage_uw: float
    tiles: int


@dataclass(frozen=True, slots=True)
class SramFits:
    """A node's three fits, the word rounding of its generator and its table's range."""

    area: Fit
    energy: Fit
    leakage: Fit
    byte_words: bool
    words: tuple[int, int]
    width: tuple[int, int]


def _width(width: int, byte_words: bool) -> int:
    """The width the generator sized (whole bytes for CACTI)."""
    return 8 * math.ceil(width / 8) if byte_words else width


def _columns(macros: list[dict], byte_words: bool) -> tuple[np.ndarray, ...]:
    """words, fitted width, area (um^2), energy (pJ), leakage (uW) of a list of macros."""
    return (np.array([m["words"] for m in macros], float),
            np.array([_width(m["width"], byte_words) for m in macros], float),
            np.array([m["area_um2"] for m in macros], float),
            np.array([m.get("access_pj", m.get("access_fj", 0) * 1e-3) for m in macros], float),
            np.array([m.get("leakage_mw", 0) * 1e3 + m.get("leakage_nw", 0) * 1e-3
                      for m in macros], float))


def macros(name: str) -> list[dict] | None:
    """The node's macro table as stored, or None."""
    s = raw(name).get("sram")
    return s["macros"] if s else None


@functools.cache
def sram_fits(name: str) -> SramFits | None:
    """The node's fits to its 1rw macros, or None without a table."""
    table = macros(name)
    if not table:
        return None
    byte_words = name == "45nm"
    single = [m for m in table if m.get("ports", "1rw") == "1rw"]
    sized = [m for m in single if not m.get("area_hand_tuned")]
    w, b, area, _, _ = _columns(sized, byte_words)
    w_all, b_all, _, energy, leak = _columns(single, byte_words)
    return SramFits(
        area=power_law([w, b], area), energy=power_law([w_all, b_all], energy),
        leakage=power_law([w_all, b_all], leak), byte_words=byte_words,
        words=(int(w_all.min()), int(w_all.max())), width=(int(b_all.min()), int(b_all.max())))


@functools.cache
def port_factors() -> dict[str, float]:
    """Mean ratio 1rw1r / 1rw (area, energy per port access, leakage) over the 130 nm OpenRAM
    macros of equal words and width."""
    table = macros("130nm")
    one = {(m["words"], m["width"]): m for m in table if m["ports"] == "1rw"}
    pairs = [(one[(m["words"], m["width"])], m) for m in table
             if m["ports"] == "1rw1r" and (m["words"], m["width"]) in one]
    ratio = {k: float(np.mean([b[k] / a[k] for a, b in pairs]))
             for k in ("area_um2", "access_pj", "leakage_mw")}
    return {"area": ratio["area_um2"], "energy": ratio["access_pj"],
            "leakage": ratio["leakage_mw"], "pairs": len(pairs)}


def sram_macro(node: str, bits: int, word_bits: int, ports: str = "1rw") -> SramMacro:
    """The macro holding ``bits`` in words of ``word_bits`` with ``ports`` ("1rw", "1r1w",
    "2rw") at ``node``: area, energy of one access of one port (read = write: the libraries
    give one figure), leakage. A node without a table, unknown ports or a non-positive size
    raise ConfigError."""
    if node not in FILES:
        raise ConfigError(f"unknown technology node {node!r} (known: {', '.join(FILES)})")
    if ports not in PORTS:
        raise ConfigError(f"unknown SRAM ports {ports!r} (known: {', '.join(PORTS)})")
    if bits <= 0 or word_bits <= 0:
        raise ConfigError(f"an SRAM needs bits > 0 and word_bits > 0 (got {bits}, {word_bits})")
    fits = sram_fits(node)
    if fits is None:
        raise ConfigError(f"no cited SRAM macro table for {node} (nodes with one: "
                          f"{', '.join(n for n in FILES if sram_fits(n))})")
    words = math.ceil(bits / word_bits)
    width = _width(word_bits, fits.byte_words)
    rows = math.ceil(words / fits.words[1])
    cols = math.ceil(width / fits.width[1])
    tile_words = max(math.ceil(words / rows), fits.words[0])
    tile_width = max(math.ceil(width / cols), fits.width[0])
    scale = port_factors() if ports != "1rw" else {"area": 1.0, "energy": 1.0, "leakage": 1.0}
    energy = cols * power_law_eval(fits.energy, tile_words, tile_width) * scale["energy"]
    return SramMacro(
        area_mm2=rows * cols * power_law_eval(fits.area, tile_words, tile_width)
        * scale["area"] * 1e-6,
        read_pj=energy, write_pj=energy,
        leakage_uw=rows * cols * power_law_eval(fits.leakage, tile_words, tile_width)
        * scale["leakage"],
        tiles=rows * cols)
