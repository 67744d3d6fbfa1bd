"""Sweeps (sim/sweep.py) on a real Dask LocalCluster, the sweep file checks, and the plots."""

import csv
import logging

import pytest

from sim.cli import main
from sim.datasets import shared_data_dir
from sim.sweep import CSV_NAME, load_sweep, read_rows, run_sweep, run_task, synthetic_pair

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
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None, silence_logs=logging.ERROR,
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


class _CountingClient:
    """The real client, counting the tasks submitted to it."""

    def __init__(self, client):
        self.client = client
        self.submitted = []

    def submit(self, fn, task, **kw):
        self.submitted.append(task)
        return self.client.submit(fn, task, **kw)


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
        assert float(r["throughput.fps"]) > 0
        assert r["config.sva.disparities"] == r["sva.disparities"]
        assert r["config.sva.paths"] == "2"
        assert int(r["cycles.last_output.sva"]) > int(r["cycles.first_output.sva"])
        assert r["estimate.throughput.fps"] == r["throughput.fps"]
    before = (out / CSV_NAME).read_bytes()
    # resume: only the failed point is submitted again; finished rows stay byte for byte
    counting = _CountingClient(client)
    counts = run_sweep(sweep, out, client=counting, progress=False)
    assert counts == {"tasks": 4, "skipped": 3, "ok": 0, "error": 1}
    assert [t.point for t in counting.submitted] == [3]
    assert (out / CSV_NAME).read_bytes() == before


def test_rows_do_not_depend_on_completion_order(tmp_path):
    sweep = load_sweep(_write(tmp_path, FOUR_POINTS.replace('"64x24"', '"64x24", "80x16"')))
    assert [(t.point, t.scene) for t in sweep.tasks][:3] == [(0, "64x24"), (0, "80x16"),
                                                             (1, "64x24")]
    from sim.sweep import write_rows

    rows = [run_task(t) for t in sweep.tasks[:4]]
    write_rows(tmp_path / "a.csv", rows, sweep.axes)
    write_rows(tmp_path / "b.csv", sorted(rows, key=lambda r: -r["point"]), sweep.axes)
    a = list(csv.DictReader((tmp_path / "a.csv").open()))
    assert [r["scene"] for r in a] == ["64x24", "80x16", "64x24", "80x16"]


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
    from sim.sweep import Task

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
    from sim.sweep import write_rows

    write_rows(tmp_path / CSV_NAME, rows, sweep.axes)
    return tmp_path / CSV_NAME, sweep


def test_plot_is_byte_identical_across_runs(tmp_path, capsys):
    csv_path, _ = _results(tmp_path)
    args = ["plot", str(csv_path), "--x", "nna.stereo_submodules", "--y", "throughput.fps",
            "--hue", "nna.descriptor"]
    assert main([*args, "--png", str(tmp_path / "a.png")]) == 0
    assert main([*args, "--png", str(tmp_path / "b.png")]) == 0
    a = (tmp_path / "a.png").read_bytes()
    assert a[:8] == b"\x89PNG\r\n\x1a\n" and a == (tmp_path / "b.png").read_bytes()


def test_plot_of_a_missing_column_is_one_line_exit_2(tmp_path, capsys):
    csv_path, _ = _results(tmp_path)
    capsys.readouterr()
    png = tmp_path / "x.png"
    assert main(["plot", str(csv_path), "--x", "nope", "--y", "throughput.fps",
                 "--png", str(png)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: column 'nope'") and err.count("\n") == 1
    assert not png.exists()


def test_built_in_plots(tmp_path):
    from sim.plot import sweep_plots

    csv_path, sweep = _results(tmp_path)
    written = sweep_plots(read_rows(csv_path), sweep.axes, tmp_path)
    assert [p.name for p in written] == ["fps_vs_submodules.png", "pareto_sram_fps.png"]
    assert all(p.stat().st_size > 1000 for p in written)
