"""Traces of the chip: the compiled engine's trace read back by two
independent VCD readers equals the readable kernel's own state; tracing changes nothing; the
output-valid pulses count the disparities; two runs give identical files; bad trace options
fail cleanly."""

import json

import cv2
import numpy as np
import pytest
import pywellen
import vcdvcd

from stereosim.core.config import load_config
from stereosim.core.io import read_pfm
from stereosim.sim.cli import main
from stereosim.sim.cycle.compiled.run import run_compiled
from stereosim.sim.cycle.contract import BudgetExceeded
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.chip import build_chip
from stereosim.sim.tracing import TraceRequest, run_traced, write_traces


def run_cycle_fast(left, right, cfg):
    """The compiled engine: (words, report, statistics)."""
    frame = run_compiled(build_plan(cfg, left.shape), left, right)
    report = dict(frame.report, engine="fast")
    return frame.words, report, frame.stats

SHAPE = (14, 40)
CONFIG = {"sva.disparities": 16, "nna.descriptor": "cnn", "sva.paths": 4, "sva.lr_check": True,
          "fifo.nna_to_sva_depth": 4}
STATUS = {"idle": 0, "busy": 1, "starved": 2, "blocked": 3}


def _pair(shape=SHAPE, seed=3):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, shape, dtype=np.uint8)
    return left, np.roll(left, -4, axis=1)


def _traced(tmp_path, cfg, left, right, window=None):
    req = TraceRequest(window=window, vcd=str(tmp_path / "t.vcd"),
                       timeline=str(tmp_path / "t.json"))
    frame, log = run_traced(build_plan(cfg, left.shape), left, right, req)
    write_traces(log, req)
    return frame.words, frame.report, log, req


class _Wellen:
    """Values of a VCD through pywellen (Surfer's backend)."""

    def __init__(self, path):
        self.vars = {var.full_name: var.signal for var in pywellen.Waveform(str(path)).all_vars()}

    def value(self, name, t_fs):
        return int(self.vars[name].value_at(t_fs))


def _vcdvcd_value(vcd, name, t_fs):
    return int(vcd[name][t_fs], 2)


SPLIT = {**CONFIG, "nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 8}
SPLIT_ROWS = {**CONFIG, "nna.stereo_submodules": 6, "nna.split": "rows",
              "source.kind": "camera", "clocks.camera_mhz": 60}


@pytest.mark.parametrize("over", [CONFIG, SPLIT, SPLIT_ROWS], ids=["whole", "tiles", "bands"])
def test_trace_values_equal_the_readable_kernels_state_at_sampled_instants(tmp_path, over):
    """At SVA cycles k, the readable kernel stopped by a budget of k SVA cycles reports every
    FIFO's occupancy and every block's status after its last step; the VCD of the compiled
    engine, read by pywellen and by vcdvcd at that step, says the same -- for a whole frame and for
    frames split into column tiles or row bands (with their merges)."""
    cfg = load_config(overrides=over)
    left, right = _pair()
    _, _, log, req = _traced(tmp_path, cfg, left, right)
    wellen = _Wellen(req.vcd)
    vv = vcdvcd.VCDVCD(req.vcd, store_scopes=True)
    plan = build_plan(cfg, left.shape)
    blocks = {b.name: b.scope for b in plan.blocks}
    sva_cycles = [3, 250, 1200, 2500, 3001]
    checked = 0
    for k in sva_cycles:
        chip = build_chip(left, right, cfg)
        budget = dict(chip.plan.budget)
        budget["sva"] = k
        with pytest.raises(BudgetExceeded) as info:
            chip.sim.run(chip.done, budget_cycles=budget,
                         watchdog_cycles=cfg.sim.watchdog_cycles)
        err = info.value
        t = err.time_fs  # the last step run: the state the error reports holds from it on
        assert t >= log.start_fs
        for fifo, st in err.fifos.items():
            name = f"top.fifo.{fifo}.occupancy"
            assert wellen.value(name, t) == st["occupancy"]
            assert _vcdvcd_value(vv, _vcdvcd_name(vv, name), t) == st["occupancy"]
        for block, st in err.blocks.items():
            name = f"{blocks[block]}.status"
            expected = STATUS[st["status"]] if st["status"] else 0
            assert wellen.value(name, t) == expected
            assert _vcdvcd_value(vv, _vcdvcd_name(vv, name), t) == expected
            checked += 1
    assert checked == len(plan.blocks) * len(sva_cycles)


def _vcdvcd_name(vv, dotted):
    """vcdvcd names vectors with their range: find the reference for a dotted path."""
    for ref in vv.references_to_ids:
        if ref == dotted or ref.split("[")[0] == dotted:
            return ref
    raise KeyError(dotted)


def test_tracing_changes_nothing_and_valid_pulses_count_the_disparities(tmp_path):
    cfg = load_config(overrides=CONFIG)
    left, right = _pair()
    words0, report0, stats0 = run_cycle_fast(left, right, cfg)
    words1, report1, log, req = _traced(tmp_path, cfg, left, right)
    assert report1.pop("trace")["outputs_in_window"] == words0.size
    assert np.array_equal(words0, words1) and report0 == report1
    # output valid sampled at every SVA clock edge of the window = words the SVA produced
    wellen = _Wellen(req.vcd)
    sva = next(c for c in log.clocks if c.name == "sva")
    edges = range(-(-(log.start_fs - sva.phase_fs) // sva.period_fs),
                  (log.end_fs - 1 - sva.phase_fs) // sva.period_fs + 1)
    pulses = sum(wellen.value("top.sva.output.valid", sva.phase_fs + k * sva.period_fs)
                 for k in edges)
    assert pulses == words0.size == report0["fifos"]["sva_to_sink"]["pushes"]


def test_a_window_traces_only_its_instants_and_leaves_results_alone(tmp_path):
    cfg = load_config(overrides=CONFIG)
    left, right = _pair()
    words0, report0, _ = run_cycle_fast(left, right, cfg)
    words1, report1, log, req = _traced(tmp_path, cfg, left, right, window="sva:1500:2600")
    produced = report1.pop("trace")["outputs_in_window"]
    assert np.array_equal(words0, words1) and report0 == report1
    # the output-valid pulses at the window's SVA edges = the words the engine counted in it
    wellen = _Wellen(req.vcd)
    sva = next(c for c in log.clocks if c.name == "sva")
    pulses = sum(wellen.value("top.sva.output.valid", sva.phase_fs + k * sva.period_fs)
                 for k in range(1500, 2600))
    assert 0 < produced < words0.size and pulses == produced
    sva = next(c for c in log.clocks if c.name == "sva")
    assert log.start_fs == sva.phase_fs + 1500 * sva.period_fs
    assert log.end_fs == sva.phase_fs + 2600 * sva.period_fs
    assert log.n_changes > 0 and log.times_fs.min() >= log.start_fs
    assert log.times_fs.max() < log.end_fs


def test_rows_window_spans_from_the_line_buffer_to_the_sink(tmp_path):
    cfg = load_config(overrides=CONFIG)
    left, right = _pair()
    _, _, log, req = _traced(tmp_path, cfg, left, right, window="rows:2:5")
    wellen = _Wellen(req.vcd)
    # at the start the left line buffer has just reached row 2; at the end the sink holds 5 rows
    assert wellen.value("top.nna.left.sub0.line_buffer.row_in", log.start_fs) == 2
    assert wellen.value("top.sink.count", log.end_fs - 1) == 5 * SHAPE[1]
    # ... and did not hold it one instant before (the last step of the window completed it)
    assert wellen.value("top.sink.count", log.times_fs[-1] - 1) < 5 * SHAPE[1]


def _cli_run(tmp_path, name, *extra):
    left, right = _pair((20, 48))
    cv2.imwrite(str(tmp_path / "l.png"), left)
    cv2.imwrite(str(tmp_path / "r.png"), right)
    out = tmp_path / name
    argv = ["run", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
            "--disparities", "16", "--set", "nna.descriptor=cnn", "--out", str(out), *extra]
    return main(argv), out


def test_cli_traces_are_deterministic_and_do_not_change_the_outputs(tmp_path, capsys):
    rc, plain = _cli_run(tmp_path, "plain")
    assert rc == 0
    files = []
    for name in ("a", "b"):
        rc, out = _cli_run(tmp_path, name, "--vcd", str(tmp_path / f"{name}.vcd"), "--timeline",
                           str(tmp_path / f"{name}.json"), "--trace-window", "0:3000")
        assert rc == 0
        files.append(out)
    for ext in ("vcd", "gtkw", "json", "status.txt"):
        assert (tmp_path / f"a.{ext}").read_bytes().replace(b"/a.", b"/b.") == \
            (tmp_path / f"b.{ext}").read_bytes()
    assert np.array_equal(read_pfm(plain / "disparity.pfm"), read_pfm(files[0] / "disparity.pfm"),
                          equal_nan=True)
    rep0 = json.loads((plain / "report.json").read_text())
    rep1 = json.loads((files[0] / "report.json").read_text())
    rep1.pop("trace")
    listed0, listed1 = rep0.pop("files"), rep1.pop("files")  # the set's SHA-256 manifest
    assert sorted(listed1) == ["../a.gtkw", "../a.json", "../a.status.txt", "../a.vcd",
                               "disparity.pfm", "disparity.png"]
    assert {k: listed1[k] for k in listed0} == listed0
    assert rep0 == rep1


def test_cli_time_window_and_the_gtkw_beside_the_dump(tmp_path, monkeypatch):
    """`--trace-window 0:3us` is 3 us of the frame; `--signals` is `--trace`; the .gtkw names
    the dump and the status filter by absolute path (the run is started in another folder)."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    rc, out = _cli_run(tmp_path, "w", "--vcd", "../w.vcd", "--trace-window", "0:3us",
                       "--signals", "top.sva.*", "--trace", "top.fifo.*.occupancy")
    assert rc == 0
    report = json.loads((out / "report.json").read_text())
    assert report["trace"]["window_fs"] == [0, 3 * 10**9]
    lines = (tmp_path / "w.gtkw").read_text().splitlines()
    assert f'[dumpfile] "{tmp_path / "w.vcd"}"' in lines
    assert f"^1 {tmp_path / 'w.status.txt'}" in lines
    assert (tmp_path / "w.status.txt").read_text().startswith("0 idle\n1 ?green?busy\n")
    names = set(_Wellen(tmp_path / "w.vcd").vars)
    assert "top.sva.stage.wta.status" in names and "top.fifo.sva_to_sink.occupancy" in names
    assert not any(n.startswith("top.nna") for n in names)
    aliases = [ln[2:].split("}")[0] for ln in lines if ln.startswith("+{")]
    assert "sva/stage/wta/status" in aliases and len(set(aliases)) == len(aliases)


def test_cli_trace_patterns_keep_only_matching_signals(tmp_path):
    rc, _ = _cli_run(tmp_path, "p", "--vcd", str(tmp_path / "p.vcd"), "--trace",
                     "top.sva.output.*", "--trace", "top.fifo.*.occupancy")
    assert rc == 0
    names = set(_Wellen(tmp_path / "p.vcd").vars)
    assert "top.sva.output.valid" in names and "top.fifo.sva_to_sink.occupancy" in names
    assert not any(n.startswith("top.nna") for n in names)


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--trace-window", "0:100"], "need --vcd"),
        (["--vcd", "X.vcd", "--mode", "functional"], "cycle model"),
        (["--vcd", "X.vcd", "--trace-window", "9:3"], "0 <= A < B"),
        (["--vcd", "X.vcd", "--trace-window", "gpu:0:3"], "expected A:B"),
        (["--vcd", "X.vcd", "--trace-window", "camera:0:3"], "no camera clock"),
        (["--vcd", "X.vcd", "--trace-window", "sva:900000000:900000001"], "after the frame"),
        (["--vcd", "X.vcd", "--trace-limit", "0.001"], "--force"),
        (["--vcd", "X.vcd", "--trace", "top.nothing.*"], "match"),
    ],
)
def test_bad_trace_options_fail_in_one_line_and_write_nothing(tmp_path, capsys, extra, words):
    extra = [e.replace("X.vcd", str(tmp_path / "x.vcd")) for e in extra]
    rc, out = _cli_run(tmp_path, "bad", *extra)
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert err.startswith("stereosim: error:") and "\n" not in err and words in err
    assert "Traceback" not in err
    assert not (tmp_path / "x.vcd").exists() and not out.exists()


def test_forced_trace_above_the_limit_is_written(tmp_path):
    rc, _ = _cli_run(tmp_path, "f", "--vcd", str(tmp_path / "f.vcd"), "--trace-limit", "0.001",
                     "--force")
    assert rc == 0 and (tmp_path / "f.vcd").stat().st_size > 1000
