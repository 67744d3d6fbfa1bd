"""Energy and power of the chip: every action of a frame, counted from the plan and the run,
times the energy of one action from an energy reference table (as Accelergy and Timeloop do).

The table (``sim/energy.toml`` by default, ``--energy FILE`` or ``energy_table(path)``) gives
the energy of an int8 MAC, a 32-bit multiply, one bit of an adder, an SRAM bit read by array
size (written: ``write_factor`` reads), a bit pushed or popped through a FIFO, a DRAM bit and a
clock cycle per domain. The actions of one frame:

- **NNA** (both cameras): its MACs and requantising multiplies
  (:func:`~sim.cycle.figures.action_counts`); the census unit's comparisons as bit-adds (8 per
  window sample);
- **SRAM**: every buffer's declared accesses per output pixel (:class:`BufferPlan`:
  ``pixel_reads``, ``pixel_writes`` of ``word_bits`` bits), priced at the size of one of its
  banks;
- **SVA datapath**, in bit-adds per pixel and disparity: the Hamming cost (b XOR bits and a
  popcount tree, sum over levels i of (b / 2^i) i bits), the box filter (4 adds: column and row
  sums updated), each SGM path (7 adds and compares of the path costs), the path sum (paths -
  1 adds), the winner-take-all (1 compare, 2 with the uniqueness check) and the LR check's
  diagonal (1 compare);
- **FIFOs**: every bit through them, pushed and popped (over the run, shared per frame);
- **DRAM**: a memory source reads both views (a byte a pixel each), a camera with frame
  buffers writes them first, the disparity is written back (a word a pixel);
- **clock**: the run's cycles of each domain, per frame;
- **lent** (``nna.lent_network``): the network on the lent submodules over the stereo frame's
  time, as many of its frames as its fps gives (:func:`lent_energy_items`).

The report (``energy``) lists every item -- block, action, what, count, unit energy -- so the
total is their sum (``tests/sim/cycle/test_energy.py`` holds it), the totals by block and by action,
and the average power at the stream's measured frame rate (the work bound for one frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from stereosim.core.config import read_toml
from stereosim.core.errors import ConfigError
from stereosim.core.timing import lg
from stereosim.sim.cycle.figures import action_counts
from stereosim.sim.cycle.lent import LentPlan
from stereosim.sim.cycle.plan import ChipPlan
from stereosim.sva.geometry import bits_for
from stereosim.sva.hamming.noise import band_rows

DEFAULT_TABLE = Path(__file__).resolve().parents[1] / "energy.toml"

# the table's keys: section -> key -> kind ("number", "numbers" or "text")
_KEYS = {
    "technology": {"node": "text", "source": "text"},
    "logic": {"mac_int8_pj": "number", "mult32_pj": "number", "add_pj_per_bit": "number"},
    "sram": {"read_kbit": "numbers", "read_pj_per_bit": "numbers", "write_factor": "number"},
    "fifo": {"pj_per_bit": "number"},
    "dram": {"pj_per_bit": "number"},
    "clock": {"nna_pj_per_cycle": "number", "sva_pj_per_cycle": "number"},
}


@dataclass(frozen=True)
class EnergyTable:
    """An energy reference table (pJ per action; see the module docstring)."""

    node: str
    source: str
    mac_int8_pj: float
    mult32_pj: float
    add_pj_per_bit: float
    read_kbit: tuple[float, ...]
    read_pj_per_bit: tuple[float, ...]
    write_factor: float
    fifo_pj_per_bit: float
    dram_pj_per_bit: float
    clock_pj_per_cycle: dict[str, float]

    def sram_read_pj_per_bit(self, bits: int) -> float:
        """Read energy per bit of an array of ``bits`` bits: log-linear between the table's
        sizes, flat beyond them."""
        kbit = max(bits, 1) / 1024
        xs, ys = self.read_kbit, self.read_pj_per_bit
        if kbit <= xs[0]:
            return ys[0]
        if kbit >= xs[-1]:
            return ys[-1]
        i = next(i for i in range(1, len(xs)) if kbit <= xs[i])
        f = (math.log(kbit) - math.log(xs[i - 1])) / (math.log(xs[i]) - math.log(xs[i - 1]))
        return ys[i - 1] + f * (ys[i] - ys[i - 1])


def energy_table(path: str | Path | None = None) -> EnergyTable:
    """The table at ``path`` (default: stereosim's); every key checked, one line for any
    mistake."""
    path = DEFAULT_TABLE if path is None else Path(path)
    raw = read_toml(path, "energy table")
    where = f"energy table {path}"
    for section, body in raw.items():
        if section not in _KEYS or not isinstance(body, dict):
            raise ConfigError(f"{where}: unknown section [{section}] (known: "
                              f"{', '.join(_KEYS)})")
        for key in body:
            if key not in _KEYS[section]:
                raise ConfigError(f"{where}: unknown key {section}.{key} (known: "
                                  f"{', '.join(_KEYS[section])})")
    values = {}
    for section, keys in _KEYS.items():
        for key, kind in keys.items():
            if key not in raw.get(section, {}):
                raise ConfigError(f"{where}: {section}.{key} is missing")
            v = raw[section][key]
            name = f"{section}.{key}"
            if kind == "text":
                if not isinstance(v, str):
                    raise ConfigError(f"{where}: {name} must be text")
            elif kind == "number":
                v = _number(where, name, v)
            else:
                if not isinstance(v, list) or not v:
                    raise ConfigError(f"{where}: {name} must be a list of numbers")
                v = tuple(_number(where, name, x) for x in v)
            values[name] = v
    kbit, pj = values["sram.read_kbit"], values["sram.read_pj_per_bit"]
    if len(kbit) != len(pj) or any(b <= a for a, b in zip(kbit, kbit[1:])) or kbit[0] <= 0:
        raise ConfigError(f"{where}: sram.read_kbit must increase from above 0 and match "
                          "sram.read_pj_per_bit entry for entry")
    return EnergyTable(
        node=values["technology.node"], source=values["technology.source"],
        mac_int8_pj=values["logic.mac_int8_pj"], mult32_pj=values["logic.mult32_pj"],
        add_pj_per_bit=values["logic.add_pj_per_bit"], read_kbit=kbit, read_pj_per_bit=pj,
        write_factor=values["sram.write_factor"], fifo_pj_per_bit=values["fifo.pj_per_bit"],
        dram_pj_per_bit=values["dram.pj_per_bit"],
        clock_pj_per_cycle={"nna": values["clock.nna_pj_per_cycle"],
                            "sva": values["clock.sva_pj_per_cycle"]})


def _number(where: str, name: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
        raise ConfigError(f"{where}: {name} must be a finite number >= 0, got {v!r}")
    return float(v)


def popcount_bit_adds(bits: int) -> int:
    """Bit-adds of a popcount of ``bits`` bits as a tree of adders: level i has bits / 2^i
    adders of i bits."""
    return sum((bits >> i) * i for i in range(1, lg(bits) + 1))


def sva_bit_adds_per_cell(plan: ChipPlan) -> dict[str, int]:
    """The SVA datapath's bit-adds per pixel and disparity, stage by stage (module docstring)."""
    s = plan.cfg.sva
    b = plan.descriptor_bits
    box = bits_for(s.box_size * s.box_size * plan.cost_max)
    # the XOR, each part's popcount; the hybrid's two weighted distances (a distance plus
    # itself shifted) and their sum, adders of the cost's width
    hamming = b + sum(popcount_bit_adds(p) for p in plan.part_bits)
    if plan.hybrid:
        hamming += 3 * bits_for(plan.cost_max)
    out = {
        "hamming": hamming,
        "box_filter": 4 * box,
        "sgm": s.paths * 7 * s.path_bits,
        "path_sum": (s.paths - 1) * s.sum_bits,
        "wta": (2 if s.uniqueness else 1) * s.sum_bits,
    }
    if s.lr_check:
        out["lr_check"] = s.sum_bits
    return out


def energy_items(plan: ChipPlan, table: EnergyTable, stats: dict) -> list[dict]:
    """Every action of one frame: ``{block, action, what, count, unit, pj_each}``."""
    h, w = plan.shape
    n = h * w
    frames = plan.frames
    cfg = plan.cfg
    counts = action_counts(plan)
    items: list[dict] = []

    def add(block, action, what, count, unit, pj_each):
        if count:
            items.append({"block": block, "action": action, "what": what, "count": int(count),
                          "unit": unit, "pj_each": pj_each})

    nna = counts["nna_per_camera"]
    # one layer: the submodule's; several: each layer's, over its region
    for layer, c in counts.get("nna_layers", {"": nna}).items():
        of = f"{layer}: " if layer else ""
        add("nna", "mac", f"{of}int8 multiply-accumulates, both cameras", 2 * c["macs"], "MAC",
            table.mac_int8_pj)
        add("nna", "multiply", f"{of}requantising multiplies, both cameras",
            2 * c["requant_multiplies"], "32-bit multiply", table.mult32_pj)
    if cfg.nna.descriptor in ("census", "hybrid"):
        ww, wh = cfg.nna.census.window
        add("nna", "logic", "census comparisons (8-bit), both cameras", 2 * n * ww * wh * 8,
            "bit-add", table.add_pj_per_bit)
    if plan.hybrid and cfg.sva.weight_mode == "auto":  # the noise unit over the band's pixels
        add("sva", "logic", "noise statistic: a 3x3 Laplacian and gradient (10 adds of 12 "
            "bits) and the accumulators, over the band's pixels",
            (band_rows(cfg.sva, h) - 2) * max(0, w - 2) * (10 * 12 + 2 * 32), "bit-add",
            table.add_pj_per_bit)
    for block, copies in (("nna", 2), ("sva", 1)):
        bufs = {}
        for b in plan.blocks_of(block):
            for buf in b.buffers:
                bufs.setdefault(buf.name, buf)
        for buf in bufs.values():
            bank = buf.bits // max(1, buf.banks)
            read = table.sram_read_pj_per_bit(bank)
            add(block, "sram_read", f"{buf.name} ({bank} bits a bank)",
                copies * n * buf.pixel_reads * buf.word_bits, "bit", read)
            add(block, "sram_write", f"{buf.name} ({bank} bits a bank)",
                copies * n * buf.pixel_writes * buf.word_bits, "bit", read * table.write_factor)
    for stage, bit_adds in sva_bit_adds_per_cell(plan).items():
        add("sva", "logic", f"{stage} datapath", n * cfg.sva.disparities * bit_adds, "bit-add",
            table.add_pj_per_bit)
    for f in plan.fifos:
        bits = stats["fifos"][f.name]["bits_transferred"] // frames
        add("fifos", "fifo", f"{f.name}: bits pushed and popped", 2 * bits, "bit",
            table.fifo_pj_per_bit)
    if not plan.camera_direct:
        add("dram", "dram", "both views read by the memory sources", 2 * n * 8, "bit",
            table.dram_pj_per_bit)
    if plan.frame_buffered:
        add("dram", "dram", "both views written into the frame buffers", 2 * n * 8, "bit",
            table.dram_pj_per_bit)
    add("dram", "dram", "disparity words written back", n * plan.word_bits, "bit",
        table.dram_pj_per_bit)
    spill = plan.dram.client("spill") if plan.dram is not None else None
    if spill is not None:
        add("dram", "dram", f"{cfg.dram.spill} spilled between NNA and SVA (written and read "
            "back, both views)", round(spill.bytes_per_pixel * n * 8), "bit",
            table.dram_pj_per_bit)
    if plan.lent is not None:  # the lent network, over the stereo frame's time
        seconds = stats["cycles"]["nna"] / frames / plan.domains["nna"].freq_hz
        items.extend(lent_energy_items(plan.lent, table, plan.lent.fps * seconds))
    for domain, cycles in sorted(stats["cycles"].items()):
        pj = table.clock_pj_per_cycle.get(domain, 0.0)
        add("clock", "clock", f"{domain} domain cycles", cycles // frames, "cycle", pj)
    return items


def lent_energy_items(lent: LentPlan, table: EnergyTable, frames: float) -> list[dict]:
    """The lent network's actions over ``frames`` of its frames (a stereo frame's time at its
    fps): its MACs and requantising multiplies, its on-chip line buffers' accesses (per input
    pixel one word of C_in activations written; per output pixel s K words read, the window's
    next s columns) and its DRAM bytes (input, output, spills and weights read per frame)."""
    out = []

    def add(action, what, count, unit, pj_each):
        if round(count):
            out.append({"block": "lent", "action": action, "what": what,
                        "count": round(count), "unit": unit, "pj_each": pj_each})

    of = f"the lent network ({frames:.4g} of its frames)"
    add("mac", f"{of}: int8 multiply-accumulates", frames * lent.macs_per_frame, "MAC",
        table.mac_int8_pj)
    add("multiply", f"{of}: requantising multiplies",
        frames * sum(lay.items * lay.layer.channels_out for lay in lent.layers),
        "32-bit multiply", table.mult32_pj)
    for lay in lent.layers:
        if not lay.on_chip:
            continue
        bank = lay.buffer_bits // lay.rows
        read = table.sram_read_pj_per_bit(bank)
        word = 8 * lay.layer.channels_in
        add("sram_read", f"{of}: layer {lay.index} line buffer ({bank} bits a bank)",
            frames * lay.items * lay.layer.stride * lay.layer.kernel * word, "bit", read)
        add("sram_write", f"{of}: layer {lay.index} line buffer ({bank} bits a bank)",
            frames * lay.in_shape[0] * lay.in_shape[1] * word, "bit", read * table.write_factor)
    for what, nbytes in lent.bytes_per_frame.items():
        add("dram", f"{of}: DRAM {what}", frames * nbytes * 8, "bit", table.dram_pj_per_bit)
    return out


def energy_report(plan: ChipPlan, stats: dict, fps: float | None, fps_basis: str,
                  table: EnergyTable | None = None) -> dict:
    """The ``energy`` section of a cycle report: every item, the frame's total by block and by
    action (uJ), and the average power (mW) at ``fps``."""
    table = table or energy_table()
    return _totals(energy_items(plan, table, stats), table, fps, fps_basis)


def frame_cycles_at(plan: ChipPlan, fps: float) -> dict[str, int]:
    """Each clock domain's cycles in one frame period at ``fps``: round(f / fps) (the clocks
    run all the time, so a chip delivering ``fps`` frames a second spends that many cycles a
    frame)."""
    return {name: round(d.freq_hz / fps) for name, d in plan.domains.items()}


def analytic_stats(plan: ChipPlan, frame_cycles: dict[str, int]) -> dict:
    """The two counts :func:`energy_items` takes from a run, from the plan instead: the bits
    each FIFO moves (its beats a frame x its width: what a run that completes counts, exactly)
    and each domain's clock cycles a frame (``frame_cycles``: :func:`frame_cycles_at`, or a
    one-frame run's span), over the plan's ``frames``."""
    frames = plan.frames
    return {"fifos": {f.name: {"bits_transferred": frames * f.beats * f.width_bits}
                      for f in plan.fifos},
            "cycles": {d: frames * c for d, c in frame_cycles.items()}}


def estimate_energy(plan: ChipPlan, table: EnergyTable, fps: float, fps_basis: str = "",
                    frame_cycles: dict[str, int] | None = None) -> dict:
    """The energy a frame and the power at ``fps`` without a run: :func:`energy_items` of the
    same table, every count from the plan (:func:`analytic_stats`). MACs, multiplies, SRAM,
    datapath, FIFO and DRAM counts are the ones a cycle run counts, exactly; the clocks' are
    each domain's cycles in a frame period at ``fps`` (:func:`frame_cycles_at`) unless
    ``frame_cycles`` gives them (a one-frame run counts its span instead: first input pixel to
    last output word); the lent network's frames follow from the NNA's cycles. The keys are
    the run's (:func:`energy_report`) plus ``analytic``: what the clock counts are."""
    cycles = frame_cycles if frame_cycles is not None else frame_cycles_at(plan, fps)
    items = energy_items(plan, table, analytic_stats(plan, cycles))
    out = _totals(items, table, fps, fps_basis)
    out["analytic"] = ("every count from the chip plan; the clocks' cycles a frame: "
                       + ("as given" if frame_cycles is not None
                          else f"a frame period at {fps:g} fps (f / fps per domain)"))
    return out


def _totals(items: list[dict], table: EnergyTable, fps: float | None, fps_basis: str) -> dict:
    """The energy section from its items: totals by block and by action, power at ``fps``."""
    total_pj = sum(it["count"] * it["pj_each"] for it in items)
    by_block: dict[str, float] = {}
    by_action: dict[str, float] = {}
    for it in items:
        pj = it["count"] * it["pj_each"]
        by_block[it["block"]] = by_block.get(it["block"], 0.0) + pj
        by_action[it["action"]] = by_action.get(it["action"], 0.0) + pj
    return {
        "table": {"node": table.node, "source": table.source},
        "per_frame_uj": {
            "total": round(total_pj / 1e6, 6),
            "by_block": {k: round(v / 1e6, 6) for k, v in sorted(by_block.items())},
            "by_action": {k: round(v / 1e6, 6) for k, v in sorted(by_action.items())},
        },
        "power_mw": round(total_pj * 1e-12 * fps * 1e3, 6) if fps else None,
        "power_at_fps": fps,
        "fps_basis": fps_basis,
        "items": items,
    }
