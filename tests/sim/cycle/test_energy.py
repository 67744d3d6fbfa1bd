"""Energy (sim/cycle/energy.py): every action of a frame times the table's energy per action;
the report's breakdowns add up to its total, the counts are the chip's, and a table with a
mistake is one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.sim.api import run, run_stream
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.energy import (
    DEFAULT_TABLE,
    energy_report,
    energy_table,
    estimate_energy,
    popcount_bit_adds,
)
from stereosim.sim.cycle.estimate import estimate, one_frame_cycles
from stereosim.sim.cycle.plan import build_plan

SAME = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16}


def _run(over, shape=(8, 40), frames=1):
    plan = build_plan(load_config(overrides={**SAME, **over}), shape, frames)
    rng = np.random.default_rng(0)
    left = rng.integers(0, 256, (frames, *shape), dtype=np.uint8)
    res = run_compiled(plan, left, np.roll(left, -2, axis=2))
    return plan, res


def test_energy_is_the_sum_of_count_times_table_entry():
    plan, res = _run({"nna.descriptor": "cnn"})
    e = res.report["energy"]
    total = sum(it["count"] * it["pj_each"] for it in e["items"]) / 1e6
    assert e["per_frame_uj"]["total"] == pytest.approx(total, abs=1e-6)
    assert sum(e["per_frame_uj"]["by_block"].values()) == pytest.approx(total, abs=1e-5)
    assert sum(e["per_frame_uj"]["by_action"].values()) == pytest.approx(total, abs=1e-5)
    # the power at the frame rate it names
    assert e["power_mw"] == pytest.approx(total * 1e-6 * e["power_at_fps"] * 1e3, rel=1e-6)


def test_the_counts_and_unit_energies_are_the_chips_and_the_tables():
    """By hand, for an 8x40 CNN frame at D = 16: 2 cameras x 320 descriptors x 9 x 9 x 32 MACs
    at 0.3 pJ; 32 requantising multiplies a descriptor at 3.1 pJ; the Hamming datapath's 32
    XOR bits and a 32-bit popcount tree (16 1-bit + 8 2-bit + 4 3-bit + 2 4-bit + 1 5-bit =
    57 bit-adds) per pixel and disparity at 0.1 / 32 pJ a bit; both views read from DRAM, a
    byte a pixel, and 9-bit words written back, at 20.3 pJ a bit; each NNA -> SVA FIFO moves
    a 40-bit beat a pixel (the descriptor and the pixel the adaptive P2 compares)."""
    plan, res = _run({"nna.descriptor": "cnn"})
    items = {(it["block"], it["action"], it["what"]): it for it in res.report["energy"]["items"]}
    n = 8 * 40
    mac = items["nna", "mac", "int8 multiply-accumulates, both cameras"]
    assert (mac["count"], mac["pj_each"]) == (2 * n * 81 * 32, 0.3)
    mul = items["nna", "multiply", "requantising multiplies, both cameras"]
    assert (mul["count"], mul["pj_each"]) == (2 * n * 32, 3.1)
    assert popcount_bit_adds(32) == 57
    ham = items["sva", "logic", "hamming datapath"]
    assert (ham["count"], ham["pj_each"]) == (n * 16 * (32 + 57), 0.1 / 32)
    read = items["dram", "dram", "both views read by the memory sources"]
    assert (read["count"], read["pj_each"]) == (2 * n * 8, 20.3)
    back = items["dram", "dram", "disparity words written back"]
    assert back["count"] == n * plan.word_bits == n * 9
    fifo = items["fifos", "fifo", "nna_left_to_sva: bits pushed and popped"]
    assert fifo["count"] == 2 * n * (32 + 8)
    # an SRAM bank of 64 kbit or less costs the table's first figure a bit, 8 KB: 10 pJ / 64
    table = energy_table()
    assert table.sram_read_pj_per_bit(1000) == 10 / 64
    assert table.sram_read_pj_per_bit(32 * 8 * 1024) == 20 / 64
    assert table.sram_read_pj_per_bit(1 << 30) == 100 / 64
    mid = table.sram_read_pj_per_bit(128 * 1024)  # 128 kbit, log-half way from 64 to 256
    assert mid == pytest.approx((10 / 64 + 20 / 64) / 2)


def test_a_stream_takes_its_fifo_traffic_and_cycles_per_frame_and_its_measured_rate():
    plan, res = _run({"nna.descriptor": "census"}, frames=3)
    e = res.report["energy"]
    one = _run({"nna.descriptor": "census"}, frames=1)[1].report["energy"]
    fifo3 = [it for it in e["items"] if it["action"] == "fifo"]
    fifo1 = [it for it in one["items"] if it["action"] == "fifo"]
    assert [it["count"] for it in fifo3] == [it["count"] for it in fifo1]
    assert e["fps_basis"] == "sustained (measured)"
    assert e["power_at_fps"] == res.report["stream"]["sustained_fps"]


def test_a_custom_table_and_its_mistakes(tmp_path):
    plan, res = _run({"nna.descriptor": "census"})
    text = DEFAULT_TABLE.read_text()
    doubled = tmp_path / "node.toml"
    doubled.write_text(text.replace("pj_per_bit = 20.3", "pj_per_bit = 40.6"))
    e1 = res.report["energy"]
    e2 = energy_report(plan, res.stats, e1["power_at_fps"], e1["fps_basis"],
                       energy_table(doubled))
    assert math.isclose(e2["per_frame_uj"]["by_block"]["dram"],
                        2 * e1["per_frame_uj"]["by_block"]["dram"], rel_tol=1e-9)
    for bad, match in [
        (text + "\n[extra]\nx = 1\n", "unknown section \\[extra\\]"),
        (text.replace("mac_int8_pj = 0.3", "mac_int8_pj = -1"), "logic.mac_int8_pj must be"),
        (text.replace("mac_int8_pj = 0.3", "mac_int8_pj = nan"), "logic.mac_int8_pj must be"),
        (text.replace("mac_int8_pj = 0.3", "mac_pj = 0.3"), "unknown key logic.mac_pj"),
        (text.replace("read_kbit = [64.0, 256.0, 8192.0]", "read_kbit = [64.0, 8.0, 8192.0]"),
         "sram.read_kbit must increase"),
        ("not toml [", "not valid TOML"),
    ]:
        f = tmp_path / "bad.toml"
        f.write_text(bad)
        with pytest.raises(ConfigError, match=match):
            energy_table(f)


# the estimate against the cycle model: a 20x112 CNN frame from memory, whose latency the
# estimate gives to the cycle (tests/sim/cycle/test_estimate.py), priced with a table whose
# clocks cost
ESTIMATED = {"sva.disparities": 32, "nna.descriptor": "cnn", "sva.median": 3}


def _clocked_table(tmp_path):
    path = tmp_path / "clocked.toml"
    path.write_text(DEFAULT_TABLE.read_text()
                    .replace("nna_pj_per_cycle = 0.0", "nna_pj_per_cycle = 5.0")
                    .replace("sva_pj_per_cycle = 0.0", "sva_pj_per_cycle = 7.0"))
    return path, energy_table(path)


def _estimated_pair(shape):
    left = np.random.default_rng(7).integers(0, 256, shape, dtype=np.uint8)
    return left, np.roll(left, -5, axis=1)


def test_the_estimates_energy_is_a_one_frame_cycle_runs_item_for_item(tmp_path):
    """Every count the estimate prices comes from the plan; given the clocks' cycles of a
    one-frame run (its span, from the estimate's own last output word), every item -- clocks
    included -- equals the run's exactly."""
    path, table = _clocked_table(tmp_path)
    shape = (20, 112)
    cfg = load_config(overrides=ESTIMATED)
    rep = run(*_estimated_pair(shape), config=cfg, energy=path).report
    est = estimate(cfg, shape, table)
    plan = build_plan(cfg, shape)
    cycles = one_frame_cycles(plan, est["latency"]["last_output_sva_cycle"])
    assert cycles == rep["cycles"]["total"]
    one = estimate_energy(plan, table, rep["energy"]["power_at_fps"], frame_cycles=cycles)
    assert one["items"] == rep["energy"]["items"]
    assert one["per_frame_uj"] == rep["energy"]["per_frame_uj"]
    assert one["power_mw"] == rep["energy"]["power_mw"]


def test_the_estimates_energy_at_its_rate_is_a_streams(tmp_path):
    """The estimate's own figure counts the clocks over a frame period at the rate the chip
    delivers (f / fps cycles a domain), every other item as the run does (exactly). A stream
    of N frames counts its span over N frames: the first frame's latency and N - 1 frame
    periods, that mix of the estimate's two clock counts within a cycle a frame."""
    path, table = _clocked_table(tmp_path)
    shape = (20, 112)
    cfg = load_config(overrides=ESTIMATED)
    pair = _estimated_pair(shape)
    rep = run(*pair, config=cfg, energy=path).report
    est = estimate(cfg, shape, table)
    fps = est["throughput"]["fps_delivered"]
    energy = est["energy"]
    assert energy["power_at_fps"] == fps
    assert energy["power_mw"] == pytest.approx(energy["per_frame_uj"]["total"] * fps * 1e-3,
                                               rel=1e-6)

    def split(items):
        clocks = {it["what"]: it["count"] for it in items if it["action"] == "clock"}
        return [it for it in items if it["action"] != "clock"], clocks

    others, clocks = split(energy["items"])
    run_others, _ = split(rep["energy"]["items"])
    assert others == run_others
    plan = build_plan(cfg, shape)
    at_rate = {d: round(dom.freq_hz / fps) for d, dom in plan.domains.items()}
    assert clocks == {f"{d} domain cycles": c for d, c in at_rate.items()}
    frames = 8
    stream = run_stream([pair] * frames, config=cfg, energy=path).report
    assert stream["stream"]["sustained_fps"] == pytest.approx(fps, rel=1e-4)
    _, stream_clocks = split(stream["energy"]["items"])
    first = one_frame_cycles(plan, est["latency"]["last_output_sva_cycle"])
    for d in plan.domains:
        mix = (first[d] + (frames - 1) * at_rate[d]) / frames
        assert stream_clocks[f"{d} domain cycles"] == pytest.approx(mix, abs=frames)


def test_a_users_energy_table_prices_the_power_section_too(tmp_path):
    """``energy=FILE`` re-prices the report's ``energy`` and its ``power`` alike: the power
    section's dynamic energy a frame is the user's table's items, for a frame and a stream."""
    path, _ = _clocked_table(tmp_path)
    cfg = load_config(overrides=ESTIMATED)
    pair = _estimated_pair((20, 112))
    for rep in (run(*pair, config=cfg, energy=path).report,
                run_stream([pair] * 2, config=cfg, energy=path).report):
        items = rep["energy"]["items"]
        assert any(it["action"] == "clock" and it["pj_each"] > 0 for it in items)
        assert rep["power"]["per_frame_pj"]["dynamic"] == pytest.approx(
            sum(it["count"] * it["pj_each"] for it in items), rel=1e-12)
