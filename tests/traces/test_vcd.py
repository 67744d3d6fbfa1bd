"""The VCD writer: read back by two independent readers (vcdvcd, pywellen) it gives the log's
values at every instant; the pyvcd reference writer reads back the same; header, clocks, sizes."""

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
import pywellen
import vcdvcd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereosim.core.errors import ConfigError
from stereosim.sim.cycle.rules import ClockDomain
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.log import Clock, Signal, TraceLog, select, window
from stereosim.traces.vcd import (
    bound_vcd_bytes,
    clock_edges,
    estimate_vcd_bytes,
    identifier_code,
    vcd_bytes,
    vcd_text_pyvcd,
    write_vcd,
)

# ---- a naive model of what the dump must say ------------------------------------------------


def expected_changes(log: TraceLog) -> dict[str, list[tuple[int, int]]]:
    """path -> [(time, value)] of the value at the window's start and every real change after,
    computed the slow way from the log's semantics (last change at an instant wins, repeats
    are not changes), clocks included."""
    out = {}
    for clk in log.clocks:
        seq = []
        k = 0
        while True:
            rise = clk.phase_fs + k * clk.period_fs
            if rise >= log.end_fs:
                break
            for t, v in ((rise, 1), (rise + clk.period_fs // 2, 0)):
                if t < log.end_fs:
                    seq.append((t, v))
            k += 1
        value = 0
        for t, v in seq:
            if t <= log.start_fs:
                value = v
        changes = [(log.start_fs, value)] + [(t, v) for t, v in seq if t > log.start_fs]
        out[f"clocks.{clk.name}"] = changes
    final: dict[int, dict[int, int]] = {}
    for t, i, v in zip(log.times_fs.tolist(), log.ids.tolist(), log.values.tolist()):
        final.setdefault(i, {})[max(t, log.start_fs)] = v
    for i, sig in enumerate(log.signals):
        cur = int(log.initial[i])
        at_start = final.get(i, {}).get(log.start_fs, cur)
        seq = [(log.start_fs, at_start)]
        cur = at_start
        for t, v in sorted(final.get(i, {}).items()):
            if t > log.start_fs and v != cur:
                seq.append((t, v))
                cur = v
        out[sig.path] = seq
    return out


def read_vcdvcd(path: Path) -> dict[str, list[tuple[int, int]]]:
    v = vcdvcd.VCDVCD(str(path))
    out = {}
    for name in v.signals:
        base = re.sub(r"\[\d+:\d+\]$", "", name)
        out[base] = [(t, int(val, 2)) for t, val in v[name].tv]
    return out


def read_pywellen(path: Path) -> dict[str, list[tuple[int, int]]]:
    w = pywellen.Waveform(str(path))
    return {var.full_name: [(t, int(val)) for t, val in var.tv] for var in w.all_vars()}


def _dump(log: TraceLog, folder: Path, name: str = "t.vcd") -> Path:
    path = folder / name
    write_vcd(path, log)
    return path


# ---- random logs ----------------------------------------------------------------------------


@st.composite
def logs(draw):
    n_sig = draw(st.integers(1, 6))
    signals = []
    for i in range(n_sig):
        depth = draw(st.integers(0, 2))
        path = "top." + "".join(f"u{draw(st.integers(0, 1))}." for _ in range(depth)) + f"s{i}"
        signals.append(Signal(path, draw(st.sampled_from([1, 1, 2, 7, 31, 32, 63, 64])), "d"))
    clocks = [
        Clock(f"c{j}", draw(st.integers(2, 40)), draw(st.integers(0, 30)))
        for j in range(draw(st.integers(0, 3)))
    ]
    start = draw(st.integers(0, 40))
    end = start + draw(st.integers(1, 200))

    def value(i):
        w = signals[i].width
        return draw(st.one_of(st.integers(0, 2), st.integers(0, (1 << w) - 1)).map(
            lambda v: v & ((1 << w) - 1)))

    initial = np.array([value(i) for i in range(n_sig)], dtype=np.uint64)
    n = draw(st.integers(0, 60))
    times = sorted(draw(st.lists(st.integers(start, end - 1), min_size=n, max_size=n)))
    ids = [draw(st.integers(0, n_sig - 1)) for _ in range(n)]
    values = [value(i) for i in ids]
    return TraceLog(
        signals=signals, clocks=clocks, start_fs=start, end_fs=end, initial=initial,
        times_fs=np.array(times, dtype=np.int64), ids=np.array(ids, dtype=np.int32),
        values=np.array(values, dtype=np.uint64),
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(logs())
def test_random_logs_read_back_with_both_readers(log):
    want = expected_changes(log)
    with tempfile.TemporaryDirectory() as tmp:
        path = _dump(log, Path(tmp))
        assert read_vcdvcd(path) == want
        assert read_pywellen(path) == want


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(logs())
def test_pyvcd_reference_reads_back_the_same(log):
    with tempfile.TemporaryDirectory() as tmp:
        fast = _dump(log, Path(tmp), "fast.vcd")
        ref = Path(tmp) / "ref.vcd"
        ref.write_text(vcd_text_pyvcd(log))
        assert read_pywellen(fast) == read_pywellen(ref)
        assert read_vcdvcd(fast) == read_vcdvcd(ref)


@settings(max_examples=60, deadline=None)
@given(logs())
def test_estimate_is_the_real_size(log):
    assert estimate_vcd_bytes(log) == len(vcd_bytes(log))


@settings(max_examples=60, deadline=None)
@given(logs())
def test_body_times_increase_and_values_change(log):
    text = vcd_bytes(log).decode("ascii")
    body = text.split("$enddefinitions $end\n", 1)[1]
    times = [int(line[1:]) for line in body.splitlines() if line.startswith("#")]
    assert times == sorted(set(times))
    assert times[0] == log.start_fs and times[-1] == log.end_fs
    last = {}
    for line in body.split("$end\n", 1)[1].splitlines():
        if line.startswith("#"):
            continue
        value, code = (line[1:].split(" ") if line[0] == "b" else (line[0], line[1:]))
        assert value == "0" or not value.startswith("0")  # no leading zeros
        assert last.get(code) != value
        last[code] = value


# ---- the chip's clocks ----------------------------------------------------------------------


def _chip_log(start_fs, end_fs, phases=(0, 0, 0)):
    clocks = []
    for (name, mhz), phase in zip((("camera", 74.25), ("nna", 460.0), ("sva", 465.0)), phases):
        dom = ClockDomain(name, mhz * 1e6, phase)
        clocks.append(Clock(name, dom.period_fs, dom.phase_fs))
    return TraceLog(
        signals=[Signal("top.x.y", 1, "sva")], clocks=clocks, start_fs=start_fs, end_fs=end_fs,
        initial=np.zeros(1, np.uint64), times_fs=np.zeros(0, np.int64),
        ids=np.zeros(0, np.int32), values=np.zeros(0, np.uint64),
    )


@pytest.mark.parametrize("start_fs, phases", [(0, (0, 0, 0)), (123_456_789, (5, 1_000_000, 7))])
def test_clocks_toggle_at_exact_edges(tmp_path, start_fs, phases):
    log = _chip_log(start_fs, start_fs + 200_000_000, phases)
    got = read_pywellen(_dump(log, tmp_path))
    for clk, mhz in zip(log.clocks, (74.25, 460.0, 465.0)):
        assert clk.period_fs == round(1e15 / (mhz * 1e6))
        seq = got[f"clocks.{clk.name}"]
        rises = [t for t, v in seq[1:] if v == 1]
        falls = [t for t, v in seq[1:] if v == 0]
        k0 = rises and (rises[0] - clk.phase_fs) // clk.period_fs
        assert rises == [clk.phase_fs + (k0 + k) * clk.period_fs for k in range(len(rises))]
        assert all((f - clk.phase_fs) % clk.period_fs == clk.period_fs // 2 for f in falls)
        assert abs(len(rises) - 200_000_000 / clk.period_fs) <= 1
        assert [v for _, v in seq[1:]] == [1 - seq[0][1] + (k % 2) * (2 * seq[0][1] - 1)
                                           for k in range(len(seq) - 1)]


def test_clock_value_at_start():
    clk = Clock("c", 10, 3)
    assert clock_edges(clk, 0, 30)[0] == 0  # before the first edge
    assert clock_edges(clk, 3, 30)[0] == 1  # on a rising edge
    assert clock_edges(clk, 8, 30)[0] == 0  # on a falling edge
    v0, t, v = clock_edges(clk, 8, 30)
    assert t.tolist() == [13, 18, 23, 28] and v.tolist() == [1, 0, 1, 0]


# ---- header and determinism -----------------------------------------------------------------


def _small_log():
    return TraceLog(
        signals=[Signal("top.nna.left.valid", 1, "nna"), Signal("top.nna.left.fill", 16, "nna"),
                 Signal("top.fifo.a_to_b.occupancy", 5, "sva")],
        clocks=[Clock("nna", 2173913, 0), Clock("sva", 2150538, 0)],
        start_fs=0, end_fs=6_000_000,
        initial=np.array([0, 0, 0], np.uint64),
        times_fs=np.array([0, 2173913, 2173913, 4301076], np.int64),
        ids=np.array([1, 0, 1, 2], np.int32),
        values=np.array([9, 1, 10, 3], np.uint64),
    )


def test_header_structure():
    text = vcd_bytes(_small_log()).decode("ascii")
    head, body = text.split("$enddefinitions $end\n")
    assert "$date" not in head
    assert "$timescale 1 fs $end" in head
    assert re.search(r"^\$version stereosim \S+ \$end$", head, re.M)
    assert head.splitlines()[-2:] == ["$upscope $end", "$upscope $end"]
    assert body.startswith("#0\n$dumpvars\n1!\n1\"\n0#\nb1001 $\nb0 %\n$end\n#1075269\n0\"\n")
    assert "#2173913\n1!\n1#\nb1010 $\n" in body
    assert "#4301076\n1\"\nb11 %\n" in body
    assert body.endswith("#6000000\n")
    scopes = sum(1 for line in head.splitlines() if line.startswith("$scope"))
    upscopes = sum(1 for line in head.splitlines() if line == "$upscope $end")
    assert scopes == upscopes == 6  # clocks, top, nna, left, fifo, a_to_b


def test_declarations_nest_scopes():
    head = vcd_bytes(_small_log()).decode("ascii").split("$enddefinitions")[0].splitlines()
    decl = head[head.index("$scope module top $end"):]
    assert decl == [
        "$scope module top $end",
        "$scope module nna $end",
        "$scope module left $end",
        "$var wire 1 # valid $end",
        "$var wire 16 $ fill [15:0] $end",
        "$upscope $end",
        "$upscope $end",
        "$scope module fifo $end",
        "$scope module a_to_b $end",
        "$var wire 5 % occupancy [4:0] $end",
        "$upscope $end",
        "$upscope $end",
        "$upscope $end",
    ]


def test_bytes_are_deterministic_and_date_is_optional(tmp_path):
    log = _small_log()
    a, b = tmp_path / "a.vcd", tmp_path / "b.vcd"
    write_vcd(a, log)
    write_vcd(b, synthetic_log(50, seed=3))
    write_vcd(b, log)
    assert a.read_bytes() == b.read_bytes() == vcd_bytes(log)
    dated = vcd_bytes(log, date="2024-01-01").decode()
    assert dated.startswith("$date 2024-01-01 $end\n")
    assert read_pywellen(a) == read_pywellen(_write(tmp_path / "d.vcd", dated))


def _write(path, text):
    path.write_text(text)
    return path


def test_identifier_codes_are_unique_printable():
    codes = [identifier_code(i) for i in range(20_000)]
    assert len(set(codes)) == len(codes)
    assert all(33 <= ord(c) <= 126 for code in codes for c in code)
    assert codes[0] == "!" and codes[93] == "~" and codes[94] == "!!"
    assert [len(c) for c in codes[:95]] == [1] * 94 + [2]


# ---- realistic logs, sizes, scoping ----------------------------------------------------------


def test_synthetic_log_sampled_times_match_both_readers(tmp_path):
    log = synthetic_log(3000, seed=1)
    path = _dump(log, tmp_path)
    w = pywellen.Waveform(str(path))
    wvars = {var.full_name: var.signal for var in w.all_vars()}
    v = vcdvcd.VCDVCD(str(path))
    rng = np.random.default_rng(0)
    samples = np.sort(rng.integers(log.start_fs, log.end_fs, 40))
    for t in samples.tolist():
        # the simulator's state at t: every change at or before t applied
        state = log.initial.copy()
        k = int(np.searchsorted(log.times_fs, t, side="right"))
        for i, val in zip(log.ids[:k].tolist(), log.values[:k].tolist()):
            state[i] = val
        for i, sig in enumerate(log.signals):
            assert int(wvars[sig.path].value_at(t)) == int(state[i]), (sig.path, t)
            name = sig.path if sig.width == 1 else f"{sig.path}[{sig.width - 1}:0]"
            assert int(v[name][t], 2) == int(state[i]), (sig.path, t)


def test_estimate_and_bound_on_a_chip_like_log():
    log = synthetic_log(2000, seed=2)
    real = len(vcd_bytes(log))
    assert estimate_vcd_bytes(log) == real
    bound = bound_vcd_bytes(log.signals, log.clocks, log.start_fs, log.end_fs)
    assert real <= bound <= 4 * real


def test_bound_needs_a_clock_per_domain():
    log = _small_log()
    with pytest.raises(ConfigError, match="domain 'dsp', which has no clock"):
        bound_vcd_bytes([Signal("top.a.b", 3, "dsp")], log.clocks, 0, 100)


def test_select_and_window_dump_the_same_values(tmp_path):
    log = synthetic_log(2000, seed=4)
    part = window(select(log, ["top.sva.*", "*.occupancy"]), 1_000_000_000, 3_000_000_000)
    got = read_pywellen(_dump(part, tmp_path))
    full = expected_changes(log)
    assert set(got) == {f"clocks.{c.name}" for c in log.clocks} | {
        s.path for s in log.signals if s.path.startswith("top.sva.") or
        s.path.endswith(".occupancy")}
    for path, seq in got.items():
        before = [(t, v) for t, v in full[path] if t <= 1_000_000_000]
        inside = [(t, v) for t, v in full[path] if 1_000_000_000 < t < 3_000_000_000]
        assert seq == [(1_000_000_000, before[-1][1])] + inside


def test_writer_refuses_an_invalid_log_and_writes_nothing(tmp_path):
    log = _small_log()
    log.values[0] = 1 << 16
    with pytest.raises(ConfigError, match="does not fit the 16 bits of signal 'top.nna.left.fill'"):
        write_vcd(tmp_path / "x.vcd", log)
    assert list(tmp_path.iterdir()) == []
