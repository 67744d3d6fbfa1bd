"""FST output: the same signals and changes as the VCD of the same log, both read
back by pywellen (Surfer's backend), from the writer and from ``stereosim run --vcd x.fst``."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest
import pywellen

from stereosim.sim.cli import main
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.fst import fst_bytes
from stereosim.traces.vcd import vcd_bytes


def _read(path) -> tuple[str, str, dict]:
    """(format, timescale, {full name: (width, [(instant, value), ...])}) of a dump."""
    wave = pywellen.Waveform(str(path))
    out = {}
    for var in wave.all_vars():
        changes = []

        def note(t, _sid, value, changes=changes):
            changes.append((t, value))

        wave.stream_changes(note, [var])
        out[var.full_name] = (var.bitwidth, changes)
    return wave.file_format, str(wave.timescale), out


def _same_as_vcd(fst_path, vcd_path):
    fmt_f, scale_f, fst = _read(fst_path)
    fmt_v, scale_v, vcd = _read(vcd_path)
    assert (fmt_f, fmt_v) == ("FST", "VCD") and scale_f == scale_v
    assert list(fst) == list(vcd)  # the same scopes and signals, in the same order
    assert fst == vcd  # widths, and every change at its instant
    return fst


@pytest.mark.parametrize("cycles, seed", [(300, 0), (2000, 1)])
def test_the_fst_holds_the_vcds_signals_and_changes(tmp_path, cycles, seed):
    log = synthetic_log(cycles, seed=seed)
    (tmp_path / "t.fst").write_bytes(fst_bytes(log))
    (tmp_path / "t.vcd").write_bytes(vcd_bytes(log))
    got = _same_as_vcd(tmp_path / "t.fst", tmp_path / "t.vcd")
    assert sum(len(c) for _, c in got.values()) > 1000  # (a dump with something in it)
    first = fst_bytes(log)
    time.sleep(1.1)  # (libfst would stamp the wall-clock second)
    assert fst_bytes(log) == first  # deterministic
    assert len(fst_bytes(log)) < len(vcd_bytes(log)) / 3


def test_the_cli_writes_fst_when_the_name_ends_in_fst(tmp_path):
    rng = np.random.default_rng(3)
    left = rng.integers(0, 256, (20, 48), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "l.png"), left)
    cv2.imwrite(str(tmp_path / "r.png"), np.roll(left, -2, axis=1))
    for name in ("f.fst", "v.vcd"):
        rc = main(["run", "--left", str(tmp_path / "l.png"), "--right", str(tmp_path / "r.png"),
                   "--disparities", "16", "--trace-window", "0:3000", "--vcd",
                   str(tmp_path / name), "--out", str(tmp_path / name.replace(".", "_"))])
        assert rc == 0
    assert not (tmp_path / "f.fst").read_bytes().startswith(b"$")  # not VCD text
    # the same save file as the VCD's, naming the .fst (by absolute path)
    fst_gtkw = (tmp_path / "f.gtkw").read_text()
    assert f'[dumpfile] "{tmp_path / "f.fst"}"' in fst_gtkw.splitlines()
    assert fst_gtkw.replace("/f.fst", "/v.vcd").replace("/f.", "/v.") == \
        (tmp_path / "v.gtkw").read_text()
    _same_as_vcd(tmp_path / "f.fst", tmp_path / "v.vcd")
