"""Sweeps (sim/sweep.py) on a real Dask LocalCluster, the sweep file checks, and the plots."""

import csv
import logging
import time
from pathlib import Path

import pytest

from sim.cli import main
from sim.datasets import shared_data_dir
from sim.errors import ConfigError
from sim.sweep import (
    CSV_NAME,
    MAX_POINTS,
    load_sweep,
    read_rows,
    run_sweep,
    run_task,
    synthetic_pair,
)

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


def _estimate(disparities, scene="64x24", extra=""):
    return (f'mode = "estimate"\nscenes = ["{scene}"]\n[grid]\n'
            f'"sva.disparities" = {list(disparities)}\n{extra}')


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


