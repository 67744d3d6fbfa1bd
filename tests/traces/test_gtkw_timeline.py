"""The GTKWave save file and the Perfetto timeline."""

import json

import numpy as np
import pytest
import vcdvcd

from sim.errors import ConfigError
from traces.gtkw import gtkw_text, write_gtkw
from traces.log import Clock, Signal, TraceLog, changes_of
from traces.synthetic import synthetic_log
from traces.timeline import STATUS_NAMES, timeline_bytes, timeline_events, write_timeline
from traces.vcd import write_vcd

# ---- GTKWave ----------------------------------------------------------------------------------


def _groups(text: str) -> list[tuple[str, list[tuple[str, str]]]]:
    """Parse the save file's groups: [(name, [(flag, trace), ...])], checking the markers."""
    lines = text.splitlines()
    body = lines[lines.index(next(ln for ln in lines if ln == "@800200")):]
    groups, k = [], 0
    while k < len(body):
        assert body[k] == "@800200" and body[k + 1].startswith("-")
        name, k, members = body[k + 1][1:], k + 2, []
        while body[k] != "@1000200":
            members.append((body[k], body[k + 1]))
            k += 2
        assert body[k + 1] == f"-{name}"
        groups.append((name, members))
        k += 2
    return groups


def test_gtkw_groups_reference_every_vcd_variable(tmp_path):
    log = synthetic_log(200, seed=5)
    write_vcd(tmp_path / "t.vcd", log)
    write_gtkw(tmp_path / "t.gtkw", log, "t.vcd")
    text = (tmp_path / "t.gtkw").read_text()
    assert '[dumpfile] "t.vcd"' in text.splitlines()
    assert f"[timestart] {log.start_fs}" in text.splitlines()
    groups = _groups(text)
    assert [g for g, _ in groups] == ["clocks", "cameras", "nna", "fifo", "sva"]
    names_in_vcd = set(vcdvcd.VCDVCD(str(tmp_path / "t.vcd"), only_sigs=True).signals)
    traces = [t for _, members in groups for _, t in members]
    assert sorted(traces) == sorted(names_in_vcd)
    widths = {s.path: s.width for s in log.signals} | {f"clocks.{c.name}": 1 for c in log.clocks}
    for _, members in groups:
        for flag, trace in members:
            path = trace.split("[")[0]
            assert flag == ("@28" if widths[path] == 1 else "@22")
            if widths[path] > 1:
                assert trace.endswith(f"[{widths[path] - 1}:0]")


def test_gtkw_is_deterministic_and_refuses_quotes():
    log = synthetic_log(50)
    assert gtkw_text(log, "a.vcd") == gtkw_text(synthetic_log(50), "a.vcd")
    with pytest.raises(ConfigError, match="without quotes"):
        gtkw_text(log, 'a".vcd')


# ---- Perfetto timeline ------------------------------------------------------------------------


def _status_log():
    # block a (nna, period 10): idle, busy from 20, starved from 40 (repeat at 50 ignored)
    # block b (sva, period 4): blocked from the start; FIFO occupancy 0 -> 3 -> 1
    return TraceLog(
        signals=[Signal("top.nna.a.status", 2, "nna"), Signal("top.sva.b.status", 2, "sva"),
                 Signal("top.fifo.a_to_b.occupancy", 3, "sva"), Signal("top.nna.a.row", 8, "nna")],
        clocks=[Clock("nna", 10, 0), Clock("sva", 4, 2)],
        start_fs=0, end_fs=100,
        initial=np.array([0, 3, 0, 0], np.uint64),
        times_fs=np.array([20, 30, 40, 50, 70], np.int64),
        ids=np.array([0, 2, 0, 0, 2], np.int32),
        values=np.array([1, 3, 2, 2, 1], np.uint64),
    )


def test_timeline_spans_and_counters_by_hand():
    events = timeline_events(_status_log())
    spans = [(e["name"], e["ts"] * 1e9, e["dur"] * 1e9, e["pid"], e["tid"], e["args"]["cycles"])
             for e in events if e["ph"] == "X"]
    assert [(n, round(t), round(d), p, c) for n, t, d, p, _, c in spans] == [
        ("idle", 0, 20, 1, 2), ("blocked", 0, 100, 2, 25), ("busy", 20, 20, 1, 2),
        ("starved", 40, 60, 1, 6)]
    counters = [(round(e["ts"] * 1e9), e["args"]["occupancy"]) for e in events if e["ph"] == "C"]
    assert counters == [(0, 0), (30, 3), (70, 1), (100, 1)]
    names = {(e["pid"], e["tid"]): e["args"]["name"] for e in events
             if e["ph"] == "M" and e["name"] == "thread_name"}
    procs = {e["pid"]: e["args"]["name"] for e in events
             if e["ph"] == "M" and e["name"] == "process_name"}
    assert names == {(1, 1): "a", (2, 1): "b"} and procs == {1: "nna", 2: "sva", 3: "fifo"}


def test_timeline_of_a_chip_like_log(tmp_path):
    log = synthetic_log(3000, seed=6)
    write_timeline(tmp_path / "t.json", log)
    doc = json.loads((tmp_path / "t.json").read_text())
    assert doc["displayTimeUnit"] == "ns"
    events = doc["traceEvents"]
    kinds = [e["ph"] for e in events]
    assert kinds == sorted(kinds, key=lambda k: k != "M")  # metadata first
    timed = [e for e in events if e["ph"] != "M"]
    assert [e["ts"] for e in timed] == sorted(e["ts"] for e in timed)
    tracks: dict = {}
    for e in timed:
        if e["ph"] == "X":
            assert e["name"] in STATUS_NAMES and e["dur"] > 0
            tracks.setdefault((e["pid"], e["tid"]), []).append(e)
    statuses = [s for s in log.signals if s.path.endswith(".status")]
    assert len(tracks) == len(statuses)
    end_us = log.end_fs / 1e9
    for spans in tracks.values():
        assert spans[0]["ts"] == log.start_fs / 1e9
        for a, b in zip(spans, spans[1:]):
            assert a["ts"] + a["dur"] == pytest.approx(b["ts"], abs=1e-9)  # no gap, no overlap
            assert a["name"] != b["name"]
        assert spans[-1]["ts"] + spans[-1]["dur"] == pytest.approx(end_us, abs=1e-9)
    # busy cycles of a block from the spans equal those counted from the log
    i = next(k for k, s in enumerate(log.signals) if s.path == "top.sva.wta.status")
    clk = next(c for c in log.clocks if c.name == "sva")
    t, v = changes_of(log, i)
    ends = np.append(t[1:], log.end_fs)
    busy_edges = sum(len(range(-(-(a - clk.phase_fs) // clk.period_fs),
                               -(-(b - clk.phase_fs) // clk.period_fs)))
                     for a, b, s in zip(t.tolist(), ends.tolist(), v.tolist()) if s == 1)
    wta = next(e["args"]["name"] for e in events if e["ph"] == "M" and e["name"] == "thread_name"
               and e["args"]["name"] == "wta")
    pid_tid = next((e["pid"], e["tid"]) for e in events
                   if e["ph"] == "M" and e["args"].get("name") == wta)
    got = sum(e["args"]["cycles"] for e in tracks[pid_tid] if e["name"] == "busy")
    assert got == busy_edges > 0


def test_timeline_is_byte_deterministic():
    assert timeline_bytes(synthetic_log(500, seed=7)) == timeline_bytes(synthetic_log(500, seed=7))


def test_timeline_refuses_an_unknown_status():
    log = _status_log()
    log.values[0] = 1
    log.signals[0] = Signal("top.nna.a.status", 3, "nna")
    log.values[2] = 5
    with pytest.raises(ConfigError, match="'top.nna.a.status' is 5 at 40 fs"):
        timeline_events(log)
