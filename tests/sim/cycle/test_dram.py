"""The DRAM channel (dram.model = "tdm"): the reads and the write-back in exact cycles by hand,
both engines alike, the report's figures and the configurations it refuses; the watchdog and
the automatic cycle budget allow the channel's latency."""

from __future__ import annotations

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import DeadlockError
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import run_readable
from stereosim.sim.cycle.rules import (
    burst_last,
    burst_of,
    dram_read_ready_fs,
    dram_slot,
    dram_write_done_fs,
    first_edge_at,
)

H, W = 8, 40
CHIP = {"clocks.nna_mhz": 400, "clocks.sva_mhz": 400, "sva.disparities": 16,
        "nna.descriptor": "census", "dram.model": "tdm"}


def _stream(n, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (n, H, W + 3), dtype=np.uint8)
    return base[:, :, :W].copy(), base[:, :, 3:].copy()


def _plan(frames=1, **over):
    return build_plan(load_config(overrides={**CHIP, **over}), (H, W), frames)


def test_the_slot_rule_serves_each_client_in_its_own_slots_in_order():
    # rounds of 5 slots of 10 fs; a client owning offsets 2 and 3
    assert dram_slot(0, -1, 10, 5, 2, 2) == 2
    assert dram_slot(21, -1, 10, 5, 2, 2) == 3  # slot 3 starts at 30 >= 21
    assert dram_slot(31, -1, 10, 5, 2, 2) == 7  # past its slots: the next round's first
    assert dram_slot(0, 3, 10, 5, 2, 2) == 7  # after its previous burst's slot
    assert dram_slot(20, -1, 10, 5, 2, 2) == 2  # a slot starting at the request serves it
    # bursts restart at each frame: a frame of 10 items in bursts of 4 has bursts of 4, 4, 2
    assert [burst_of(k, 10, 4)[0] for k in range(12)] == [0] * 4 + [1] * 4 + [2] * 2 + [3] * 2
    assert [burst_last(b, 10, 4) for b in range(4)] == [3, 7, 9, 13]


def test_a_slow_channel_paces_the_reads_a_round_per_burst():
    """Bursts of 16 pixels at 0.01 GB/s: a slot is 1.6 us, 640 NNA cycles, far longer than a
    burst's 16 pushes. With one burst of prefetch, burst b is requested when the last pixel of
    burst b - 1 leaves, which is before the next round starts: burst b takes round b, its
    pixels leave from the first edge at or after (R b + 2) slot + latency, one per cycle."""
    plan = _plan(**{"dram.gbps": 0.01, "dram.burst_bytes": 16, "dram.read_prefetch_bursts": 1,
                    "dram.latency_ns": 30})
    d = plan.dram
    per = plan.domains["nna"].period_fs
    assert d.slot_fs == 1_600_000_000 and d.round_slots == 2 + 2  # reads, write-back
    left, right = _stream(1)
    res = run_compiled(plan, left, right)
    bursts = H * W // 16
    ready = [first_edge_at(dram_read_ready_fs(d.round_slots * b, d.slot_fs, d.latency_fs), per)
             for b in range(bursts)]
    # the first pixel leaves with the first burst; the last, 15 cycles after the last burst
    assert res.frame_times[0, 0] == ready[0] * per
    mem = res.stats["blocks"]["memory_left"]
    assert mem["busy"] + mem["starved"] + mem["blocked"] == ready[-1] + 15 + 1
    assert mem["blocked"] == 0 and mem["busy"] == H * W
    # every cycle before a burst is in was a wait on the channel
    waits = ready[0] + sum(ready[b] - (ready[b - 1] + 16) for b in range(1, bursts))
    assert res.stats["dram"]["read_stall_cycles"] == [waits, waits]
    assert mem["starved"] == waits
    assert res.report["dram"]["stall_cycles"]["memory_left"] == waits
    # the read slots bound the frame rate: a round per burst
    assert res.report["dram"]["read_bound_fps"] == round(1e15 / (bursts * d.round_fs), 3)
    assert res.report["throughput"]["bottleneck"] in ("memory_left", "memory_right")


def _changes(trace, path, per):
    """(cycles, values) of a traced signal's changes."""
    i = next(k for k, sig in enumerate(trace.signals) if sig.path == path)
    m = trace.ids == i
    return trace.times_fs[m] // per, trace.values[m]


def test_a_full_write_buffer_blocks_the_sink_until_its_oldest_burst_is_written():
    """Write-back bursts of 8 bytes (7 words of 9 bits) at 0.05 GB/s with a one-burst buffer:
    burst u is requested at the pop of its last word and written in the next write slot
    (rules.dram_slot); word j of burst u >= 1 waits for burst u - 1 to be written -- the first
    sink edge at or after that slot's end. Replayed by hand from the traced pops."""
    plan = _plan(**{"dram.gbps": 0.05, "dram.burst_bytes": 8, "dram.write_buffer_bursts": 1,
                    "dram.latency_ns": 0})
    d, wb = plan.dram, plan.dram.write_back
    per = plan.domains["sva"].period_fs
    left, right = _stream(1)
    end = run_compiled(plan, left, right).report["cycles"]["last_output"]["sva"]
    res = run_compiled(plan, left, right, window=(0, (end + 2) * per))
    cyc, count = _changes(res.trace, "top.sink.count", per)
    pops = cyc[np.argsort(count)]  # word j popped in cycle pops[j]
    assert len(pops) == H * W and d.write_words == 64 // plan.word_bits == 7
    s_cyc, s_val = _changes(res.trace, "top.sink.status", per)
    slot, free = -1, []
    for u in range(-(-H * W // d.write_words)):
        last = burst_last(u, H * W, d.write_words)
        slot = dram_slot(int(pops[last]) * per, slot, d.slot_fs, d.round_slots, wb.first,
                         wb.count)
        free.append(first_edge_at(dram_write_done_fs(slot, d.slot_fs), per))
    waited = 0
    for u in range(1, len(free)):
        first = u * d.write_words
        assert pops[first] >= free[u - 1]  # never before the buffer has room
        # blocked right before (the word was there): popped the cycle the room came
        k = np.searchsorted(s_cyc, free[u - 1] - 1, side="right") - 1
        if s_val[k] == 3:
            assert pops[first] == free[u - 1]
            waited += 1
    assert waited > 10  # the channel, not the SVA, paced most bursts
    sink = res.stats["blocks"]["sink"]
    assert sink["blocked"] == res.stats["dram"]["write_stall_cycles"] > 0
    assert res.report["dram"]["stall_cycles"]["sink"] == sink["blocked"]
    assert res.report["cycles"]["last_output"]["sva"] == pops[-1]


def test_a_larger_write_buffer_absorbs_the_channel_and_the_sink_never_waits():
    plan = _plan(**{"dram.gbps": 0.05, "dram.burst_bytes": 8, "dram.write_buffer_bursts": 4096,
                    "dram.latency_ns": 0})
    left, right = _stream(1)
    res = run_compiled(plan, left, right)
    assert res.stats["blocks"]["sink"]["blocked"] == 0
    assert res.stats["dram"]["write_stall_cycles"] == 0


@pytest.mark.parametrize("over, stall", [
    ({"dram.gbps": 0.2}, None),
    ({"dram.gbps": 0.05, "dram.burst_bytes": 8, "dram.read_prefetch_bursts": 1,
      "dram.write_buffer_bursts": 1}, (3, 1)),
    ({"dram.gbps": 0.2, "dram.spill": "descriptors", "nna.lent_submodules": 2,
      "nna.lent_network": "LENT", "dram.burst_bytes": 16, "nna.stereo_submodules": 4,
      "fifo.nna_to_merge_depth": 8}, None),
    ({"dram.gbps": 2, "source.kind": "camera", "source.frame_buffers": 2,
      "source.on_overflow": "drop_frame", "clocks.camera_mhz": 400, "source.camera_vblank": 4,
      "source.camera_hblank": 60, "dram.write_buffer_bursts": 1, "dram.latency_ns": 2000}, None),
    ({"dram.gbps": 0.5, "source.kind": "camera", "dram.write_buffer_bursts": 1,
      "clocks.camera_mhz": 50}, (2, 0)),
])
def test_the_engines_agree_through_the_channel(over, stall, engines_agree, tmp_path,
                                               lent_toml):
    """Words of every frame, statistics, report and a trace window over a frame boundary."""
    if over.get("nna.lent_network") == "LENT":  # about 0.05 GB/s: 1348 bytes at 37,000 fps
        over = {**over, "nna.lent_network": lent_toml(tmp_path / "n.toml", [(3, 1, 4, 1)],
                                                      fps=37000)}
    plan = _plan(3, **over)
    p = plan.domains["sva"].period_fs
    slow, _ = engines_agree(plan, *_stream(3, seed=7), sink_stall=stall,
                            window=(1000 * p, 4000 * p))
    assert slow.trace is not None


def test_the_report_counts_every_clients_bytes_and_the_utilisation(tmp_path, lent_toml):
    net = lent_toml(tmp_path / "n.toml", [(3, 1, 4, 1)], fps=74000)  # 1348 B a frame: 0.1 GB/s
    plan = _plan(2, **{"dram.gbps": 0.3, "dram.spill": "float32", "nna.lent_submodules": 2,
                       "nna.lent_network": net})
    left, right = _stream(2)
    rep = run_compiled(plan, left, right).report
    dram = rep["dram"]
    n = H * W
    span_s = rep["cycles"]["last_output"]["time_ms"] / 1e3
    c = dram["clients"]
    assert c["read"]["bytes"] == 2 * 2 * n
    assert c["write_back"]["bytes"] == 2 * -(-n * plan.word_bits // 8)
    assert c["spill"]["bytes"] == 2 * n * 2 * 2 * plan.descriptor_bits * 4
    assert plan.lent.gbps == pytest.approx(1348 * 74000 / 1e9)
    assert c["lent"]["gbps"] == pytest.approx(plan.lent.gbps, rel=1e-3)
    total = sum(v["bytes"] for v in c.values())
    assert dram["utilisation"] == pytest.approx(total / (0.3e9 * span_s), rel=1e-4)
    slots = sum(v["slots_per_round"] for v in c.values())
    assert slots == dram["round_slots"]
    # the spill's slots carry its bytes in step with the reads: a round per read burst
    assert c["spill"]["slots_per_round"] * plan.dram.burst_bytes >= \
        plan.dram.read_pixels * 2 * 2 * plan.descriptor_bits * 4
    # energy prices the spill and the lent network
    whats = [it["what"] for it in rep["energy"]["items"]]
    assert any("spilled" in w for w in whats) and any("lent network" in w for w in whats)


@pytest.mark.parametrize("over, needle", [
    ({"dram.model": "none", "dram.spill": "descriptors"}, "dram.spill needs the DRAM channel"),
    ({"dram.lent_gbps": 1.0}, "dram.lent_gbps is retired: .* nna.lent_network"),
    ({"nna.lent_mac_load": 0.5}, "nna.lent_mac_load is retired: .* nna.lent_network"),
    ({"nna.lent_submodules": 2}, "nna.lent_network names none"),
    ({"nna.lent_submodules": 2, "nna.lent_network": "LENT"},
     "needs 0.135 GB/s of DRAM, not below the channel's dram.gbps=0.1"),
    ({"nna.lent_submodules": 9}, "exceeds nna.submodules"),
    ({"source.kind": "camera", "source.frame_buffers": 2, "dram.gbps": 0.01},
     "per camera into the frame buffers"),
])
def test_impossible_channels_are_refused_in_one_line(over, needle, tmp_path, lent_toml):
    if over.get("nna.lent_network") == "LENT":  # 1348 bytes a frame at 100,000 fps
        over = {**over, "dram.gbps": 0.1,
                "nna.lent_network": lent_toml(tmp_path / "n.toml", [(3, 1, 4, 1)], fps=1e5)}
    with pytest.raises(ConfigError, match=needle) as err:
        _plan(**over)
    assert "\n" not in str(err.value)


# ---- the watchdog and the automatic budget allow the channel's latency -----------------------


def test_the_longest_legal_latency_completes_under_the_automatic_limits():
    """``dram.latency_ns = 1e6`` (the largest the key takes): a millisecond before the first
    pixel, and the read window of 8 bursts per millisecond after it, is neither a deadlock
    (the watchdog allows the channel's longest wait on top of sim.watchdog_cycles) nor past
    the automatic cycle budget (which counts the latency-bound read rate)."""
    plan = _plan(**{"dram.latency_ns": 1e6})
    d = plan.dram
    assert d.longest_wait_fs == 2 * d.round_fs + 10**12
    assert plan.dram_wait_cycles == -(-d.longest_wait_fs // plan.p_max_fs)
    assert plan.watchdog_fs == (200_000 + plan.dram_wait_cycles) * plan.p_max_fs
    assert plan.watchdog_fs > d.longest_wait_fs
    left, right = _stream(1)
    res = run_compiled(plan, left, right)
    # the first burst's data after a millisecond; 320 pixels in bursts of 64, all requested
    # at once (8 bursts of prefetch): one latency in all
    assert 1.0 < res.report["latency"]["frame_ms"] < 1.01
    budget_fs = min(n * plan.domains[k].period_fs for k, n in plan.budget.items())
    assert budget_fs > 10 * res.stats["end_time_fs"]  # generous, as without the channel


def test_a_window_of_a_few_periods_still_waits_for_the_channel_on_both_engines(engines_agree):
    """sim.watchdog_cycles = 10 (25 ns) and a 2 us latency: the wait for the first burst is not
    a deadlock, on either engine."""
    plan = _plan(**{"dram.latency_ns": 2000, "sim.watchdog_cycles": 10})
    assert plan.watchdog_cycles == 10 + plan.dram_wait_cycles > 800
    slow, _ = engines_agree(plan, *_stream(1))
    assert slow.report["latency"]["first_output_us"] > 2


def test_a_watchdog_stop_names_the_limit_and_how_to_raise_it():
    plan = _plan(**{"dram.latency_ns": 2000, "sim.watchdog_cycles": 10})
    never = (1 << 40, (1 << 40) - 1)  # a sink that never pops
    left, right = _stream(1)
    with pytest.raises(DeadlockError) as fast:
        run_compiled(plan, left, right, sink_stall=never)
    with pytest.raises(DeadlockError) as slow:
        run_readable(plan, left, right, sink_stall=never)
    assert str(fast.value) == str(slow.value)
    assert (f"the watchdog allows sim.watchdog_cycles = 10 periods (+ {plan.dram_wait_cycles} "
            "for the DRAM's longest wait)") in str(fast.value)
    assert "raise sim.watchdog_cycles" in str(fast.value)
    no_dram = _plan(**{"dram.model": "none", "sim.watchdog_cycles": 10})
    assert no_dram.dram_wait_cycles == 0 and no_dram.watchdog_fs == 10 * no_dram.p_max_fs
    assert "sim.watchdog_cycles = 10 periods" in no_dram.watchdog_remedy
