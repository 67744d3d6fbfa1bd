"""``--max-cycles N`` (sim.max_cycles): a run stops once any clock domain ran N cycles, on both
engines at the same instant with the same state of every FIFO; a limit the run does not reach
changes nothing; a limit beyond what the engines' time holds is capped to it. A stopped
command (the limit, the automatic budget, or a deadlock) exits 2 with one line and publishes its
report and the trace up to the stop; the line of the limit the user set says so, and is no
error of the chip's. ``--version`` names the installed
version."""

import hashlib
import importlib.metadata
import json
import os

import numpy as np
import pytest
import pywellen

import stereosim
from stereosim.core.config import load_config
from stereosim.core.errors import ConfigError
from stereosim.core.io import encode_png
from stereosim.sim import tracing
from stereosim.sim.cli import main
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import BudgetExceeded
from stereosim.sim.cycle.plan import MAX_RUN_FS, STATUS_CODES, build_plan
from stereosim.sim.cycle.simulate import check_run_time, simulate
from stereosim.sim.run_files import StopAsked, publish_stop

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census"}


def _pair(h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, :w].copy(), base[:, shift:].copy()


@pytest.mark.parametrize("clocks, share", [((400, 400), 0.5), ((460, 465), 0.3),
                                            ((300, 500), 0.77)])
def test_the_run_stops_at_the_limit_of_its_fastest_domain(clocks, share, run_cycle):
    """With N = sim.max_cycles every domain may run N cycles: the fastest clock gets there first,
    so the run stops with that domain at exactly N cycles and the others at the cycles their
    clock fits into the same time; both engines agree on the message and the state."""
    left, right = _pair(6, 40)
    over = {**CENSUS, "clocks.nna_mhz": clocks[0], "clocks.sva_mhz": clocks[1]}
    free = run_compiled(build_plan(load_config(overrides=over), left.shape), left, right)
    limit = int(share * max(free.report["cycles"]["total"].values()))
    cfg = load_config(overrides={**over, "sim.max_cycles": limit})
    plan = build_plan(cfg, left.shape)
    assert plan.budget == {"nna": limit, "sva": limit}
    with pytest.raises(BudgetExceeded) as fast:
        run_compiled(plan, left, right)
    with pytest.raises(BudgetExceeded) as slow:
        run_cycle(left, right, cfg)
    assert str(fast.value) == str(slow.value)
    assert fast.value.fifos == slow.value.fifos and fast.value.cycles == slow.value.cycles
    fastest = min(plan.domains, key=lambda d: (plan.domains[d].period_fs, d))
    assert fast.value.cycles[fastest] == limit
    for d, dom in plan.domains.items():  # every domain's edges before the stop instant
        per = dom.period_fs
        assert fast.value.cycles[d] == -(-limit * plan.domains[fastest].period_fs // per)
    assert str(fast.value).startswith(f"stopped at the cycle budget you set (--max-cycles {limit})"
                                      " at ")
    assert f"{fastest} reached {limit} cycles" in str(fast.value)


def test_a_limit_the_run_does_not_reach_changes_nothing(run_cycle):
    left, right = _pair(6, 40)
    free = load_config(overrides=CENSUS)
    words, report, _ = run_cycle(left, right, free)
    need = max(report["cycles"]["total"].values())
    capped = load_config(overrides={**CENSUS, "sim.max_cycles": need})
    frame = run_compiled(build_plan(capped, left.shape), left, right)
    assert np.array_equal(frame.words, words)
    assert frame.report["cycles"] == report["cycles"]
    with pytest.raises(BudgetExceeded):  # one cycle fewer does not complete the frame
        run_compiled(build_plan(load_config(overrides={**CENSUS, "sim.max_cycles": need - 1}),
                                left.shape), left, right)


def _inputs(tmp_path, h, w):
    left, right = _pair(h, w)
    lp, rp = tmp_path / "l.png", tmp_path / "r.png"
    lp.write_bytes(encode_png(left))
    rp.write_bytes(encode_png(right))
    return ["run", "--left", str(lp), "--right", str(rp), "--disparities", "16"]


class _Wave:
    """A dump read back by pywellen (Surfer's backend): every signal's value at an instant,
    and the last instant it holds."""

    def __init__(self, path):
        wave = pywellen.Waveform(str(path))
        self.vars = {var.full_name: var.signal for var in wave.all_vars()}
        times = []
        wave.stream_time_steps(lambda t, *_: times.append(t), None)
        self.last_fs = times[-1]

    def value(self, name, t_fs):
        return int(self.vars[name].value_at(t_fs))


def _one_line(err: str) -> str:
    """The error line on stderr, less numba's first-run compile notice (core.progress)."""
    lines = [ln for ln in err.splitlines(True) if not ln.startswith("stereosim: compiling")]
    assert len(lines) == 1, lines
    return lines[0]


def _stopped_set(out, err, dump, plan) -> dict:
    """What a stopped run left: one line naming the report and the dump; report.json marked
    stopped, with the hashes of the set's files; the dump, read back by pywellen, ending at the
    stop with every FIFO's occupancy and every block's status the report gives; nothing that
    pretends to be a frame."""
    err = _one_line(err)
    # a stop the user asked for is not called an error; a deadlock is one
    asked = "stopped at the cycle budget you set" in err
    assert err.startswith("stereosim: stopped at the cycle budget you set" if asked
                          else "stereosim: error: ")
    assert f"see {out / 'report.json'} for every block's and FIFO's state" in err
    assert f"the trace up to the stop in {dump}" in err
    assert not (out / "disparity.pfm").exists() and not (out / "disparity.png").exists()
    report = json.loads((out / "report.json").read_text())
    stop = report["stopped"]
    assert stop["message"] in err
    for whole_frame in ("output", "throughput", "cycles", "metrics"):
        assert whole_frame not in report
    files = {name: hashlib.sha256((out / name).read_bytes()).hexdigest()
             for name in sorted(os.listdir(out))
             if name != "report.json" and not name.startswith(".")}
    assert report["files"] == files and dump.name in files
    wave = _Wave(dump)
    t = stop["time_fs"]
    assert t <= wave.last_fs <= t + 1  # up to the stop, nothing after it
    for name, st in stop["fifos"].items():
        assert wave.value(f"top.fifo.{name}.occupancy", t) == st["occupancy"]
    scopes = {b.name: b.scope for b in plan.blocks}
    for name, st in stop["blocks"].items():
        assert wave.value(f"{scopes[name]}.status", t) == STATUS_CODES[st["status"]]
    return report


@pytest.mark.parametrize("engine, dump", [("fast", "t.vcd"), ("readable", "t.fst")])
def test_a_stopped_run_publishes_its_report_and_the_trace_up_to_the_stop(tmp_path, capsys,
                                                                          engine, dump):
    """``--max-cycles 5000 --vcd t.vcd`` exits 2 with one line and
    leaves the dump up to the stop and a report marked stopped -- replacing a complete run's
    set in the same folder, whose disparity maps and page go (they are not this run's)."""
    args = _inputs(tmp_path, 40, 64) + ["--set", f"sim.engine={engine}"]
    out = tmp_path / "out"
    dump = out / dump
    files = ["--out", str(out), "--vcd", str(dump), "--html", str(out / "page.html")]
    assert main(args + files) == 0  # a whole frame first
    assert (out / "disparity.pfm").is_file() and (out / "page.html").is_file()
    capsys.readouterr()
    assert main(args + files + ["--max-cycles", "5000"]) == 2
    assert not (out / "page.html").exists()
    err = capsys.readouterr().err
    assert "stopped at the cycle budget you set (--max-cycles 5000)" in err
    cfg = load_config(overrides={"sva.disparities": 16, "sim.max_cycles": 5000})
    report = _stopped_set(out, err, dump, build_plan(cfg, (40, 64)))
    assert report["stopped"]["reason"] == "max_cycles" and report["engine"] == engine
    assert max(report["stopped"]["cycles"].values()) == 5000
    assert report["config"]["sim"]["max_cycles"] == 5000
    assert main(args + ["--out", str(out), "--max-cycles", "0"]) == 2  # not a positive count
    assert "--max-cycles" in capsys.readouterr().err
    assert main(args + ["--out", str(out), "--max-cycles", "10000000", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["config"]["sim"]["max_cycles"] == 10000000


def test_a_deadlocked_run_publishes_its_report_and_the_trace_up_to_the_stop(tmp_path, capsys,
                                                                           monkeypatch):
    """A sink that never pops (the hook the engine tests use, here under the command): the
    FIFOs fill back to the sources and the watchdog stops the run; the line names the full
    FIFOs, the report who waits on whom."""
    def never_popping(plan, left, right, **kw):
        return simulate(plan, left, right, sink_stall=(1 << 40, (1 << 40) - 1), **kw)

    monkeypatch.setattr(tracing, "simulate", never_popping)
    args = _inputs(tmp_path, 12, 40) + ["--set", "sim.watchdog_cycles=500"]
    out, dump = tmp_path / "out", tmp_path / "out" / "t.vcd"
    assert main(args + ["--out", str(out), "--vcd", str(dump)]) == 2
    err = _one_line(capsys.readouterr().err)
    assert err.startswith("stereosim: error: deadlock at ") and "full FIFOs: " in err
    assert "sva_to_sink 16/16" in err and "sim.watchdog_cycles = 500" in err
    plan = build_plan(load_config(overrides={"sva.disparities": 16}), (12, 40))
    report = _stopped_set(out, err, dump, plan)
    stop = report["stopped"]
    assert stop["reason"] == "deadlock"
    assert stop["blocks"]["sva"]["waiting_on_block"] == "sink"
    assert stop["fifos"]["sva_to_sink"]["state"] == "full"


def test_a_stopped_stream_publishes_its_report_and_the_trace_up_to_the_stop(tmp_path, capsys):
    """A stream (``--frames 3``) stopped by ``--max-cycles`` in its second frame leaves what a
    single frame's stop does: one line, the dump up to the stop, the report marked stopped (with
    the stream's frame count) -- and no saved frame or last-frame map of an earlier run."""
    args = _inputs(tmp_path, 40, 64) + ["--frames", "3", "--save-every", "1"]
    out = tmp_path / "out"
    dump = out / "t.vcd"
    assert main(args + ["--out", str(out)]) == 0  # a whole stream first
    assert (out / "frames" / "disparity_00002.pfm").is_file()
    capsys.readouterr()
    limit = 12000  # beyond one 40x64 frame (about 5,700 SVA cycles), short of three
    assert main(args + ["--out", str(out), "--vcd", str(dump), "--max-cycles", str(limit)]) == 2
    err = capsys.readouterr().err
    assert f"stopped at the cycle budget you set (--max-cycles {limit})" in err
    cfg = load_config(overrides={"sva.disparities": 16, "sim.max_cycles": limit})
    report = _stopped_set(out, err, dump, build_plan(cfg, (40, 64), 3))
    assert report["frames"] == 3 and report["stopped"]["reason"] == "max_cycles"
    assert not (out / "frames").exists()


def test_a_stop_whose_trace_is_above_the_limit_still_publishes_its_report(tmp_path, capsys):
    """The trace up to a stop is held to ``--trace-limit`` like any other: above it, the stop's
    report is published alone, and the one line and the report say why there is no trace."""
    out = tmp_path / "out"
    args = _inputs(tmp_path, 40, 64) + ["--out", str(out), "--vcd", str(out / "t.vcd"),
                                        "--trace-limit", "0.001", "--max-cycles", "5000"]
    assert main(args) == 2
    err = _one_line(capsys.readouterr().err)
    assert "stopped at the cycle budget you set (--max-cycles 5000)" in err
    assert "(no trace: the VCD would be" in err
    report = json.loads((out / "report.json").read_text())
    assert report["stopped"]["reason"] == "max_cycles"
    assert "--trace-limit" in report["trace"]["refused"] and report["files"] == {}
    assert sorted(os.listdir(out)) == ["report.json"]


def test_version_is_the_installed_one(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"stereosim {importlib.metadata.version('stereosim')} (Python ")


def test_a_stop_the_user_asked_for_is_no_error_and_its_advice_is_what_the_cli_takes(tmp_path):
    """``--max-cycles N`` is a stop the user asked for: its line says so (not "cycle budget
    exceeded"), advises what --max-cycles takes (it refuses 0: leave it out for the automatic
    budget), and the command's line is a :class:`StopAsked` -- the automatic budget's safety
    net stays a budget overrun."""
    left, right = _pair(6, 40)
    cfg = load_config(overrides={**CENSUS, "sim.max_cycles": 300})
    with pytest.raises(BudgetExceeded) as info:
        stereosim.run(left, right, config=cfg)
    line = str(info.value)
    assert line.startswith("stopped at the cycle budget you set (--max-cycles 300) at ")
    assert "exceeded" not in line and "error" not in line and "give 0" not in line
    assert "raise --max-cycles N (sim.max_cycles), or leave it out for the automatic" in line
    assert info.value.report["stopped"]["reason"] == "max_cycles"
    said = publish_stop(info.value, None, tmp_path, [], {"name": "pair", "source": "test"})
    assert isinstance(said, StopAsked) and str(said).startswith(line)
    assert main(["run", "--max-cycles", "0"]) == 2  # what the advice steers clear of


def test_the_automatic_budget_is_still_an_overrun(tmp_path, capsys, monkeypatch):
    """A sink that never pops and a watchdog longer than the automatic budget: the budget's
    safety net stops the run, worded as an overrun, and its line is no :class:`StopAsked`."""
    def never_popping(plan, left, right, **kw):
        return simulate(plan, left, right, sink_stall=(1 << 40, (1 << 40) - 1), **kw)

    monkeypatch.setattr("stereosim.sim.api.simulate", never_popping)
    out = tmp_path / "out"
    args = _inputs(tmp_path, 12, 40) + ["--set", "sim.watchdog_cycles=1000000000", "--out",
                                         str(out)]
    assert main(args) == 2
    err = _one_line(capsys.readouterr().err)
    assert err.startswith("stereosim: error: cycle budget exceeded at ")
    assert "the automatic budget (20x the expected run) ran out" in err
    report = json.loads((out / "report.json").read_text())
    assert report["stopped"]["reason"] == "cycle_budget"


def test_a_huge_max_cycles_is_capped_to_what_the_engines_time_holds(run_cycle, capsys,
                                                                    tmp_path):
    """``--max-cycles 10000000000000`` (legal up to 2**50) overflowed the compiled engine's
    int64 femtoseconds (a traceback): every domain's budget is capped to the cycles of
    MAX_RUN_FS, and the run completes on both engines as without a limit."""
    left, right = _pair(6, 40)
    free = load_config(overrides=CENSUS)
    words, report, _ = run_cycle(left, right, free)
    for n in (10**13, 1 << 50):
        cfg = load_config(overrides={**CENSUS, "sim.max_cycles": n})
        plan = build_plan(cfg, left.shape)
        for d, dom in plan.domains.items():
            assert plan.budget[d] == min(n, MAX_RUN_FS // dom.period_fs)
        assert plan.budget_reason == "time_limit"
        assert plan.budget_head == "stopped at the longest run the cycle engines simulate"
        assert f"--max-cycles {n} asks for more" in plan.budget_remedy
        frame = run_compiled(plan, left, right)
        assert np.array_equal(frame.words, words)
        assert frame.report["cycles"] == report["cycles"]
    assert run_cycle(left, right, cfg)[1]["cycles"] == report["cycles"]
    assert main(_inputs(tmp_path, 12, 40) + ["--out", str(tmp_path / "out"), "--max-cycles",
                                             str(10**13)]) == 0
    assert "Traceback" not in capsys.readouterr().err


def test_a_stream_longer_than_the_engines_simulate_is_one_line(tmp_path, capsys):
    """At 1 kHz clocks a 6 x 40 frame takes about 1.76 s: 1,000 frames fit the 2,305.843 s
    the engines simulate (the automatic budget, 20x that, is capped to it: its int64
    femtoseconds overflowed), 2,000 do not and are refused in one line before any work, with
    the stream's way out."""
    cfg = load_config(overrides={**CENSUS, "clocks.nna_mhz": 0.001, "clocks.sva_mhz": 0.001})
    fits = build_plan(cfg, (6, 40), 1000)
    assert fits.budget_reason == "time_limit"
    assert max(n * fits.domains[d].period_fs for d, n in fits.budget.items()) <= MAX_RUN_FS
    check_run_time(fits)
    with pytest.raises(ConfigError, match="simulate the stream in parts"):
        check_run_time(build_plan(cfg, (6, 40), 2000))
    args = _inputs(tmp_path, 6, 40) + ["--frames", "2000", "--out", str(tmp_path / "out"),
                                        "--set", "nna.descriptor=census", "--set",
                                        "clocks.nna_mhz=0.001", "--set", "clocks.sva_mhz=0.001"]
    assert main(args) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith("stereosim: error: the run would take about 3,520.002 s of chip time")
    assert not any((tmp_path / "out").rglob("*"))  # nothing written


def test_a_watchdog_beyond_the_engines_time_is_one_line():
    """sim.watchdog_cycles at its maximum (2**40) at 1 kHz clocks is a window of 1.1e9 s: it
    overflowed the compiled engine's int64 femtoseconds; now refused in one line. At the
    default clocks (2.4e3 s, within what the engine's time holds) the run is not refused."""
    slow = {**CENSUS, "sim.watchdog_cycles": 1 << 40}
    check_run_time(build_plan(load_config(overrides=slow), (6, 40)))
    slow |= {"clocks.nna_mhz": 0.001, "clocks.sva_mhz": 0.001}
    with pytest.raises(ConfigError, match="lower sim.watchdog_cycles"):
        simulate(build_plan(load_config(overrides=slow), (6, 40)), *_pair(6, 40))
