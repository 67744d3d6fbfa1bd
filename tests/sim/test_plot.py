"""Plots of sweep results (sim/plot.py): the Pareto view's target line and the point it picks,
and whole-number ticks on an axis of counts. Each figure is inspected as drawn (its artists,
found by gid, and its ticks), not only through the data the functions return."""

import math

import pytest

from stereosim.core.errors import InputError
from stereosim.sim import plot
from stereosim.sim.plot import pareto_plot, plot_xy, sweep_pareto, sweep_plots, target_rate

# (sram bits, frame rate) of five points: two reach 60 fps, one just misses it
POINTS = [(1000, 20.0), (1200, 45.0), (1600, 59.5), (1500, 61.0), (1800, 75.0)]


def _rows(points=POINTS, camera=60.0, column="throughput.camera_fps"):
    return [{"point": str(i), "status": "ok", "sram_bits": s, "throughput.fps_bound": f,
             "nna.stereo_submodules": 2 * (i + 1), column: camera}
            for i, (s, f) in enumerate(points)]


@pytest.fixture
def figures(monkeypatch):
    """The figures the plots draw, kept before they are written."""
    kept = []
    real = plot._png_bytes

    def keep(plt, fig, **kw):
        kept.append(fig)
        return real(plt, fig, **kw)

    monkeypatch.setattr(plot, "_png_bytes", keep)
    return kept


def _by_gid(fig, gid):
    return fig.findobj(lambda a: a.get_gid() == gid)


def _offsets(fig, gid) -> list[tuple[float, float]]:
    (marks,) = _by_gid(fig, gid)
    return [tuple(map(float, xy)) for xy in marks.get_offsets()]


def test_the_target_line_is_drawn_and_the_boxed_point_is_the_least_sram_reaching_it(
        tmp_path, figures):
    data = pareto_plot(_rows(), tmp_path / "p.png", label_keys=["nna.stereo_submodules"])
    (fig,) = figures
    (line,) = _by_gid(fig, "target")
    assert list(line.get_ydata()) == [60.0, 60.0]
    assert (data.target, data.target_source) == (60.0, "throughput.camera_fps")
    reaching = [(s, f) for s, f in POINTS if f >= 60.0]
    least = min(reaching)
    assert _offsets(fig, "chosen") == [(least[0] / 1e3, least[1])]  # the axis is in k bits
    assert (data.chosen.sram, data.chosen.fps) == least
    rings = _offsets(fig, "ringed")
    assert rings and all(f >= 60.0 for _, f in rings)
    # the least-SRAM point of all (20 fps) is Pareto-optimal, but not ringed: it misses
    assert next(p for p in data.points if p.sram == 1000).optimal
    assert (1.0, 20.0) not in rings
    title = fig.axes[0].get_title()
    assert "dashed: target 60 fps (throughput.camera_fps)" in title
    assert "boxed: the least SRAM there" in title


def test_when_no_point_reaches_the_target_none_is_ringed_and_the_title_says_so(
        tmp_path, figures):
    data = pareto_plot(_rows(), tmp_path / "p.png", target_fps=100.0)
    (fig,) = figures
    assert data.chosen is None and data.ringed == []
    assert _offsets(fig, "ringed") == [] and _by_gid(fig, "chosen") == []
    (line,) = _by_gid(fig, "target")
    assert list(line.get_ydata()) == [100.0, 100.0]
    best = max(f for _, f in POINTS)
    assert f"no point reaches it (best {best:g} fps): none ringed" in fig.axes[0].get_title()


def test_without_a_target_the_pareto_front_is_ringed_and_no_line_drawn(tmp_path, figures):
    rows = [{k: v for k, v in r.items() if k != "throughput.camera_fps"} for r in _rows()]
    data = pareto_plot(rows, tmp_path / "p.png")
    (fig,) = figures
    assert data.target is None and _by_gid(fig, "target") == []
    assert sorted(_offsets(fig, "ringed")) == sorted((p.sram / 1e3, p.fps) for p in data.front)


def test_the_target_comes_from_the_camera_column_only_when_all_rows_agree():
    assert target_rate(_rows()) == (60.0, "throughput.camera_fps")
    assert target_rate(_rows(column="estimate.throughput.camera_fps")) == (
        60.0, "estimate.throughput.camera_fps")
    mixed = _rows()
    mixed[0]["throughput.camera_fps"] = 30.0
    assert target_rate(mixed) is None
    assert target_rate(_rows(camera="")) is None  # a memory source: no camera rate
    # a sweep's view and its plots take it; a target given wins
    assert sweep_pareto(_rows(), ["nna.stereo_submodules"]).target == 60.0
    assert sweep_pareto(_rows(), ["nna.stereo_submodules"], target_fps=30.0).target == 30.0


def test_sweep_plots_draw_the_target(tmp_path, figures):
    written = sweep_plots(_rows(), ["nna.stereo_submodules"], tmp_path)
    assert [p.name for p in written] == ["fps_vs_submodules.png", "pareto_sram_fps.png"]
    assert len(_by_gid(figures[-1], "target")) == 1


@pytest.mark.parametrize("bad", [0.0, -5.0, math.nan, math.inf])
def test_a_target_that_is_not_a_positive_rate_is_refused(tmp_path, bad):
    with pytest.raises(InputError, match="positive"):
        pareto_plot(_rows(), tmp_path / "p.png", target_fps=bad)
    assert not (tmp_path / "p.png").exists()


def _visible_ticks(ax, axis):
    lo, hi = sorted(ax.get_xlim() if axis == "x" else ax.get_ylim())
    ticks = ax.get_xticks() if axis == "x" else ax.get_yticks()
    return [t for t in ticks if lo <= t <= hi]


def test_an_axis_of_whole_numbers_gets_whole_number_ticks(tmp_path, figures):
    rows = _rows([(1000, 57.27), (1100, 59.0), (1200, 60.0)])
    for i, r in enumerate(rows):
        r["nna.stereo_submodules"] = 36 + i  # 36, 37, 38: matplotlib would tick 36.5
        r["fifos.high"] = 3 + 2 * i
    plot_xy(rows, "nna.stereo_submodules", "throughput.fps_bound", tmp_path / "a.png")
    plot_xy(rows, "nna.stereo_submodules", "fifos.high", tmp_path / "b.png")
    plot_xy(rows, "throughput.fps_bound", "nna.stereo_submodules", tmp_path / "c.png")
    a, b, c = (f.axes[0] for f in figures)
    for ax, axis in ((a, "x"), (b, "x"), (b, "y"), (c, "y")):
        ticks = _visible_ticks(ax, axis)
        assert len(ticks) >= 2 and all(float(t).is_integer() for t in ticks), (axis, ticks)
    # a rate axis is not forced to whole numbers
    assert not all(float(t).is_integer() for t in _visible_ticks(a, "y"))
