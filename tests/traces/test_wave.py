"""Reading a VCD back, the waveform PNG and the ``stereosim wave`` subcommand (FST dumps and
the run-to-wave round trip: test_wave_fst.py)."""

import os
import re
import sys
import warnings

import numpy as np
import pytest

from stereosim.core.errors import InputError, UserError
from stereosim.sim.cli import _Parser
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.cli import add_wave_parser
from stereosim.traces.log import changes_of
from stereosim.traces.vcd import write_vcd
from stereosim.traces.vcdread import read_vcd, value_at
from stereosim.traces.wave import CycleClock, drawable, window_clock, window_units


def _main(argv):
    """What sim.cli.main does with a registered subcommand."""
    parser = _Parser(prog="stereosim")
    add_wave_parser(parser.add_subparsers(dest="command", required=True, parser_class=_Parser))
    try:
        args = parser.parse_args(argv)
        return args.func(args)
    except UserError as exc:
        print(f"stereosim: error: {exc}", file=sys.stderr)
        return 2


@pytest.fixture(scope="module")
def dumped(tmp_path_factory):
    log = synthetic_log(400, seed=8)
    path = tmp_path_factory.mktemp("wave") / "t.vcd"
    write_vcd(path, log)
    return log, path


def test_reader_gives_back_the_log(dumped):
    log, path = dumped
    data = read_vcd(path)
    assert data.unit_fs == 1 and (data.first_time, data.last_time) == (log.start_fs, log.end_fs)
    by_path = {v.path: v for v in data.vars}
    for i, sig in enumerate(log.signals):
        var = by_path[sig.path]
        assert var.width == sig.width
        t, v = changes_of(log, i)
        assert data.changes[var.code] == (t.tolist(), v.tolist())
    clk = by_path["clocks.sva"]
    times, values = data.changes[clk.code]
    assert value_at(times, values, 1) == 1 and value_at(times, values, 1_075_269) == 0


def test_reader_reads_x_z_and_other_timescales(tmp_path):
    path = tmp_path / "o.vcd"
    path.write_text(
        "$timescale 10 ps $end\n$scope module m $end\n$var wire 1 ! a $end\n"
        "$var reg 4 # b [3:0] $end\n$upscope $end\n$enddefinitions $end\n"
        "$comment hi $end\n#0\n$dumpvars\nx!\nbz1 #\n$end\n#5\n1!\nb101 #\n"
    )
    data = read_vcd(path)
    assert data.unit_fs == 10_000 and [v.path for v in data.vars] == ["m.a", "m.b"]
    assert data.changes["!"] == ([0, 5], [None, 1])
    assert data.changes["#"] == ([0, 5], [None, 5])


@pytest.mark.parametrize("text, message", [
    ("hello", "no \\$enddefinitions"),
    ("$timescale 3 ns $end $enddefinitions $end", "timescale '3 ns'"),
    ("$var wire 1 ! a $end $enddefinitions $end #5 1! #3 0!", "time goes back"),
    ("$var wire 1 ! a $end $enddefinitions $end #5 q!", "unexpected token 'q!'"),
    ("$var wire 1 ! a $end $enddefinitions $end 1!", "before the first timestamp"),
    ("$var wire 1 ! a $end $enddefinitions $end", "no timestamp"),
    ("$enddefinitions $end #0", "declares no variables"),
    ("$var wire 1 ! a $end $enddefinitions $end #" + "9" * 400 + " 1!", "has 400 digits, above"),
    ("$var wire 1 ! a $end $enddefinitions $end #9223372036854775808 1!", r"above 2\*\*63 - 1"),
    ("$var wire 1 ! a $end $enddefinitions $end #" + "1" * 5000, "has 5000 digits"),
    ("$var wire 1 ! a $end $enddefinitions $end #-5 1!", "bad timestamp '#-5'"),
    ("$var wire 0 ! a $end $enddefinitions $end #0", "corrupt header"),
])
def test_reader_rejects_corrupt_files(tmp_path, text, message):
    path = tmp_path / "bad.vcd"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as exc:
        read_vcd(path)
    assert "\n" not in str(exc.value)


def test_the_largest_timestamp_is_read(tmp_path):
    """2**63 - 1 is the last instant a dump may hold (numpy's int64, FST's times)."""
    path = tmp_path / "big.vcd"
    path.write_text(f"$var wire 1 ! a $end $enddefinitions $end #0 0! #{2**63 - 1} 1!")
    assert read_vcd(path).changes["!"] == ([0, 2**63 - 1], [0, 1])


def test_windows(dumped):
    _, path = dumped
    data = read_vcd(path, lambda vs: [])
    end = data.last_time
    assert window_units(None, data) == (0, end)
    assert window_units("100:2000", data) == (100, 2000)
    assert window_units("1ns:2.5ns", data) == (1_000_000, 2_500_000)
    assert window_units(":1us", data) == (0, 10**9)
    assert window_units("0:1us", data) == (0, 10**9)  # as `stereosim run --trace-window 0:100us`
    assert window_units("3ns:", data) == (3_000_000, end)
    for bad, message in [("5", "expected A:B"), ("9:3", "is empty"), ("1.5:3", "whole numbers"),
                         ("abc:3", "not a number"), ("100:2us", "mixes a time"),
                         ("gpu:0:10", "KIND one of sva, nna, camera, rows"),
                         ("rows:0:2", "a rows window needs the run's row instants"),
                         ("nna:0:3us", "whole numbers"),
                         (f"{end + 1}:{end + 9}", "outside the dump")]:
        with pytest.raises(UserError, match=message):
            window_units(bad, data)


def test_cycle_windows_count_the_dumps_own_clock_edges(dumped):
    """Cycle k of a clock starts at its rising edge k (phase + k * period), as in
    ``run --trace-window``; the period and phase come from the dump's clock wire."""
    log, path = dumped
    data = read_vcd(path)
    clocks = {c.name: c for c in log.clocks}
    for name in ("sva", "nna", "camera"):
        per, phase = clocks[name].period_fs, clocks[name].phase_fs
        assert window_clock(f"{name}:1:2", data) == CycleClock(name, phase, per)
        assert window_units(f"{name}:1:3", data) == (phase + per, phase + 3 * per)
    per = clocks["sva"].period_fs
    assert window_units("sva:100:", data) == (100 * per, data.last_time)
    assert window_units("sva::7", data) == (0, 7 * per)
    assert window_clock("0:40ns", data) is None and window_clock(None, data) is None
    with pytest.raises(UserError, match="outside the dump"):
        window_units("sva:100000:100001", data)


@pytest.mark.parametrize("edges, message", [
    ("#0 0! #10 1! #15 0! #30", "has 1 rising edge"),
    ("#0 0! #10 1! #15 0! #20 1! #25 0! #40 1! #45 0!", r"not evenly spaced \(gaps 10 to 20"),
])
def test_cycle_windows_need_a_regular_clock(tmp_path, edges, message):
    path = tmp_path / "c.vcd"
    path.write_text("$timescale 1 ps $end $scope module clocks $end $var wire 1 ! sva $end "
                    f"$upscope $end $enddefinitions $end {edges}")
    with pytest.raises(UserError, match=message):
        window_units("sva:0:1", read_vcd(path))


def test_a_phase_shifted_clock(tmp_path):
    """A clock whose first edge is not at 0 (phase 3, period 10): cycle 2 starts at 23."""
    path = tmp_path / "p.vcd"
    path.write_text("$scope module clocks $end $var wire 1 ! nna $end $upscope $end "
                    "$enddefinitions $end #0 0! #3 1! #8 0! #13 1! #18 0! #23 1! #28 0! #33 1!")
    data = read_vcd(path)
    assert window_clock("nna:2:3", data) == CycleClock("nna", 3, 10)
    assert window_units("nna:2:3", data) == (23, 33)


def test_wave_writes_a_deterministic_png(dumped, tmp_path, capsys):
    _, path = dumped
    argv = ["wave", str(path), "--signals", "clocks.*,top.sva.output.*,*.nna_left_to_sva.*",
            "--window", "0:40ns"]
    assert _main(argv + ["--png", str(tmp_path / "a.png")]) == 0
    assert _main(argv + ["--png", str(tmp_path / "b.png")]) == 0
    a = (tmp_path / "a.png").read_bytes()
    assert a.startswith(b"\x89PNG") and a == (tmp_path / "b.png").read_bytes()
    assert b"Software" not in a and b"matplotlib" not in a
    assert "11 signals" in capsys.readouterr().out
    # a different window draws a different picture
    assert _main(argv[:-1] + ["40ns:80ns", "--png", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").read_bytes() != a
    # run's option names work too: --trace (repeatable) and --trace-window
    same = ["wave", str(path), "--trace", "clocks.*", "--trace", "top.sva.output.*",
            "--signals", "*.nna_left_to_sva.*", "--trace-window", "0:40ns"]
    assert _main(same + ["--png", str(tmp_path / "d.png")]) == 0
    assert (tmp_path / "d.png").read_bytes() == a


def test_wave_picture_shows_the_levels(dumped, tmp_path):
    """A 1-bit row is drawn high where the value is 1: check the pixels of the SVA clock row."""
    import matplotlib.image as mpimg

    _, path = dumped
    out = tmp_path / "clk.png"
    assert _main(["wave", str(path), "--signals", "clocks.sva", "--window", "0:2150538",
                  "--png", str(out)]) == 0
    img = mpimg.imread(out)[..., :3].mean(axis=2)
    dark = img < 0.5
    counts = dark.sum(axis=1)
    # horizontal half-period lines: long, but shorter than the x axis that spans the window,
    # and above it (the tick labels are below)
    axis = int(np.argmax(counts))
    long_rows = [r for r in range(axis) if 100 < counts[r] < 0.8 * counts.max()]
    high, low = min(long_rows), max(long_rows)
    assert low - high > 10
    high_x, low_x = np.flatnonzero(dark[high]), np.flatnonzero(dark[low])
    # the clock is high in the first half-period of the window and low in the second
    assert high_x.max() < low_x.min() + 3
    assert abs((high_x.max() - high_x.min()) - (low_x.max() - low_x.min())) < 0.1 * low_x.size


@pytest.mark.parametrize("args, message", [
    (["missing.vcd"], "not found"),
    (["{corrupt}"], "corrupt"),
    (["{vcd}", "--signals", "nothing.*"],
     "signal pattern 'nothing.*' matches no signal (there are 78: clocks.camera"),
    (["{vcd}", "--signals", "clocks.*,nothing.*"], "'nothing.*' matches no signal"),
    (["{vcd}", "--signals", "*"], "78 signals match *; draw at most 64"),
    (["{vcd}", "--signals", "clocks.*", "--window", "9:3"], "is empty"),
    (["{vcd}", "--signals", "clocks.*", "--window", "rows:0:3"], "rows window needs"),
    (["{plain}", "--window", "sva:0:3"],
     "counts cycles of clocks.sva, which the dump does not hold (its clocks: none)"),
    (["{vcd}", "--signals", " , "], "--signals ' , ' holds no pattern"),
    (["{vcd}", "--signals", ""], "--signals '' holds no pattern"),
    (["{huge}"], "has 400 digits, above 2**63 - 1"),
])
def test_wave_errors_are_one_line_and_write_nothing(dumped, tmp_path, capsys, args, message):
    corrupt = tmp_path / "c.vcd"
    corrupt.write_text("$var wire 1 ! a $end $enddefinitions $end #1 7!")
    plain = tmp_path / "p.vcd"
    plain.write_text("$scope module m $end $var wire 1 ! a $end $upscope $end "
                     "$enddefinitions $end #0 1! #5 0!")
    huge = tmp_path / "h.vcd"
    huge.write_text(plain.read_text() + " #" + "7" * 400 + " 1!")
    argv = ["wave"] + [a.format(vcd=dumped[1], corrupt=corrupt, plain=plain, huge=huge)
                       for a in args]
    out = tmp_path / "o.png"
    assert _main(argv + ["--png", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: ") and err.count("\n") == 1
    assert message in err
    assert not out.exists()


@pytest.mark.parametrize("link", ["same", "relative", "symlink", "hardlink"])
def test_wave_never_writes_over_the_dump(dumped, tmp_path, capsys, link):
    """``wave t.vcd --png t.vcd`` (or a path that reaches the dump another way) is refused
    before anything is read or written; the dump is left as it was."""
    dump = tmp_path / "t.vcd"
    dump.write_bytes(dumped[1].read_bytes())
    before = dump.read_bytes()
    png = {"same": str(dump), "relative": os.path.relpath(dump), "symlink": tmp_path / "s.png",
           "hardlink": tmp_path / "h.png"}[link]
    if link == "symlink":
        png.symlink_to(dump)
    elif link == "hardlink":
        os.link(dump, png)
    assert _main(["wave", str(dump), "--signals", "clocks.*", "--png", str(png)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is the input dump" in err
    assert dump.read_bytes() == before


def test_without_signals_wave_draws_the_status_overview(dumped, tmp_path, capsys):
    """No --signals: every status signal (78 signals would be above the 64-row limit); a dump
    without status signals: every signal."""
    log, path = dumped
    statuses = [s.path for s in log.signals if s.path.endswith(".status")]
    assert _main(["wave", str(path), "--png", str(tmp_path / "o.png")]) == 0
    assert f"({len(statuses)} signals," in capsys.readouterr().out
    plain = tmp_path / "p.vcd"
    plain.write_text("$scope module m $end $var wire 1 ! a $end $var wire 3 # b $end $upscope "
                     "$end $enddefinitions $end #0 1! b101 # #5 0!")
    assert _main(["wave", str(plain), "--png", str(tmp_path / "p.png")]) == 0
    assert "(2 signals," in capsys.readouterr().out


def _figure_texts(data, paths, a, b):
    """(texts per row, top first; row names; legend labels) of the picture of ``paths``."""
    from stereosim.traces.wave import wave_figure

    chosen = [v for v in data.vars if v.path in paths]
    fig = wave_figure(data, chosen, a, b)
    ax = fig.axes[0]
    n = len(chosen)
    rows = [set() for _ in chosen]
    for t in ax.texts:
        rows[n - 1 - int(t.get_position()[1])].add(t.get_text())
    legend = [t.get_text() for lg in fig.legends for t in lg.get_texts()]
    return rows, [t.get_text() for t in ax.get_yticklabels()], legend


def test_the_picture_names_statuses_and_writes_counts_in_decimal(dumped):
    """What a reader sees: status values by name with a legend of the four, counts in decimal
    and other vectors in hex, marked (hex) -- from the values of the dump."""
    from stereosim.traces.gtkw import STATUS_NAMES

    log, path = dumped
    data = read_vcd(path)
    by_path = {v.path: v for v in data.vars}
    status, desc, occ = ("top.nna.left.sub0.status", "top.nna.left.sub0.descriptor",
                         "top.fifo.nna_left_to_sva.occupancy")

    def values(p):
        return data.changes[by_path[p].code][1]

    assert max(values(occ)) >= 10  # (so decimal and hex differ)
    nna = next(c for c in log.clocks if c.name == "nna").period_fs
    # (the descriptor changes every NNA cycle: 5 cycles leave room to write its values)
    texts, names, legend = _figure_texts(data, {status, occ, desc}, 0, 5 * nna)
    assert names == [status, f"{desc} (hex)", occ]
    assert legend == list(STATUS_NAMES)
    assert texts[0] and texts[0] <= {STATUS_NAMES[v] for v in values(status)}
    assert texts[1] and texts[1] <= {f"{v:x}" for v in values(desc)}
    assert texts[2] and texts[2] <= {str(v) for v in values(occ)}
    # a window where the occupancy sits at 10 or more: written 10.., not a..
    times, occs = data.changes[by_path[occ].code]
    k = next(i for i, v in enumerate(occs) if v >= 10)
    texts, _, legend = _figure_texts(data, {occ}, times[k], times[k + 1])
    assert texts == [{str(occs[k])}] and legend == []  # no status row, no legend


def test_status_rows_are_filled_with_their_colour(tmp_path):
    """A status row busy over the whole window is green (GTKWave's colour for busy), blocked
    red; the legend shows all four colours even where the data has one status."""
    import matplotlib.image as mpimg
    from matplotlib.colors import to_rgb

    from stereosim.traces.wave import STATUS_ALPHA

    path = tmp_path / "s.vcd"
    path.write_text("$scope module top $end $scope module blk $end $var wire 2 ! status $end "
                    "$upscope $end $upscope $end $enddefinitions $end #0 b1 ! #1000 b11 ! #2000")
    out = tmp_path / "s.png"
    assert _main(["wave", str(path), "--png", str(out)]) == 0
    img = mpimg.imread(out)[..., :3]

    def count(colour):
        want = STATUS_ALPHA * np.array(to_rgb(colour)) + (1 - STATUS_ALPHA)  # over white
        return int((np.abs(img - want).max(axis=2) < 0.02).sum())

    h, w = img.shape[:2]
    green, red, orange = count("green"), count("red"), count("orange")
    assert green > 0.1 * w * 20 and red > 0.1 * w * 20  # half the row each, ~20 px high
    assert 0 < orange < 0.01 * h * w  # the legend's patch only


def test_status_names_are_the_chips_codes():
    """The names the picture, the timeline and GTKWave's filter give the codes are the codes the
    chip traces."""
    from stereosim.sim.cycle.plan import STATUS_CODES
    from stereosim.traces.gtkw import STATUS_NAMES

    assert {name: STATUS_NAMES.index(name) for name in STATUS_NAMES} == STATUS_CODES


def test_signal_patterns_are_one_rule_for_run_and_wave():
    from stereosim.traces.log import parse_patterns

    assert parse_patterns(None) == () and parse_patterns([]) == ()
    assert parse_patterns([" a.* , b", "c", "d,,"]) == ("a.*", "b", "c", "d")
    for empty in ([""], [" , "], ["", " "]):
        with pytest.raises(UserError, match="holds no pattern"):
            parse_patterns(empty)


@pytest.mark.parametrize("value", ["", " , "])
def test_run_refuses_empty_signals_before_any_work(tmp_path, capsys, value):
    """``run --signals ''`` is refused as ``wave --signals ''`` is (it traced everything)."""
    from stereosim.sim.cli import main

    out = tmp_path / "out"
    rc = main(["run", "--left", str(tmp_path / "missing_l.png"), "--right",
               str(tmp_path / "missing_r.png"), "--vcd", str(tmp_path / "t.vcd"),
               "--signals", value, "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "holds no pattern" in err
    assert not out.exists() and not (tmp_path / "t.vcd").exists()


def test_wave_checks_the_png_path_before_reading(tmp_path, capsys):
    """An unusable --png (here a folder) is refused before the dump is read: the dump named
    does not even exist."""
    assert _main(["wave", str(tmp_path / "missing.vcd"), "--png", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a folder" in err


def test_wave_refuses_huge_windows_in_one_line(dumped, tmp_path, capsys):
    """A 5,000-digit bound, 34 digits of cycles, and cycles whose instant passes 2**63 - 1."""
    _, path = dumped
    for window, message in [("0:" + "9" * 5000 + "us", "more than a window can span"),
                            ("sva:0:" + "9" * 34, r"above 2\*\*63 - 1"),
                            (f"sva:0:{2**62}", "after the last instant a dump can hold")]:
        png = tmp_path / "w.png"
        assert _main(["wave", str(path), "--window", window, "--png", str(png)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err and len(err) < 400, err
        assert re.search(message, err), err
        assert not png.exists()


def test_wave_prints_no_third_party_warnings(tmp_path, capsys):
    """A title with glyphs the font lacks (and control characters, and a '$' that would be
    read as mathematics), and a window of 1 unit at 10**18 units, draw without a warning
    of matplotlib's: the characters become '?', the axis counts from the window's start."""
    path = tmp_path / "g.vcd"
    path.write_text("$scope module m $end $var wire 1 ! a $end $upscope $end $enddefinitions "
                    "$end #0 0! #1000000000000000000 1! #1000000000000000002 0!")
    runs = [["--title", "t \u4e2d\u6587 \x01 $\\foo{$ \u00e9"],
            ["--window", "1000000000000000000:1000000000000000001"]]
    for extra in runs:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            code = _main(["wave", str(path), "--png", str(tmp_path / "w.png"), *extra])
        assert code == 0 and [str(w.message) for w in caught] == []
    assert capsys.readouterr().err == ""
    assert drawable("t \u4e2d \x01 $ \u00e9", "DejaVu Sans") == "t ? ? $ \u00e9"
