"""Reports that explain themselves: report.json's keys (units, clock domains, bound vs
measured), the run summary's tables, eval's cycle columns, config show's descriptor defaults,
and plot's axes."""

import csv
import json

import numpy as np
import pytest

from stereosim.core.config import DESCRIPTOR_DEFAULTS, load_config
from stereosim.core.errors import InputError
from stereosim.core.io import encode_png, pfm_bytes
from stereosim.sim.api import REPORT_VERSION, run, run_stream
from stereosim.sim.cli import main
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.metrics import format_table
from stereosim.sim.plot import plot_xy, point_labels, time_scale
from stereosim.sim.summary import (
    eval_document,
    eval_tables,
    eval_timing,
    format_estimate,
    summary_text,
)

H, W, D = 20, 48, 16
ACTIVITIES = ("busy", "starved", "blocked", "idle")


def _pair(h=H, w=W, shift=4, seed=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return np.ascontiguousarray(base[:, shift:]), np.ascontiguousarray(base[:, :w])


@pytest.fixture(scope="module")
def cycle_report():
    cfg = load_config(overrides={"sva.disparities": D})
    gt = np.full((H, W), 4.0, np.float32)
    return run(*_pair(), mode="cycle", config=cfg, gt=gt, masks={"all": np.ones((H, W), bool)}
               ).report


# ---- report.json -----------------------------------------------------------------------------


def test_report_names_its_version_units_and_fps_kinds(cycle_report):
    rep = cycle_report
    assert rep["report_version"] == REPORT_VERSION == 3
    thr, lat, cyc = rep["throughput"], rep["latency"], rep["cycles"]
    assert {"fps_bound", "fps_measured", "fps_bound_per_block", "bottleneck"} <= set(thr)
    assert "fps" not in thr and "fps_frame" not in thr
    assert set(lat) == {"first_output_us", "frame_ms"}
    assert cyc["clock_mhz"] == {"nna": 460.0, "sva": 465.0}
    # an SVA cycle at 465 MHz is 1e6 / 465 ps: the times follow from the cycle numbers
    period_fs = round(1e15 / 465e6)
    assert cyc["first_output"]["time_us"] == cyc["first_output"]["sva"] * period_fs / 1e9
    assert cyc["last_output"]["time_ms"] == cyc["last_output"]["sva"] * period_fs / 1e12
    assert lat["first_output_us"] == cyc["first_output"]["time_us"]
    assert lat["frame_ms"] == cyc["last_output"]["time_ms"] == rep["stream"]["span_ms"]
    # one frame alone: 1 / (first input pixel to the last word), 3 decimals
    assert thr["fps_measured"] == round(1e3 / lat["frame_ms"], 3)
    assert thr["fps_bound"] == thr["fps_bound_per_block"][thr["bottleneck"]]


def test_block_cycles_say_their_domain_and_percentages(cycle_report):
    rep = cycle_report
    plan = build_plan(load_config(overrides={"sva.disparities": D}), (H, W))
    domains = {b.name: b.domain for b in plan.blocks}
    assert domains["memory_left"] == "nna" and domains["sink"] == "sva"
    for name, b in rep["blocks"].items():
        assert b["clock_domain"] == domains[name]
        assert b["clock_mhz"] == {"nna": 460.0, "sva": 465.0}[b["clock_domain"]]
        total = rep["cycles"]["total"][b["clock_domain"]]
        assert b["cycles_total"] == total == sum(b[a] for a in ACTIVITIES)
        assert b["percent"] == {a: round(100 * b[a] / total, 2) for a in ACTIVITIES}
        assert sum(b["percent"].values()) == pytest.approx(100, abs=0.03)


def test_fifo_histograms_have_bins_and_add_up_to_their_domains_cycles(cycle_report):
    rep = cycle_report
    consumer = {"src_left_to_nna": "nna", "src_right_to_nna": "nna", "nna_left_to_sva": "sva",
                "nna_right_to_sva": "sva", "sva_to_sink": "sva"}
    assert set(rep["fifos"]) == set(consumer)
    for name, f in rep["fifos"].items():
        hist = f["occupancy_histogram"]
        assert hist["occupancy"] == list(range(f["depth"] + 1))
        assert len(hist["cycles"]) == f["depth"] + 1
        assert hist["clock_domain"] == f["consumer_domain"] == consumer[name]
        assert sum(hist["cycles"]) == rep["cycles"]["total"][consumer[name]]
        # an item held but not yet visible to the consumer leaves it empty: empty >= bin 0
        assert f["cycles_empty"] >= hist["cycles"][0]


def test_estimate_uses_the_same_names_and_units():
    cfg = load_config(overrides={"nna.descriptor": "cnn"})
    est = estimate(cfg, (720, 1280))
    assert est["throughput"]["fps_bound"] == round(460e6 / (9 * 921_600), 3)
    assert set(est["latency"]) == {"first_output_us", "frame_ms", "first_output_sva_cycle",
                                   "last_output_sva_cycle"}
    period_fs = round(1e15 / 465e6)
    assert est["latency"]["first_output_us"] == pytest.approx(
        est["latency"]["first_output_sva_cycle"] * period_fs / 1e9, abs=period_fs / 1e9)
    text = format_estimate(est)
    assert f"work bound {est['throughput']['fps_bound']} fps (bottleneck nna_left)" in text
    assert f"first output {est['latency']['first_output_us']:.3f} us" in text
    assert f"frame {est['latency']['frame_ms']:.4f} ms" in text


# ---- the summary --------------------------------------------------------------------------------


def test_summary_is_plain_tables_with_labelled_fps_and_block_domains(cycle_report):
    rep = {**cycle_report, "scene": {"name": "s", "source": "a + b"}}
    text = summary_text(rep, 1.234, terminal=False)
    assert text == summary_text(rep, 1.234, terminal=False)  # deterministic
    assert "\x1b" not in text and "{" not in text  # no colour, no Python dict
    assert all(len(line) <= 100 for line in text.splitlines())
    lines = text.splitlines()
    thr = rep["throughput"]

    def row(label):
        return next(line for line in lines if line.startswith(label))

    assert row("work bound (fps)").split()[3] == f"{thr['fps_bound']:,.1f}"
    assert row("one frame alone, measured (fps)").split()[-1] == f"{thr['fps_measured']:,.1f}"
    assert row("bottleneck").split()[-1] == thr["bottleneck"]
    assert row("wall time").split()[-2:] == ["1.23", "s"]
    assert row("size").split()[1:] == [str(W), "x", str(H), "pixels"]
    assert row("first output latency").split()[3:5] == [
        f"{rep['latency']['first_output_us']:,.3f}", "us"]
    assert row("frame latency").split()[2:4] == [f"{rep['latency']['frame_ms']:,.3f}", "ms"]
    header = row("block ")
    assert header.split() == ["block", "clock", "cycles", "busy", "%", "starved", "%", "blocked",
                              "%", "idle", "%", "work", "ms"]
    for name, b in rep["blocks"].items():
        cells = row(name + " ").split()
        mhz = {"nna": "460", "sva": "465"}[b["clock_domain"]]
        assert cells[1:5] == [b["clock_domain"], "@", mhz, "MHz"]
        assert cells[5] == f"{b['cycles_total']:,}"
        assert cells[6:10] == [f"{100 * b[a] / b['cycles_total']:.2f}" for a in ACTIVITIES]
    assert row("per frame").split()[-2:] == [f"{rep['energy']['per_frame_uj']['total']:,.3f}",
                                             "uJ"]
    m = rep["metrics"]["all"]
    assert row("all ").split()[1:4] == [f"{m['bad2']:.3f}", f"{m['invalid']:.3f}",
                                        f"{m['totbad']:.3f}"]


@pytest.fixture(scope="module")
def stream_report():
    """Three frames (two pairs, the first again) scored against one GT."""
    cfg = load_config(overrides={"sva.disparities": D})
    first, second = _pair(), _pair(seed=7)
    stream = run_stream([first, second, first], config=cfg,
                        gt=np.full((H, W), 4.0, np.float32))
    frames = list(stream)
    assert len(frames) == 3
    return stream.report


def test_a_streams_span_is_named_apart_from_its_frames_latencies(stream_report, cycle_report):
    """A stream's last word is its span, not a frame's latency: report version 3 has no
    latency.frame_ms in a stream (stream.span_ms instead), and the summary prints it as the
    stream's span. One frame keeps latency.frame_ms, and its summary row."""
    rep = stream_report
    st = rep["stream"]
    assert set(rep["latency"]) == {"first_output_us"}
    assert st["span_ms"] == rep["cycles"]["last_output"]["time_ms"]
    assert st["span_ms"] > st["latency_ms"]["max"]  # the frames overlap: 3 latencies, 1 span
    text = summary_text(rep, 1.0, terminal=False)
    lines = text.splitlines()
    span = next(line for line in lines if line.startswith("stream span"))
    assert span.split()[2:4] == [f"{st['span_ms']:,.3f}", "ms"]
    assert "last frame's last disparity" in span
    assert not any(line.startswith("frame latency") for line in lines)
    per_frame = next(line for line in lines if line.startswith("latency per frame, measured"))
    assert f"median {st['latency_ms']['median']:.3f}" in per_frame
    single = summary_text(cycle_report, 1.0, terminal=False)
    assert "stream span" not in single and "\nframe latency" in single


def test_a_streams_summary_gives_the_mean_accuracy_of_its_frames(stream_report):
    rep = stream_report
    per_frame = [f["metrics"]["all"] for f in rep["metrics_per_frame"]]
    assert [f["frame"] for f in rep["metrics_per_frame"]] == [0, 1, 2]
    mean = rep["metrics_mean"]["all"]
    assert mean["bad2"] == pytest.approx(sum(m["bad2"] for m in per_frame) / 3)
    assert "metrics" not in rep  # a stream's accuracy is named as what it is: a mean
    text = summary_text(rep, 1.0, terminal=False)
    assert "accuracy, mean of 3 frames (thresholds in pixels of the GT's resolution)" in text
    row = next(line for line in text.splitlines() if line.startswith("all "))
    assert row.split()[1:4] == [f"{mean['bad2']:.3f}", f"{mean['invalid']:.3f}",
                                f"{mean['totbad']:.3f}"]


def test_run_prints_the_summary_tables(tmp_path, capsys):
    left, right = _pair()
    lp, rp = tmp_path / "l.png", tmp_path / "r.png"
    lp.write_bytes(encode_png(left))
    rp.write_bytes(encode_png(right))
    assert main(["run", "--left", str(lp), "--right", str(rp), "--disparities", str(D),
                 "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert "cycles: {" not in out
    assert "\nwork bound (fps)" in out and "one frame alone, measured (fps)" in out
    nna = next(line for line in out.splitlines() if line.startswith("nna_left "))
    assert nna.split()[:6] == ["nna_left", "nna", "@", "460", "MHz",
                               f"{rep['blocks']['nna_left']['cycles_total']:,}"]


# ---- stereosim eval --mode cycle ---------------------------------------------------------------


def _dataset(tmp_path):
    root = tmp_path / "ds"
    for i, name in enumerate(("Alpha", "Beta")):
        scene = root / name
        scene.mkdir(parents=True)
        left, right = _pair(seed=i)
        (scene / "im0.png").write_bytes(encode_png(left))
        (scene / "im1.png").write_bytes(encode_png(right))
        (scene / "disp0GT.pfm").write_bytes(pfm_bytes(np.full((H, W), 4.0, np.float32)))
    return root


def test_eval_in_cycle_mode_prints_and_keeps_the_timing(tmp_path, capsys):
    root = _dataset(tmp_path)
    assert main(["eval", str(root), "--mode", "cycle", "--disparities", str(D), "--out",
                 str(tmp_path / "ev.json")]) == 0
    out = capsys.readouterr().out
    doc = json.loads((tmp_path / "ev.json").read_text())
    cfg = load_config(overrides={"sva.disparities": D})
    timings = {}
    for i, name in enumerate(("Alpha", "Beta")):
        rep = run(*_pair(seed=i), mode="cycle", config=cfg).report
        timings[name] = eval_timing(rep)
        assert doc["scenes"][name]["timing"] == timings[name]
        assert timings[name]["fps_bound"] == rep["throughput"]["fps_bound"]
        assert timings[name]["frame_ms"] == round(rep["latency"]["frame_ms"], 6)
    frame_ms = [t["frame_ms"] for t in timings.values()]
    assert doc["timing"]["total_frame_ms"] == round(sum(frame_ms), 6)
    assert doc["timing"]["mean"]["frame_ms"] == round(sum(frame_ms) / 2, 6)
    table = out[out.index("[cycle]"):].splitlines()
    assert table[1].split() == ["scene", "fps_bound", "fps_measured", "first_output_us",
                                "frame_ms", "bottleneck"]
    alpha = next(line for line in table if line.startswith("Alpha")).split()
    t = timings["Alpha"]
    assert alpha == ["Alpha", f"{t['fps_bound']:.3f}", f"{t['fps_measured']:.3f}",
                     f"{t['first_output_us']:.3f}", f"{t['frame_ms']:.3f}", t["bottleneck"]]
    total = next(line for line in table if line.startswith("TOTAL")).split()
    assert total == ["TOTAL", "-", "-", "-", f"{sum(frame_ms):.3f}", "-"]
    mean = next(line for line in table if line.startswith("MEAN")).split()
    assert mean[4] == f"{sum(frame_ms) / 2:.3f}" and mean[5] == "-"


def test_eval_in_functional_mode_has_no_timing(tmp_path, capsys):
    root = _dataset(tmp_path)
    assert main(["eval", str(root), "--mode", "functional", "--disparities", str(D),
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert "timing" not in doc and "timing" not in doc["scenes"]["Alpha"]
    rows = [("Alpha", doc["scenes"]["Alpha"]["metrics"], D, None)]
    assert "[cycle]" not in eval_tables(rows, ("bad2",))
    assert eval_document("ds", rows, {})["mean"] == doc["scenes"]["Alpha"]["metrics"]


def test_format_table_text_columns_and_totals():
    rows = [("a", {"x": 1.0, "who": "nna"}), ("b", {"x": 2.5, "who": "sva"})]
    assert format_table(rows, ["x", "who"], totals=["x"]) == (
        "scene      x  who\n"
        "-----  -----  ---\n"
        "a      1.000  nna\n"
        "b      2.500  sva\n"
        "-----  -----  ---\n"
        "MEAN   1.750    -\n"
        "TOTAL  3.500    -\n"
    )


# ---- config show ---------------------------------------------------------------------------------


@pytest.mark.parametrize("saved_with, loaded_with", [("census", "cnn"), ("cnn", "census")])
def test_config_show_leaves_descriptor_defaults_to_the_descriptor(tmp_path, capsys, saved_with,
                                                                  loaded_with):
    assert main(["config", "show", "--descriptor", saved_with]) == 0
    path = tmp_path / "c.toml"
    path.write_text(capsys.readouterr().out)
    text = path.read_text()
    mine = DESCRIPTOR_DEFAULTS[saved_with]
    assert f"# p2 = {mine['p2']}" in text and f"\np2 = {mine['p2']}" not in text
    assert load_config(path).sva.p2 == mine["p2"]
    other = load_config(path, {"nna.descriptor": loaded_with}).sva
    assert (other.p1, other.p2) == (DESCRIPTOR_DEFAULTS[loaded_with]["p1"],
                                    DESCRIPTOR_DEFAULTS[loaded_with]["p2"])


def test_config_show_keeps_penalties_the_user_set(tmp_path, capsys):
    # given by hand, a penalty is pinned (whatever the descriptor's own)
    assert main(["config", "show", "--plain", "--descriptor", "cnn", "--set", "sva.p2=512"]) == 0
    path = tmp_path / "c.toml"
    path.write_text(capsys.readouterr().out)
    assert "\np2 = 512\n" in path.read_text()
    assert load_config(path, {"nna.descriptor": "census"}).sva.p2 == 512
    # p1 was not set: census's own
    assert load_config(path, {"nna.descriptor": "census"}).sva.p1 == \
        DESCRIPTOR_DEFAULTS["census"]["p1"]


# ---- plot ----------------------------------------------------------------------------------------


def _csv(tmp_path, rows):
    path = tmp_path / "results.csv"
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return path


def test_plot_logy_and_readable_time_units(tmp_path, capsys):
    rows = [{"point": i, "status": "ok", "depth": d, "latency.frame_ns": ns, "fps": f}
            for i, (d, ns, f) in enumerate([(1, 16_033_500.0, 10.0), (2, 16_026_700.0, 100.0),
                                            (4, 16_025_400.0, 1000.0)])]
    path = _csv(tmp_path, rows)
    log_png, lin_png = tmp_path / "log.png", tmp_path / "lin.png"
    assert main(["plot", str(path), "--x", "depth", "--y", "fps", "--logy", "--logx",
                 "--png", str(log_png)]) == 0
    assert main(["plot", str(path), "--x", "depth", "--y", "fps", "--png", str(lin_png)]) == 0
    assert log_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert log_png.read_bytes() != lin_png.read_bytes()
    # ns drawn in ms: 16,033,500 ns = 16.0335 ms
    factor, label = time_scale("latency.frame_ns", [r["latency.frame_ns"] for r in rows])
    assert (factor, label) == (1e-6, "latency.frame_ns (in ms)")
    assert time_scale("x.time_us", [5.0]) == (1.0, "x.time_us")
    assert time_scale("a.ns", [300.0]) == (1.0, "a.ns (in ns)")
    rows[0]["fps"] = 0.0
    with pytest.raises(InputError, match="--logy needs positive values"):
        plot_xy(rows, "depth", "fps", tmp_path / "bad.png", logy=True)
    capsys.readouterr()


def test_pareto_points_are_labelled_by_their_configuration():
    rows = [{"point": "0", "nna.stereo_submodules": 2, "fifo.nna_to_merge_depth": 64,
             "sva.paths": 4},
            {"point": "1", "nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 64,
             "sva.paths": 4},
            {"point": "1", "nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 64,
             "sva.paths": 4},
            {"point": "2", "nna.stereo_submodules": 4, "fifo.nna_to_merge_depth": 512,
             "sva.paths": 4}]
    keys = ["nna.stereo_submodules", "fifo.nna_to_merge_depth", "sva.paths"]
    assert point_labels(rows, keys) == {
        "0": "stereo_submodules=2, nna_to_merge_depth=64",
        "1": "stereo_submodules=4, nna_to_merge_depth=64",
        "2": "stereo_submodules=4, nna_to_merge_depth=512",
    }
    assert point_labels(rows[:1], keys) == {"0": "point 0"}


def test_eval_prints_the_dense_scores_beside_the_sparse_ones(tmp_path, capsys):
    """The paper's results table scores both the map as computed and the map made dense: eval
    prints a dense table per mask whose cells are the report's dense_* metrics."""
    root = _dataset(tmp_path)
    assert main(["eval", str(root), "--mode", "functional", "--disparities", str(D),
                 "--json"]) == 0
    metrics = json.loads(capsys.readouterr().out)["scenes"]["Alpha"]["metrics"]
    text = eval_tables([("Alpha", metrics, D, None)], ("bad2",))
    lines = text.splitlines()
    head = lines.index(next(line for line in lines if line.startswith("[all, dense]")))
    assert lines[head + 1].split() == ["scene", "dense_bad0.5", "dense_bad1", "dense_bad2",
                                       "dense_bad4", "dense_avgerr", "dense_rms"]
    alpha = lines[head + 3].split()
    m = metrics["all"]
    assert alpha == ["Alpha", *(f"{m[k]:.3f}" for k in ("dense_bad0.5", "dense_bad1",
                                                        "dense_bad2", "dense_bad4",
                                                        "dense_avgerr", "dense_rms"))]
    assert m["invalid"] > 0  # something was filled


# ---- chip totals, the camera's rate and what busy and work mean (issue 46, items 3 and 6) ----


def _rows(text: str) -> str:
    return " ".join(text.split())  # the plain summary wraps long rows at 100 columns


def test_the_summary_quotes_the_chips_sram_with_every_submodule(cycle_report):
    from stereosim.sim.cycle.figures import chip_sram

    sram = cycle_report["architecture"]["chip_sram"]
    cfg = load_config(overrides={"sva.disparities": D})
    assert sram == chip_sram(build_plan(cfg, (H, W)))
    text = _rows(summary_text(cycle_report, 1.0, terminal=False))
    assert (f"SRAM {sram['total'] / 1e6:,.2f} Mbit ({sram['total']:,} bits): nna_stereo "
            f"{sram['by_block']['nna_stereo'] / 1e6:,.2f}") in text
    assert f"each of the {cfg.nna.submodules} NNA submodules {sram['nna_per_submodule']:,}" in text


def test_the_summary_gives_the_lent_networks_rate_and_dram_load():
    from stereosim.sim.cli import PRESETS

    over = {"sva.disparities": D, "nna.lent_submodules": 4,
            "nna.lent_network": str(PRESETS / "lent" / "backbone224.toml")}
    rep = run(*_pair(), mode="functional", overrides=over).report
    lent = rep["lent_network"]
    text = _rows(summary_text(rep, 1.0, terminal=False))
    assert (f"lent network {lent['file']}: {lent['fps']:,.3f} fps (at most "
            f"{lent['fps_max']:,.3f}) on {lent['submodules_used']} of 4 lent submodules; DRAM "
            f"{lent['dram_bytes_per_frame']['total']:,} bytes a frame") in text


def test_a_lone_frame_faster_than_its_camera_is_explained(cycle_report):
    """A camera's rate includes its vertical blanking, which one frame alone skips: the summary
    says so when the lone frame measures faster than the camera, and not otherwise."""
    measured = cycle_report["throughput"]["fps_measured"]
    slow = {**cycle_report, "throughput": {**cycle_report["throughput"],
                                           "camera_fps": measured * 0.97}}
    text = _rows(summary_text(slow, 1.0, terminal=False))
    assert f"one frame alone measures {measured:,.1f} fps, above the camera's" in text
    assert "skips the vertical blanking" in text
    fast = {**cycle_report, "throughput": {**cycle_report["throughput"],
                                           "camera_fps": measured * 1.5}}
    assert "above the camera's" not in summary_text(fast, 1.0, terminal=False)


def test_a_camera_fed_report_carries_the_cameras_rate():
    over = {"sva.disparities": D, "source.kind": "camera", "source.frame_buffers": 2,
            "source.on_overflow": "drop_frame"}
    rep = run(*_pair(), mode="cycle", overrides=over).report
    cfg = load_config(overrides=over)
    raster = (H + cfg.source.camera_vblank) * (W + cfg.source.camera_hblank)
    assert rep["throughput"]["camera_fps"] == round(cfg.clocks.camera_mhz * 1e6 / raster, 3)
    assert "camera_fps" not in run(*_pair(), mode="cycle", overrides={"sva.disparities": D}
                                   ).report["throughput"]


def test_the_blocks_table_says_what_busy_and_work_mean(cycle_report):
    text = _rows(summary_text(cycle_report, 1.0, terminal=False))
    assert "busy %: cycles the block held work (the SVA: any word in its pipeline" in text
    assert "work ms: the cycles its critical resource is occupied" in text
