"""Sweeps (sim/sweep.py) on a real Dask LocalCluster, the sweep file checks, the results file
(appended under the folder lock, torn lines, full disks, the final order), the point cap, Ctrl-C,
exit statuses, Dask's chatter and the plots."""

import io
import logging
import os
import resource
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import distributed
import pytest

from stereosim.core.config import load_config
from stereosim.core.datasets import shared_data_dir
from stereosim.core.errors import ConfigError
from stereosim.sim.cli import main
from stereosim.sim.cycle.area import chip_area
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.plot import (
    pareto_data,
    pareto_front,
    pareto_plot,
    rate_gaps,
    sweep_pareto,
    sweep_plots,
    xy_data,
)
from stereosim.sim.sweep import (
    MAX_POINTS,
    Task,
    area_columns,
    load_sweep,
    run_sweep,
    run_task,
    synthetic_pair,
)
from stereosim.sim.sweep_results import (
    CSV_NAME,
    GUIDE_NAME,
    LEAD_COLUMNS,
    append_rows,
    finish_results,
    read_rows,
    write_rows,
)
from stereosim.sim.whatif_cli import sweep_summary

ROOT = Path(__file__).resolve().parents[2]

FOUR_POINTS = """
mode = "cycle"
scenes = ["64x24"]
[set]
"sva.paths" = 2
[grid]
"sva.disparities" = [16, 32, 48, 128]   # 128 is not below the width 64: that point fails
"""


def _write(tmp_path, text, name="sweep.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
        silence_logs=logging.CRITICAL + 10,
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


class _CountingClient:
    """The real client, counting the tasks submitted to it and, when given the results file,
    how many rows it held at each submission."""

    def __init__(self, client, results: Path | None = None):
        self.client = client
        self.submitted = []
        self.rows_at_submit = []
        self.results = results

    def submit(self, fn, task, **kw):
        self.submitted.append(task)
        if self.results is not None:
            self.rows_at_submit.append(len(read_rows(self.results)))
        return self.client.submit(fn, task, **kw)

    def __getattr__(self, name):
        return getattr(self.client, name)


def test_four_point_sweep_on_two_workers_survives_a_failure_and_resumes(tmp_path, client):
    assert len(client.scheduler_info()["workers"]) == 2
    assert all(addr.startswith("tcp://127.0.0.1:") for addr in client.scheduler_info()["workers"])
    sweep = load_sweep(_write(tmp_path, FOUR_POINTS))
    out = tmp_path / "out"
    counting = _CountingClient(client)
    counts = run_sweep(sweep, out, client=counting, progress=False)
    assert counts == {"tasks": 4, "skipped": 0, "ok": 3, "error": 1}
    assert len(counting.submitted) == 4
    rows = read_rows(out / CSV_NAME)
    assert [r["point"] for r in rows] == ["0", "1", "2", "3"]  # plan order
    assert [r["sva.disparities"] for r in rows] == ["16", "32", "48", "128"]
    assert [r["status"] for r in rows] == ["ok", "ok", "ok", "error"]
    assert "not smaller than the image width 64" in rows[3]["error"]
    for r in rows[:3]:
        assert float(r["throughput.fps_bound"]) > 0
        assert r["config.sva.disparities"] == r["sva.disparities"]
        assert r["config.sva.paths"] == "2"
        assert int(r["cycles.last_output.sva"]) > int(r["cycles.first_output.sva"])
        assert r["estimate.throughput.fps_bound"] == r["throughput.fps_bound"]
    before = (out / CSV_NAME).read_bytes()
    # resume: only the failed point is submitted again; finished rows stay byte for byte
    counting = _CountingClient(client)
    counts = run_sweep(sweep, out, client=counting, progress=False)
    assert counts == {"tasks": 4, "skipped": 3, "ok": 0, "error": 1}
    assert [t.point for t in counting.submitted] == [3]
    assert (out / CSV_NAME).read_bytes() == before
    # the same sweep into a fresh folder, one task at a time (another completion order): the
    # same bytes (no wall-clock figure in a row, one fixed column and row order)
    run_sweep(sweep, tmp_path / "again", client=client, progress=False, in_flight=1)
    assert (tmp_path / "again" / CSV_NAME).read_bytes() == before


def _failed(task):
    """The row a failed run of ``task`` gives."""
    return {"point": task.point, "scene": task.scene, "point_id": task.point_id,
            **task.overrides, "status": "error", "error": "boom"}


def test_rows_appended_in_any_order_end_in_plan_order_byte_for_byte(tmp_path):
    sweep = load_sweep(_write(tmp_path, FOUR_POINTS.replace('"64x24"', '"64x24", "80x16"')
                              .replace('"cycle"', '"estimate"')))
    assert [(t.point, t.scene) for t in sweep.tasks][:3] == [(0, "64x24"), (0, "80x16"),
                                                             (1, "64x24")]
    rows = [run_task(t) for t in sweep.tasks]
    assert [r["status"] for r in rows] == ["ok"] * 6 + ["error"] * 2
    write_rows(tmp_path / "plan.csv", rows, sweep.axes)
    expected = (tmp_path / "plan.csv").read_bytes()
    orders = {"reversed": rows[::-1], "shuffled": [rows[i] for i in (5, 0, 7, 2, 6, 1, 3, 4)]}
    for name, order in orders.items():
        path = tmp_path / name / CSV_NAME
        path.parent.mkdir()
        for row in order:
            append_rows(path, [row], sweep.axes)
        assert read_rows(path) != read_rows(tmp_path / "plan.csv")
        finish_results(path, sweep.tasks, sweep.axes)
        assert path.read_bytes() == expected, name
    # a point that failed, then succeeded on a rerun (or the other way round) keeps one row,
    # the ok one; a point that failed twice keeps its last error
    path = tmp_path / "retried" / CSV_NAME
    path.parent.mkdir()
    append_rows(path, [_failed(sweep.tasks[0])] + rows[:3], sweep.axes)
    append_rows(path, rows[3:] + [_failed(sweep.tasks[1]), {**rows[7], "error": "again"}],
                sweep.axes)
    finish_results(path, sweep.tasks, sweep.axes)
    got = read_rows(path)
    assert [r["point_id"] for r in got] == [t.point_id for t in sweep.tasks]
    assert [r["status"] for r in got] == ["ok"] * 6 + ["error"] * 2
    assert got[7]["error"] == "again"


def test_grid_and_zip_make_the_cartesian_product(tmp_path):
    sweep = load_sweep(_write(tmp_path, """
mode = "estimate"
scenes = ["128x32"]
[grid]
"sva.paths" = [2, 4]
"sva.disparities" = [16, 32, 64]
[zip]
"fifo.nna_to_sva_depth" = [8, 64]
"fifo.source_to_nna_depth" = [4, 16]
"""))
    assert len(sweep.points) == 2 * 3 * 2
    assert sweep.points[0] == {"sva.paths": 2, "sva.disparities": 16,
                               "fifo.nna_to_sva_depth": 8, "fifo.source_to_nna_depth": 4}
    assert sweep.points[1]["fifo.nna_to_sva_depth"] == 64
    assert sweep.points[2]["sva.disparities"] == 32
    row = run_task(sweep.tasks[0])
    assert row["status"] == "ok", row["error"]
    assert row["config.sva.disparities"] == 16 and "cycles.total.nna" not in row


def test_a_scene_with_gt_gets_accuracy_columns():
    data = shared_data_dir()
    if data is None or not (data / "middlebury2014_trainingQ" / "Teddy").is_dir():
        pytest.skip("needs ../shared/data/middlebury2014_trainingQ/Teddy (absent)")

    task = Task(0, 0, "Teddy", str(data / "middlebury2014_trainingQ" / "Teddy"),
                {"sva.paths": 2}, None, "functional")
    row = run_task(task)
    assert row["status"] == "ok", row["error"]
    assert 0 < row["metrics.nonocc.totbad"] < 100
    assert row["config.sva.disparities"] == 64  # from calib.txt (ndisp 64 at Q size)


def test_synthetic_pairs_are_deterministic_and_shifted():
    left, right = synthetic_pair(20, 64)
    again, _ = synthetic_pair(20, 64)
    assert (left == again).all() and left.shape == (20, 64)
    assert (left[:, :-8] == right[:, 8:]).all()


BAD_SWEEPS = {
    "not toml": "[grid\n",
    "unknown key": '[grid]\n"sva.pathz" = [1, 2]\n',
    "bad value": '[grid]\n"sva.paths" = [2, 9]\n',
    "empty grid": 'scenes = ["64x24"]\n[grid]\n',
    "empty list": '[grid]\n"sva.paths" = []\n',
    "unequal zip": '[zip]\n"sva.paths" = [1, 2]\n"sva.p1" = [5]\n',
    "unknown entry": 'modes = "cycle"\n[grid]\n"sva.paths" = [1]\n',
    "bad scene": 'scenes = ["no/such/folder"]\n[grid]\n"sva.paths" = [1]\n',
    "bad mode": 'mode = "fast"\n[grid]\n"sva.paths" = [1]\n',
}


@pytest.mark.parametrize("case", sorted(BAD_SWEEPS))
def test_bad_sweep_files_are_one_line_exit_2_and_write_nothing(case, tmp_path, capsys):
    path = _write(tmp_path, BAD_SWEEPS[case])
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: ") and err.count("\n") == 1, err
    assert not out.exists()


def _results(tmp_path):
    sweep = load_sweep(_write(tmp_path, """
mode = "estimate"
scenes = ["256x64"]
[grid]
"nna.stereo_submodules" = [2, 4, 6]
"nna.descriptor" = ["census", "cnn"]
"""))
    rows = [run_task(t) for t in sweep.tasks]

    write_rows(tmp_path / CSV_NAME, rows, sweep.axes)
    return tmp_path / CSV_NAME, sweep


def test_plot_is_byte_identical_across_runs(tmp_path, capsys):
    csv_path, _ = _results(tmp_path)
    args = ["plot", str(csv_path), "--x", "nna.stereo_submodules", "--y", "throughput.fps_bound",
            "--hue", "nna.descriptor"]
    assert main([*args, "--png", str(tmp_path / "a.png")]) == 0
    assert main([*args, "--png", str(tmp_path / "b.png")]) == 0
    a = (tmp_path / "a.png").read_bytes()
    assert a[:8] == b"\x89PNG\r\n\x1a\n" and a == (tmp_path / "b.png").read_bytes()


def test_plot_of_a_missing_column_is_one_line_exit_2(tmp_path, capsys):
    csv_path, _ = _results(tmp_path)
    capsys.readouterr()
    png = tmp_path / "x.png"
    assert main(["plot", str(csv_path), "--x", "nope", "--y", "throughput.fps_bound",
                 "--png", str(png)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: column 'nope'") and err.count("\n") == 1
    assert not png.exists()


def test_built_in_plots(tmp_path):

    csv_path, sweep = _results(tmp_path)
    written = sweep_plots(read_rows(csv_path), sweep.axes, tmp_path)
    assert [p.name for p in written] == ["fps_vs_submodules.png", "pareto_sram_fps.png",
                                         "pareto_area_fps.png"]
    assert all(p.stat().st_size > 1000 for p in written)


def test_a_rows_area_columns_are_chip_areas(tmp_path):
    """area_mm2, logic_mm2 and sram_mm2 of a row are chip_area's totals for its point."""
    csv_path, sweep = _results(tmp_path)
    rows = read_rows(csv_path)
    assert len(rows) == len(sweep.tasks) == 6
    for task, row in zip(sweep.tasks, rows, strict=True):
        cfg = load_config(task.config_path, dict(task.overrides))
        t = chip_area(build_plan(cfg, (64, 256)), cfg.power.node)["totals"]
        assert float(row["area_mm2"]) == pytest.approx(t["chip_mm2"], rel=1e-12)
        assert float(row["logic_mm2"]) == pytest.approx(t["logic_mm2"], rel=1e-12)
        assert float(row["sram_mm2"]) == pytest.approx(t["sram_mm2"], rel=1e-12)
        assert "power_mw" not in row  # no power section in an estimate's report
    assert len({r["area_mm2"] for r in rows}) > 1  # the column follows the configuration


def test_area_columns_at_a_node_without_sram_figures_are_empty():
    """7 nm has no SRAM macro table: area_mm2 and sram_mm2 are empty, logic_mm2 a number;
    power_mw comes from a power section's average where a report has one."""
    cfg = load_config(None, {"power.node": "7nm"})
    area = chip_area(build_plan(cfg, (64, 256)), "7nm")
    cols = area_columns(area)
    assert cols == {"area_mm2": "", "logic_mm2": area["totals"]["logic_mm2"], "sram_mm2": ""}
    assert cols["logic_mm2"] > 0
    assert area_columns(area, {"average_power_mw": 12.5})["power_mw"] == 12.5


def test_the_pareto_view_takes_area_as_its_axis(tmp_path, capsys):
    csv_path, _ = _results(tmp_path)
    png = tmp_path / "area.png"
    assert main(["plot", str(csv_path), "--pareto", "--x", "area_mm2", "--y",
                 "throughput.fps_bound", "--png", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = read_rows(csv_path)
    data = pareto_data(rows, sram="area_mm2", fps="throughput.fps_bound")
    assert sorted(p.sram for p in data.points) == sorted(
        {r["point"]: float(r["area_mm2"]) for r in rows}.values())


# The 720p study of docs/whatif.md (nna.stereo_submodules 2/4/6 x fifo.nna_to_merge_depth
# 64/640) on a small frame: 8 entries are too few for 100-column tiles (the estimate needs 66 for
# 6), 300 are enough.
MERGE_STUDY = """
mode = "cycle"
scenes = ["300x40"]
[set]
"nna.descriptor" = "cnn"
"sva.disparities" = 32
[grid]
"nna.stereo_submodules" = [2, 4, 6]
"fifo.nna_to_merge_depth" = [8, 300]
"""


def _boxes_apart(boxes) -> bool:
    return not any(a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]
                   for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_a_tiles_and_merge_depths_study_plots_and_ranks_the_measured_rate(tmp_path, client):
    sweep = load_sweep(_write(tmp_path, MERGE_STUDY))
    out = tmp_path / "out"
    run_sweep(sweep, out, client=client, progress=False)
    rows = read_rows(out / CSV_NAME)
    assert [r["status"] for r in rows] == ["ok"] * 6
    written = sweep_plots(rows, sweep.axes, out)
    assert [p.name for p in written] == ["fps_vs_submodules.png", "pareto_sram_fps.png",
                                         "pareto_area_fps.png", "pareto_power_fps.png"]
    # a cycle run's report has a power section: its average power is the row's power_mw
    assert all(float(r["power_mw"]) > 0 for r in rows)
    power = sweep_pareto(rows, sweep.axes, cost="power_mw")
    assert {p.point: p.sram for p in power.points} == {r["point"]: float(r["power_mw"])
                                                       for r in rows}
    measured = {r["point"]: float(r["throughput.fps_measured"]) for r in rows}
    bound = {r["point"]: float(r["throughput.fps_bound"]) for r in rows}
    point = {(r["nna.stereo_submodules"], r["fifo.nna_to_merge_depth"]): r["point"]
             for r in rows}
    # six tiles behind 8-deep merge FIFOs take turns: far below their work bound
    shallow, deep = point["6", "8"], point["6", "300"]
    assert measured[shallow] < 0.6 * bound[shallow] and bound[shallow] == bound[deep]
    # the Pareto view plots the measured rate and rings the points optimal on it
    view = sweep_pareto(rows, sweep.axes)
    assert view.fps == "throughput.fps_measured"
    assert {p.point: p.fps for p in view.points} == measured
    front = pareto_front([(p.sram, measured[p.point], 0.0) for p in view.points])
    assert [p.optimal for p in view.points] == front
    assert not next(p for p in view.points if p.point == shallow).optimal
    # fps vs submodules: the measured rate, so the two depths part at 4 and 6 submodules
    lines = xy_data(rows, "nna.stereo_submodules", "throughput.fps_measured",
                    hue="fifo.nna_to_merge_depth")
    assert lines["8"][-1] == (6.0, measured[shallow]) and lines["300"][-1] == (6.0, measured[deep])
    # the labels (one per place: the two 2-submodule points coincide) overlap no other label
    drawn = pareto_plot(rows, tmp_path / "p.png", fps=view.fps, label_keys=sweep.axes)
    assert len(drawn.label_boxes) == 5 and _boxes_apart(drawn.label_boxes)
    # the summary names the best points by their swept keys, and notes the gap once
    summary = sweep_summary(rows, sweep.axes)
    assert summary[0] == ("best points (Pareto-optimal in chip SRAM, throughput.fps_measured "
                          f"(measured, one frame alone)): {sum(front)} of 6")
    assert summary[1].startswith(f"  stereo_submodules=6, nna_to_merge_depth=300: "
                                 f"{measured[deep]:,.1f} fps (bound {bound[deep]:,.1f}), SRAM ")
    notes = [line for line in summary if line.startswith("note: ")]
    worst = rate_gaps(rows)[0]
    assert len(notes) == 1 and f"{len(rate_gaps(rows))} of 6 runs" in notes[0]
    assert (f"stereo_submodules={worst['nna.stereo_submodules']}, nna_to_merge_depth="
            f"{worst['fifo.nna_to_merge_depth']} (300x40) ran at") in notes[0]
    # and the guide to the columns lies beside the CSV
    assert "`throughput.fps_measured` | frames/s, **measured**" in (out / GUIDE_NAME).read_text()


def test_pareto_labels_never_overlap_crowded_points_get_numbers_and_a_key(tmp_path):
    def rows(n, spread):
        return [{"point": str(i), "status": "ok", "sram_bits": 1000 + spread * (i % 5),
                 "throughput.fps_bound": 50 + spread * (i // 5), "nna.macs": 288 + i,
                 "sva.paths": 1 + i % 4, "fifo.nna_to_merge_depth": 64 * (i + 1)}
                for i in range(n)]

    keys = ["nna.macs", "sva.paths", "fifo.nna_to_merge_depth"]
    few = pareto_plot(rows(5, 100), tmp_path / "few.png", label_keys=keys)
    assert few.key == [] and len(few.label_boxes) == 5 and _boxes_apart(few.label_boxes)
    crowd = pareto_plot(rows(40, 1), tmp_path / "crowd.png", label_keys=keys)
    assert len(crowd.label_boxes) == 40 and _boxes_apart(crowd.label_boxes)
    assert crowd.key[5] == "5: macs=293, paths=2, nna_to_merge_depth=384"


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_sweep_counts_its_runs_on_a_terminal_only(tmp_path, client, monkeypatch):
    sweep = load_sweep(_write(tmp_path, _estimate([16, 32])))
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    for name, stream, progress, shown in (("tty", _Terminal(), True, True),
                                          ("piped", io.StringIO(), True, False),
                                          ("quiet", _Terminal(), False, False)):
        monkeypatch.setattr(sys, "stderr", stream)
        run_sweep(sweep, tmp_path / name, client=client, progress=progress)
        assert ("sweep: 100%" in stream.getvalue() and "2/2" in stream.getvalue()) == shown, name
        if not shown:
            assert stream.getvalue() == "", name


# ----------------------------------------------------------------------------------------------
# helpers for the command in a subprocess (this checkout's sim, whatever is installed)


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    return env


def _stereosim(args, cwd, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "stereosim.sim.cli", *map(str, args)], check=False,
                          cwd=cwd,
                          env=_env(), capture_output=True, text=True, timeout=180, **kw)


def _estimate(disparities, scene="64x24", extra=""):
    return (f'mode = "estimate"\nscenes = ["{scene}"]\n[grid]\n'
            f'"sva.disparities" = {list(disparities)}\n{extra}')


# ----------------------------------------------------------------------------------------------
# 1. sweeps sharing an --out keep each other's rows


SWEEP_A = _estimate([16, 32], extra='"sva.paths" = [2, 4]\n')
SWEEP_B = ('mode = "estimate"\nscenes = ["160x16"]\n[grid]\n'
           '"fifo.nna_to_sva_depth" = [8, 16, 32]\n')


def test_a_sweep_that_runs_meanwhile_keeps_its_rows_in_a_shared_out(tmp_path, client):
    """Sweep B runs from start to end after A has read results.csv and before A's first row:
    A appends after B's rows instead of writing its own view, and B's rows survive A's final
    rewrite (after A's, in file order)."""
    a = load_sweep(_write(tmp_path, SWEEP_A, "a.toml"))
    b = load_sweep(_write(tmp_path, SWEEP_B, "b.toml"))
    out = tmp_path / "out"

    class _BFirst(_CountingClient):
        def submit(self, fn, task, **kw):
            if not self.submitted:
                assert run_sweep(b, out, client=client, progress=False)["ok"] == 3
            return super().submit(fn, task, **kw)

    assert run_sweep(a, out, client=_BFirst(client), progress=False)["ok"] == 4
    ids_a, ids_b = [t.point_id for t in a.tasks], [t.point_id for t in b.tasks]
    rows = read_rows(out / CSV_NAME)
    assert [r["point_id"] for r in rows] == ids_a + ids_b
    assert {r["status"] for r in rows} == {"ok"}
    assert [r["fifo.nna_to_sva_depth"] for r in rows[4:]] == ["8", "16", "32"]
    header = (out / CSV_NAME).read_text().split("\n", 1)[0].split(",")
    assert header[:7] == [*LEAD_COLUMNS, "sva.disparities", "sva.paths"]
    assert header[7:] == sorted(header[7:])
    # B again: nothing to run, its rows now first
    assert run_sweep(b, out, client=client, progress=False)["skipped"] == 3
    assert [r["point_id"] for r in read_rows(out / CSV_NAME)] == ids_b + ids_a


def test_two_sweep_processes_into_one_out_lose_no_row(tmp_path):
    """Two `stereosim sweep` processes at once on one --out (the folder lock across processes):
    every row of both is there, once."""
    depths = list(range(8, 28))
    files = [_write(tmp_path, _estimate([16], extra=f'"fifo.nna_to_sva_depth" = {depths}\n'),
                    "a.toml"),
             _write(tmp_path, _estimate([32], extra=f'"fifo.nna_to_sva_depth" = {depths}\n'),
                    "b.toml")]
    procs = [subprocess.Popen([sys.executable, "-m", "stereosim.sim.cli", "sweep", str(f),
                               "--out", "out", "--quiet", "--workers", "1"],
                              cwd=tmp_path, env=_env(),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for f in files]
    for proc in procs:
        _, err = proc.communicate(timeout=180)
        assert proc.returncode == 0 and err == "", err
    rows = read_rows(tmp_path / "out" / CSV_NAME)
    expected = [t.point_id for f in files for t in load_sweep(f).tasks]
    assert sorted(r["point_id"] for r in rows) == sorted(expected)
    assert len(rows) == 40 and {r["status"] for r in rows} == {"ok"}


# ----------------------------------------------------------------------------------------------
# 2. the point cap


def test_a_billion_point_grid_is_refused_before_it_is_expanded(tmp_path, capsys):
    values = list(range(1, 1001))
    path = _write(tmp_path, 'mode = "estimate"\n[grid]\n'
                  f'"fifo.nna_to_sva_depth" = {values}\n"fifo.source_to_nna_depth" = {values}\n'
                  f'[zip]\n"fifo.sva_to_sink_depth" = {values}\n"sva.paths" = {[2] * 1000}\n')
    out = tmp_path / "out"
    t0 = time.perf_counter()
    assert main(["sweep", str(path), "--out", str(out)]) == 2
    assert time.perf_counter() - t0 < 5  # 10^9 points were counted, never listed
    err = capsys.readouterr().err
    assert err == (f"stereosim: error: sweep file {path} has 1,000,000,000 points (1000 x 1000 x "
                   "1000 [zip]), more than the cap of 10,000: split it, or raise the cap with "
                   "--max-points 1000000000\n")
    assert main(["sweep", str(path), "--out", str(out), "--max-points", "999999999"]) == 2
    assert "more than the cap of 999,999,999" in capsys.readouterr().err
    assert main(["sweep", str(path), "--out", str(out), "--max-points", "0"]) == 2
    assert capsys.readouterr().err == "stereosim: error: --max-points must be at least 1; got 0\n"
    assert not out.exists()


def test_the_cap_is_max_points_by_default_and_max_points_raises_it(tmp_path, capsys):
    assert MAX_POINTS == 10_000
    path = _write(tmp_path, 'mode = "estimate"\nscenes = ["64x24"]\n[grid]\n'
                  f'"fifo.nna_to_sva_depth" = {list(range(1, 101))}\n'
                  f'"fifo.source_to_nna_depth" = {list(range(1, 102))}\n')
    with pytest.raises(ConfigError, match=r"has 10,100 points \(100 x 101\), more than the cap"):
        load_sweep(path)
    assert len(load_sweep(path, max_points=10_100).tasks) == 10_100
    two = _write(tmp_path, _estimate([16, 32]), "two.toml")
    out = tmp_path / "out"
    assert main(["sweep", str(two), "--out", str(out), "--max-points", "1"]) == 2
    assert "has 2 points (2), more than the cap of 1" in capsys.readouterr().err
    assert main(["sweep", str(two), "--out", str(out), "--max-points", "2", "--quiet",
                 "--workers", "1"]) == 0
    assert [r["status"] for r in read_rows(out / CSV_NAME)] == ["ok", "ok"]


# ----------------------------------------------------------------------------------------------
# 3. rows appended, bounded submission


def test_rows_are_appended_as_tasks_finish_and_submission_is_bounded(tmp_path, client):
    """One task in flight: each submission after the first comes after one more row, appended
    to the same file (same inode, growing by a row), never a rewrite of the whole file."""
    path = _write(tmp_path, _estimate([16, 32, 48], extra='"sva.paths" = [2, 4]\n'))
    sweep = load_sweep(path)
    out = tmp_path / "out"
    seen = []

    class _Watching(_CountingClient):
        def submit(self, fn, task, **kw):
            if (out / CSV_NAME).exists():
                st = (out / CSV_NAME).stat()
                seen.append((st.st_ino, st.st_size))
            return super().submit(fn, task, **kw)

    watching = _Watching(client, out / CSV_NAME)
    run_sweep(sweep, out, client=watching, progress=False, in_flight=1)
    assert watching.rows_at_submit == [0, 1, 2, 3, 4, 5]
    assert len(seen) == 5 and len({ino for ino, _ in seen}) == 1
    sizes = [size for _, size in seen]
    assert sizes == sorted(set(sizes))
    assert (out / CSV_NAME).read_bytes().count(b"\n") == 7


@pytest.mark.parametrize("in_flight, most", [(3, 3), (None, 8)])
def test_at_most_in_flight_tasks_are_outstanding(tmp_path, client, in_flight, most):
    """In flight = submitted and not yet written; by default 4 per worker thread (2 here)."""
    sweep = load_sweep(_write(tmp_path, _estimate([16], extra='"fifo.nna_to_sva_depth" = '
                                                  f'{list(range(8, 20))}\n')))
    out = tmp_path / "out"
    counting = _CountingClient(client, out / CSV_NAME)
    assert run_sweep(sweep, out, client=counting, progress=False, in_flight=in_flight)["ok"] == 12
    outstanding = [k + 1 - rows for k, rows in enumerate(counting.rows_at_submit)]
    assert len(outstanding) == 12 and max(outstanding) == most, outstanding


# ----------------------------------------------------------------------------------------------
# the results file itself


def test_a_torn_last_line_is_ignored_and_cut_by_the_next_append(tmp_path):
    sweep = load_sweep(_write(tmp_path, _estimate([16, 32, 48])))
    rows = [run_task(t) for t in sweep.tasks]
    path = tmp_path / CSV_NAME
    append_rows(path, rows[:1], sweep.axes)
    whole = path.read_bytes()
    with path.open("ab") as f:
        f.write(b"1,64x24,ok,,0e7166461db8bf35,32,398")  # a write cut short
    assert [r["point"] for r in read_rows(path)] == ["0"]
    append_rows(path, rows[1:], sweep.axes)
    data = path.read_bytes()
    assert data.startswith(whole) and data.endswith(b"\n") and data.count(b"\n") == 4
    assert [r["point"] for r in read_rows(path)] == ["0", "1", "2"]
    assert read_rows(path)[1]["point_id"] == sweep.tasks[1].point_id
    # a torn header: the file counts as empty, and the next append starts it again
    path.write_bytes(whole[:40])
    assert read_rows(path) == []
    append_rows(path, rows[:1], sweep.axes)
    assert path.read_bytes() == whole


def test_a_row_with_new_columns_rewrites_the_file_from_a_fresh_read(tmp_path):
    sweep = load_sweep(_write(tmp_path, _estimate([16, 128])))
    ok, failed = (run_task(t) for t in sweep.tasks)
    assert (ok["status"], failed["status"]) == ("ok", "error")
    path = tmp_path / CSV_NAME
    append_rows(path, [failed], sweep.axes)  # few columns
    other = {"point": 7, "scene": "elsewhere", "status": "ok", "error": "", "point_id": "x",
             "zz.other": 1.5}
    append_rows(path, [other], ["zz.other"])  # another sweep's row, its own column
    inode = path.stat().st_ino
    append_rows(path, [ok], sweep.axes)  # every report column: the one rewrite
    assert path.stat().st_ino != inode
    got = read_rows(path)
    assert [r["point_id"] for r in got] == [failed["point_id"], "x", ok["point_id"]]
    assert got[1]["zz.other"] == "1.5" and got[1]["throughput.fps_bound"] == ""
    assert float(got[2]["throughput.fps_bound"]) > 0 and got[0]["error"] == failed["error"]
    header = path.read_text().split("\n", 1)[0].split(",")
    assert header[:6] == [*LEAD_COLUMNS, "sva.disparities"] and header[6:] == sorted(header[6:])
    inode = path.stat().st_ino
    append_rows(path, [ok], sweep.axes)  # the header has every column now: an append
    assert path.stat().st_ino == inode and len(read_rows(path)) == 4


def test_a_full_disk_cuts_the_file_back_to_its_last_whole_row(tmp_path):
    """The file-size limit (RLIMIT_FSIZE) makes the 4th row's write fall short, as a full disk
    does: the write is undone, the command ends with one line, the 3 rows before stay whole."""
    path = _write(tmp_path, _estimate([16, 32, 48], extra='"sva.paths" = [2, 4]\n'))
    sweep = load_sweep(path)
    write_rows(tmp_path / "ref.csv", [run_task(t) for t in sweep.tasks], sweep.axes)
    lines = (tmp_path / "ref.csv").read_bytes().split(b"\n")
    limit = sum(len(line) + 1 for line in lines[:4]) + len(lines[4]) // 2

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    done = _stereosim(["sweep", path, "--out", "out", "--quiet", "--workers", "1"], tmp_path,
                      preexec_fn=small_files)
    csv_path = tmp_path / "out" / CSV_NAME
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith(f"stereosim: error: cannot append to {Path('out') / CSV_NAME}"
                                  " (only ") and done.stderr.count("\n") == 1, done.stderr
    assert "free some space or write elsewhere" in done.stderr
    data = csv_path.read_bytes()
    rows = read_rows(csv_path)
    assert data.endswith(b"\n") and data.count(b"\n") == 4 and len(rows) == 3
    assert all(r["status"] == "ok" and float(r["throughput.fps_bound"]) > 0 for r in rows)


# ----------------------------------------------------------------------------------------------
# 4-5. exit status, and nothing from Dask on stderr


@pytest.fixture
def port_8787_taken():
    """Dask's default HTTP port held, so Dask warns if it tries to use it."""
    sock = socket.socket()
    try:
        sock.bind(("0.0.0.0", 8787))
        sock.listen()
    except OSError:
        pass  # someone else holds it already: just as good
    yield
    sock.close()


def test_a_quiet_sweep_writes_nothing_on_stderr_and_failures_exit_2(tmp_path, port_8787_taken):
    good = _write(tmp_path, _estimate([16, 32]), "good.toml")
    done = _stereosim(["sweep", good, "--out", "good", "--quiet", "--workers", "2"], tmp_path)
    assert (done.returncode, done.stderr) == (0, "")
    assert done.stdout.startswith("2 runs (2 points x 1 scenes): 0 already done, 2 ok, 0 failed")
    assert f"columns: {GUIDE_NAME} beside it says what each is)" in done.stdout
    assert (tmp_path / "good" / GUIDE_NAME).is_file()
    bad = _write(tmp_path, _estimate([128, 256]), "bad.toml")  # neither D is below 64
    done = _stereosim(["sweep", bad, "--out", "bad", "--quiet", "--workers", "1"], tmp_path)
    assert done.returncode == 2
    assert done.stderr == ("stereosim: error: 2 of 2 runs failed: read why in the 'error' "
                           f"column of {Path('bad') / CSV_NAME}\n")
    assert done.stdout.startswith("2 runs (2 points x 1 scenes): 0 already done, 0 ok, 2 failed")
    assert "point 0 64x24: sva.disparities=128 is not smaller than the image width 64" in (
        done.stdout)
    assert [r["status"] for r in read_rows(tmp_path / "bad" / CSV_NAME)] == ["error", "error"]


def test_verbose_lets_dask_speak(tmp_path):
    good = _write(tmp_path, _estimate([16]), "good.toml")
    done = _stereosim(["sweep", good, "--out", "out", "--quiet", "--verbose", "--workers", "1"],
                      tmp_path)
    assert done.returncode == 0
    assert "distributed.scheduler - INFO" in done.stderr


# ----------------------------------------------------------------------------------------------
# 6. data: names stay in the shared data folder


def _fake_scene(folder: Path) -> Path:
    folder.mkdir(parents=True)
    for name in ("im0.png", "im1.png"):  # enough for find_scene; nothing is loaded here
        (folder / name).write_bytes(b"")
    return folder


def test_data_names_that_leave_the_shared_data_folder_are_refused(tmp_path, monkeypatch, capsys):
    data = tmp_path / "data"
    inside = _fake_scene(data / "set" / "A")
    outside = _fake_scene(tmp_path / "secret")
    (data / "link").symlink_to(outside)
    monkeypatch.setenv("STEREOSIM_DATA", str(data))
    sweep = load_sweep(_write(tmp_path, 'scenes = ["data:set/A"]\n[grid]\n"sva.paths" = [2]\n'))
    assert sweep.scenes == [("data:set/A", str(inside))]
    for name in ("data:..", "data:../secret", "data:set/../../secret", f"data:{outside}",
                 "data:link", "data:set/A/../../../secret"):
        path = _write(tmp_path, f'scenes = ["{name}"]\n[grid]\n"sva.paths" = [2]\n')
        assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"stereosim: error: scene '{name}' resolves to ") and (
            f"outside the shared data folder {data}" in err), err
        assert err.count("\n") == 1
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------------------------
# 7. files that cannot be read or written: one line, exit 2


def _unreadable(path: Path) -> Path:
    """A file that cannot be read, even by root: reading /proc/self/mem at 0 fails (EIO)."""
    path.symlink_to("/proc/self/mem")
    return path


GOOD = _estimate([16])


def _bad_sweep_folder(tmp):
    (tmp / "sweep.toml").mkdir()


def _bad_sweep_unreadable(tmp):
    _unreadable(tmp / "sweep.toml")


def _bad_config(kind):
    def make(tmp):
        (tmp / "sweep.toml").write_text('config = "base.toml"\n' + GOOD)
        if kind == "folder":
            (tmp / "base.toml").mkdir()
        elif kind == "unreadable":
            _unreadable(tmp / "base.toml")
        elif kind == "binary":
            (tmp / "base.toml").write_bytes(b"\xff\xfe\x00")
    return make


def _bad_results(kind):
    def make(tmp):
        (tmp / "sweep.toml").write_text(GOOD)
        (tmp / "out").mkdir()
        target = tmp / "out" / CSV_NAME
        if kind == "folder":
            target.mkdir()
        elif kind == "unreadable":
            _unreadable(target)
        elif kind == "fifo":
            os.mkfifo(target)
        elif kind == "foreign":
            target.write_text("name,value\na,1\n")
        elif kind == "binary":
            target.write_bytes(b"point,scene,status,error,point_id\n\xff\xfe\n")
    return make


def _out_is_a_file(tmp):
    (tmp / "sweep.toml").write_text(GOOD)
    (tmp / "out").write_text("not a folder")


UNUSABLE = {
    "sweep file is a folder": (_bad_sweep_folder, "sweep file sweep.toml is a folder"),
    "sweep file unreadable": (_bad_sweep_unreadable, "cannot read sweep file sweep.toml ("),
    "config missing": (_bad_config("missing"), "config file {tmp}/base.toml not found"),
    "config is a folder": (_bad_config("folder"), "config file {tmp}/base.toml is a folder"),
    "config unreadable": (_bad_config("unreadable"), "cannot read config file {tmp}/base.toml"),
    "config not text": (_bad_config("binary"), "config file {tmp}/base.toml is not UTF-8 text"),
    "results is a folder": (_bad_results("folder"), "results file out/results.csv is a folder"),
    "results unreadable": (_bad_results("unreadable"),
                           "cannot use the results file out/results.csv ("),
    "results is a fifo": (_bad_results("fifo"), "out/results.csv is not a regular file"),
    "results not ours": (_bad_results("foreign"),
                         "out/results.csv is not a stereosim results file"),
    "results not text": (_bad_results("binary"), "results file out/results.csv is not UTF-8"),
    "out is a file": (_out_is_a_file, "cannot create the output folder out"),
}


@pytest.mark.parametrize("case", sorted(UNUSABLE))
def test_files_that_cannot_be_used_are_one_line_exit_2(case, tmp_path, monkeypatch, capsys):
    make, expected = UNUSABLE[case]
    make(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert main(["sweep", "sweep.toml", "--out", "out", "--quiet", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: ") and err.count("\n") == 1, err
    assert expected.format(tmp=tmp_path.resolve()) in err, err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written


def test_a_repeated_point_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="point 2 on scene '64x24' repeats point 0"):
        load_sweep(_write(tmp_path, _estimate([16, 32, 16])))


# ----------------------------------------------------------------------------------------------
# Ctrl-C


def _live_processes_of_session(sid: int) -> list[str]:
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            found.append(entry.name)
    return found


def _default_sigint() -> None:
    """The child starts as from a terminal: SIGINT at its default disposition and no signal
    blocked. A process that inherits an ignored or blocked SIGINT rightly never sees Ctrl-C,
    and inside the full suite the test process may hand one down."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_SETMASK, set())


def test_ctrl_c_stops_a_sweep_within_seconds_and_leaves_a_valid_csv(tmp_path):
    """SIGINT to the whole process group, as Ctrl-C at a terminal sends it (the Dask workers
    get it too), while both workers are busy: exit 130 within seconds, only our line on stderr,
    every finished row whole, no process left behind."""
    depths = list(range(8, 108))
    path = _write(tmp_path, 'mode = "cycle"\nscenes = ["640x200"]\n[set]\n'
                  f'"sva.disparities" = 32\n[grid]\n"fifo.nna_to_sva_depth" = {depths}\n')
    csv_path = tmp_path / "out" / CSV_NAME
    proc = subprocess.Popen([sys.executable, "-m", "stereosim.sim.cli", "sweep", str(path),
                             "--out", "out", "--quiet", "--workers", "2"], cwd=tmp_path, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_default_sigint)
    try:
        deadline = time.monotonic() + 120
        while len(read_rows(csv_path)) < 2:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no row in 120 s"
            time.sleep(0.1)
        t0 = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
        seconds = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    # a cold kernel cache adds each worker's one-line compile note before the interrupt
    err = "".join(ln for ln in err.splitlines(True) if not ln.startswith("stereosim: compiling"))
    assert (proc.returncode, err, out) == (130, "stereosim: interrupted\n", "")
    assert seconds < 10, seconds
    data = csv_path.read_bytes()
    rows = read_rows(csv_path)
    assert data.endswith(b"\n") and data.count(b"\n") == len(rows) + 1
    assert 2 <= len(rows) < len(depths)
    assert all(r["status"] == "ok" and float(r["throughput.fps_bound"]) > 0 for r in rows)
    deadline = time.monotonic() + 5
    while _live_processes_of_session(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _live_processes_of_session(proc.pid) == []
