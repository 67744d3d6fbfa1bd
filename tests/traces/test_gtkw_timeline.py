"""The GTKWave save file and the Perfetto timeline."""

import json

import numpy as np
import pytest
import vcdvcd

from stereosim.core.errors import ConfigError
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.gtkw import (
    STATUS_NAMES,
    aliases,
    gtkw_text,
    status_filter_text,
    write_gtkw,
    zoom_to_fit,
)
from stereosim.traces.log import Clock, Signal, TraceLog, changes_of, select, window
from stereosim.traces.timeline import STATUS_NAMES as TIMELINE_STATUS_NAMES
from stereosim.traces.timeline import timeline_bytes, timeline_events, write_timeline
from stereosim.traces.vcd import write_vcd

# ---- GTKWave ----------------------------------------------------------------------------------


def _groups(text: str) -> list[tuple[str, list[dict]]]:
    """Parse the save file's groups: [(label, [{flags, alias, name, filter}, ...])], checking
    that each group opens and closes with its label and every trace carries an alias."""
    flags, filters, groups, current = None, {}, [], None
    for line in text.splitlines():
        if line.startswith("@"):
            flags = int(line[1:], 16)
        elif line.startswith("^"):
            ident, path = line[1:].split(" ", 1)
            filters[ident] = path
            current_filter = path
        elif line.startswith("-"):
            if flags == 0x800200:
                current = (line[1:], [])
            else:
                assert flags == 0x1000200 and current[0] == line[1:]
                groups.append(current)
                current = None
        elif line.startswith("+{"):
            alias, name = line[2:].split("} ", 1)
            ftrans = bool(flags & 0x2000)
            current[1].append({"flags": flags, "alias": alias, "name": name,
                               "filter": current_filter if ftrans else None})
        else:
            assert line.startswith(("[", "*")), line
    assert current is None
    return groups


def test_gtkw_groups_reference_every_vcd_variable(tmp_path):
    log = synthetic_log(200, seed=5)
    write_vcd(tmp_path / "t.vcd", log)
    write_gtkw(tmp_path / "t.gtkw", log, "/any/where/t.vcd", "/any/where/t.status.txt")
    text = (tmp_path / "t.gtkw").read_text()
    lines = text.splitlines()
    assert '[dumpfile] "/any/where/t.vcd"' in lines
    assert f"[timestart] {log.start_fs}" in lines
    assert "[size] 1400 900" in lines and "[signals_width] 300" in lines
    groups = _groups(text)
    # one group per block: the scopes that own a status signal, and each FIFO
    assert [g for g, _ in groups] == [
        "clocks", "cameras/left", "nna/left/sub0", "nna/left/sub1", "cameras/right",
        "nna/right/sub0", "nna/right/sub1", "fifo/camera_left_to_nna",
        "fifo/camera_right_to_nna", "fifo/nna_left_to_sva", "fifo/nna_right_to_sva",
        "sva/cost", "sva/aggregation", "sva/sgm", "sva/wta", "sva/lr_check", "sva/output"]
    members = dict(groups)
    assert [t["alias"] for t in members["nna/left/sub0"]] == [
        "nna/left/sub0/status", "nna/left/sub0/line_buffer/fill",
        "nna/left/sub0/line_buffer/row", "nna/left/sub0/mac_array/phase",
        "nna/left/sub0/mac_array/valid", "nna/left/sub0/descriptor", "nna/left/sub0/col"]
    names_in_vcd = set(vcdvcd.VCDVCD(str(tmp_path / "t.vcd"), only_sigs=True).signals)
    traces = [t for _, ts in groups for t in ts]
    assert sorted(t["name"] for t in traces) == sorted(names_in_vcd)
    aliases = [t["alias"] for t in traces]
    assert len(set(aliases)) == len(aliases) == len(log.signals) + len(log.clocks)
    widths = {s.path: s.width for s in log.signals} | {f"clocks.{c.name}": 1 for c in log.clocks}
    BIN, DEC, HEX, RJUSTIFY, FTRANS = 0x8, 0x4, 0x2, 0x20, 0x2000
    for t in traces:
        path = t["name"].split("[")[0]
        assert t["alias"] == path.removeprefix("top.").replace(".", "/")
        leaf = path.rsplit(".", 1)[-1]
        if widths[path] == 1:
            want = BIN
        elif leaf in ("status", "fill", "row", "col", "occupancy", "phase", "pixels_sent",
                      "disparity"):
            want = DEC
        else:
            assert leaf in ("descriptor", "value", "path_cost"), leaf
            want = HEX
        if leaf == "status":
            want |= FTRANS
            assert t["filter"] == "/any/where/t.status.txt"
        else:
            assert t["filter"] is None
        assert t["flags"] == want | RJUSTIFY, (t, hex(t["flags"]))
        if widths[path] > 1:
            assert t["name"].endswith(f"[{widths[path] - 1}:0]")


def test_gtkw_zooms_to_the_window():
    # GTKWave shows 2**-zoom / 200 fs per pixel: a 1 us window over 1000 px is 1e6 fs / px,
    # zoom = -log2(2e8) = -27.5754..., rounded down to -27.576
    assert zoom_to_fit(0, 10**9, 1000) == -27.576
    assert zoom_to_fit(5 * 10**9, 6 * 10**9, 1000) == -27.576
    assert 2 ** 27.576 / 200 * 1000 >= 10**9  # the rounding keeps the whole window in view
    log = window(synthetic_log(400, seed=2), 2_000_000, 302_000_000)
    lines = gtkw_text(log, "t.vcd", "t.status.txt").splitlines()
    assert "[timestart] 2000000" in lines
    zoom = [ln for ln in lines if ln.startswith("*")]
    assert zoom == [f"*{zoom_to_fit(2_000_000, 302_000_000):.6f}" + " -1" * 27]


def test_gtkw_aliases_stay_unique():
    assert aliases(["top.a.x", "top.b.x", "clocks.sva"]) == ["a/x", "b/x", "clocks/sva"]
    # dropping top. would merge top.a.x with a.x: keep the full paths
    assert aliases(["top.a.x", "a.x"]) == ["top/a/x", "a/x"]


def test_status_filter_names_the_kernels_activities():
    assert STATUS_NAMES == TIMELINE_STATUS_NAMES
    assert status_filter_text() == "0 idle\n1 ?green?busy\n2 ?orange?starved\n3 ?red?blocked\n"


def test_gtkw_is_deterministic_and_refuses_quotes():
    log = synthetic_log(50)
    assert gtkw_text(log, "a.vcd", "f") == gtkw_text(synthetic_log(50), "a.vcd", "f")
    with pytest.raises(ConfigError, match="without quotes"):
        gtkw_text(log, 'a".vcd', "f")
    with pytest.raises(ConfigError, match="status signals"):
        gtkw_text(log, "a.vcd")
    no_status = select(log, ["top.fifo.*"])
    assert "^1" not in gtkw_text(no_status, "a.vcd")


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
            assert e["name"] in TIMELINE_STATUS_NAMES and e["dur"] > 0
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
