"""Reading a VCD back, the waveform PNG and the ``stereosim wave`` subcommand."""

import sys

import numpy as np
import pytest

from stereosim.sim.cli import _Parser
from stereosim.sim.errors import InputError, UserError
from stereosim.traces.cli import add_wave_parser
from stereosim.traces.log import changes_of
from stereosim.traces.synthetic import synthetic_log
from stereosim.traces.vcd import write_vcd
from stereosim.traces.vcdread import read_vcd, value_at
from stereosim.traces.wave import window_units


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
])
def test_reader_rejects_corrupt_files(tmp_path, text, message):
    path = tmp_path / "bad.vcd"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as exc:
        read_vcd(path)
    assert "\n" not in str(exc.value)


def test_windows(dumped):
    data = read_vcd(dumped[0] and dumped[1], lambda vs: [])
    end = data.last_time
    assert window_units(None, data) == (0, end)
    assert window_units("100:2000", data) == (100, 2000)
    assert window_units("1ns:2.5ns", data) == (1_000_000, 2_500_000)
    assert window_units(":1us", data) == (0, 10**9)
    assert window_units("0:1us", data) == (0, 10**9)  # as `stereosim run --trace-window 0:100us`
    assert window_units("3ns:", data) == (3_000_000, end)
    for bad, message in [("5", "expected A:B"), ("9:3", "is empty"), ("1.5:3", "whole numbers"),
                         ("abc:3", "not a number"), ("100:2us", "mixes a time"),
                         ("sva:0:10", "need stereosim run --trace-window"),
                         (f"{end + 1}:{end + 9}", "outside the dump")]:
        with pytest.raises(UserError, match=message):
            window_units(bad, data)


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
    # horizontal half-period lines: long, but shorter than the x axis that spans the window
    long_rows = [r for r in range(img.shape[0]) if 100 < counts[r] < 0.8 * counts.max()]
    high, low = min(long_rows), max(long_rows)
    assert low - high > 10
    high_x, low_x = np.flatnonzero(dark[high]), np.flatnonzero(dark[low])
    # the clock is high in the first half-period of the window and low in the second
    assert high_x.max() < low_x.min() + 3
    assert abs((high_x.max() - high_x.min()) - (low_x.max() - low_x.min())) < 0.1 * low_x.size


@pytest.mark.parametrize("args, message", [
    (["missing.vcd"], "not found"),
    (["{corrupt}"], "corrupt"),
    (["{vcd}", "--signals", "nothing.*"], "no signal matches nothing.*; the dump has 78: clocks"),
    (["{vcd}", "--signals", "*"], "draw at most 64"),
    (["{vcd}", "--signals", "clocks.*", "--window", "9:3"], "is empty"),
    (["{vcd}", "--signals", " , "], "--signals is empty"),
])
def test_wave_errors_are_one_line_and_write_nothing(dumped, tmp_path, capsys, args, message):
    corrupt = tmp_path / "c.vcd"
    corrupt.write_text("$var wire 1 ! a $end $enddefinitions $end #1 7!")
    argv = ["wave"] + [a.format(vcd=dumped[1], corrupt=corrupt) for a in args]
    out = tmp_path / "o.png"
    assert _main(argv + ["--png", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stereosim: error: ") and err.count("\n") == 1
    assert message in err
    assert not out.exists()
