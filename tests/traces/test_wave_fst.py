"""``stereosim wave`` on FST dumps: the FST reader gives what the VCD reader
gives for the same log, corrupt FSTs fail with one line, and the round trip ``run --vcd t.fst``
then ``wave t.fst`` works at the command line, with cycle windows resolved as ``run`` resolves
them."""

from __future__ import annotations

import gzip
import struct

import cv2
import numpy as np
import pytest
import pywellen

from stereosim.core.errors import InputError
from stereosim.sim.cli import main
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.dumpread import read_dump
from stereosim.traces.fst import fst_bytes
from stereosim.traces.gtkw import STATUS_NAMES
from stereosim.traces.vcd import vcd_bytes
from stereosim.traces.vcdread import read_vcd
from stereosim.traces.wave import match_vars, wave_figure


@pytest.fixture(scope="module")
def dumps(tmp_path_factory):
    log = synthetic_log(400, seed=8)
    folder = tmp_path_factory.mktemp("fst")
    (folder / "t.fst").write_bytes(fst_bytes(log))
    (folder / "t.vcd").write_bytes(vcd_bytes(log))
    return folder / "t.fst", folder / "t.vcd"


def _by_path(data):
    return {v.path: (v.width, data.changes[v.code]) for v in data.vars}


def _same(a, b):
    assert (a.unit_fs, a.first_time, a.last_time) == (b.unit_fs, b.first_time, b.last_time)
    assert [(v.path, v.width) for v in a.vars] == [(v.path, v.width) for v in b.vars]
    assert _by_path(a) == _by_path(b)


def test_an_fst_reads_as_its_vcd(dumps):
    """Same variables in the same order, same changes, and the window's end -- the FST's last
    instant carries no change -- from its header."""
    fst, vcd = dumps
    _same(read_dump(fst), read_vcd(vcd))
    _same(read_dump(vcd), read_vcd(vcd))  # (the VCD goes to the project's reader)
    # select() keeps the changes of the variables it returns, as for a VCD
    data = read_dump(fst, lambda vs: [v for v in vs if v.path == "clocks.sva"])
    assert [v.path for v in data.vars if v.code in data.changes] == ["clocks.sva"]


def test_a_wrapped_fst_reads_the_same(dumps, tmp_path):
    """An FST compressed whole into one gzip wrapper block (libfst's repack-on-close)."""
    fst, vcd = dumps
    body = fst.read_bytes()
    packed = gzip.compress(body, mtime=0)
    wrapped = tmp_path / "w.fst"
    wrapped.write_bytes(bytes([254]) + struct.pack(">QQ", 16 + len(packed), len(body)) + packed)
    _same(read_dump(wrapped), read_vcd(vcd))


def _corrupt(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def test_corrupt_fsts_fail_with_one_line(dumps, tmp_path, capfd):
    fst, _ = dumps
    body = fst.read_bytes()
    cases = {"half.fst": body[: len(body) // 2], "head.fst": body[:20],
             "flip.fst": body[:300] + bytes(b ^ 0xFF for b in body[300:340]) + body[340:]}
    for name, data in cases.items():
        with pytest.raises(InputError, match=f"FST file .*{name}") as exc:
            read_dump(_corrupt(tmp_path, name, data))
        assert "\n" not in str(exc.value)
    assert capfd.readouterr().err == ""


def test_a_panic_in_the_reader_is_one_line_and_prints_nothing(dumps, tmp_path, capfd):
    """pywellen panics on this byte (a Rust panic: a BaseException, and a message printed on
    the process's stderr); wave gives one line and nothing else reaches stderr."""
    fst, _ = dumps
    data = bytearray(fst.read_bytes())
    data[444] = 0xFF
    path = _corrupt(tmp_path, "panic.fst", bytes(data))
    with pytest.raises(BaseException) as raw:  # what pywellen itself does with the file
        wave = pywellen.Waveform(str(path), multi_threaded=False)
        wave.stream_changes(lambda *_: None, list(wave.all_vars()))
    assert type(raw.value).__name__ == "PanicException"
    assert "panicked" in capfd.readouterr().err
    with pytest.raises(InputError, match="FST file .*panic.fst is corrupt") as exc:
        read_dump(path)
    assert "\n" not in str(exc.value) and capfd.readouterr().err == ""


def test_a_file_that_is_no_dump(tmp_path):
    path = tmp_path / "x.fst"
    path.write_bytes(bytes(range(1, 200)))
    with pytest.raises(InputError, match="not ASCII text, nor an FST"):
        read_dump(path)
    with pytest.raises(InputError, match="not found"):
        read_dump(tmp_path / "missing.fst")


def _pair(folder):
    rng = np.random.default_rng(5)
    left = rng.integers(0, 256, (24, 64), dtype=np.uint8)
    cv2.imwrite(str(folder / "l.png"), left)
    cv2.imwrite(str(folder / "r.png"), np.roll(left, -2, axis=1))
    return ["--left", str(folder / "l.png"), "--right", str(folder / "r.png"),
            "--disparities", "16", "--descriptor", "census"]


def _window_of(out: str) -> tuple[int, int]:
    """``a..b`` of wave's ``wrote ... (N signals, a..b x 1 fs)``."""
    span = out.rsplit("signals, ", 1)[1].split(" x ")[0]
    a, b = span.split("..")
    return int(a), int(b)


def test_run_writes_an_fst_that_wave_draws(tmp_path, capsys):
    """Acceptance 4: ``stereosim run --vcd t.fst`` then ``stereosim wave t.fst --png w.png``
    draws the status overview with the status names; a cycle window of ``wave`` is the window
    ``run --trace-window`` records for the same text."""
    pair = _pair(tmp_path)
    fst = tmp_path / "t.fst"
    assert main(["run", *pair, "--trace-window", "sva:0:4000", "--vcd", str(fst),
                 "--out", str(tmp_path / "o1")]) == 0
    assert main(["run", *pair, "--trace-window", "nna:1500:1700", "--vcd",
                 str(tmp_path / "n.vcd"), "--out", str(tmp_path / "o2")]) == 0
    capsys.readouterr()

    png = tmp_path / "w.png"
    assert main(["wave", str(fst), "--png", str(png)]) == 0
    assert png.read_bytes().startswith(b"\x89PNG")
    data = read_dump(fst)
    overview = match_vars(data.vars, ())
    statuses = [v for v in data.vars if v.path.endswith(".status")]
    assert overview == statuses and f"({len(statuses)} signals," in capsys.readouterr().out
    # what the picture writes on the status rows: names, never codes
    fig = wave_figure(data, overview, data.first_time, data.last_time)
    written = {t.get_text() for t in fig.axes[0].texts}
    assert written and written <= set(STATUS_NAMES)
    assert [t.get_text() for t in fig.legends[0].get_texts()] == list(STATUS_NAMES)

    # wave's nna:1500:1700 on the long dump is the window run recorded for nna:1500:1700
    assert main(["wave", str(fst), "--window", "nna:1500:1700", "--signals", "top.sva.*",
                 "--png", str(tmp_path / "c.png")]) == 0
    recorded = read_dump(tmp_path / "n.vcd")
    assert _window_of(capsys.readouterr().out) == (recorded.first_time, recorded.last_time)
    # a clock the dump does not hold (memory sources: no camera clock)
    assert main(["wave", str(fst), "--window", "camera:0:3", "--png", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(its clocks: clocks.nna, clocks.sva)" in err
    assert not (tmp_path / "x.png").exists()
    # and the same picture from either dump
    assert main(["wave", str(tmp_path / "n.vcd"), "--window", "nna:1500:1700", "--signals",
                 "top.sva.*", "--png", str(tmp_path / "d.png")]) == 0
    assert (tmp_path / "c.png").read_bytes() == (tmp_path / "d.png").read_bytes()


def test_wave_reads_an_fst_with_stderr_closed(dumps, tmp_path):
    """``stereosim wave t.fst ... 2>&-``: keeping pywellen's stderr clean needs no stderr."""
    import os
    import subprocess
    import sys

    fst, _ = dumps
    png = tmp_path / "c.png"
    done = subprocess.run(
        [sys.executable, "-m", "stereosim.sim.cli", "wave", str(fst), "--png", str(png)],
        stdout=subprocess.PIPE, text=True, preexec_fn=lambda: os.close(2), check=False)
    assert done.returncode == 0 and done.stdout.startswith(f"wrote {png}")
    assert png.read_bytes().startswith(b"\x89PNG")
