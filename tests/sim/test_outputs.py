"""Writing outputs whole or not at all: sim.outputs (atomic files, checked sets, publish, JSON)."""

from __future__ import annotations

import errno
import json
import math
import os

import numpy as np
import pytest

from stereosim.sim import outputs
from stereosim.sim.errors import InputError
from stereosim.sim.outputs import atomic_write_bytes, check_outputs, json_text, publish


def test_atomic_write_replaces_and_leaves_no_temp_files(tmp_path):
    target = tmp_path / "out.bin"
    atomic_write_bytes(target, b"first")
    atomic_write_bytes(target, b"second")
    assert target.read_bytes() == b"second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
    umask = os.umask(0o022)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask


def test_atomic_write_removes_temp_file_on_error(tmp_path):
    target = tmp_path / "x.bin"
    target.write_bytes(b"old")
    with pytest.raises(TypeError):
        atomic_write_bytes(target, "not bytes")  # type: ignore[arg-type]
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.bin"]


def test_atomic_write_needs_existing_folder(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        atomic_write_bytes(tmp_path / "no" / "f.bin", b"x")


def test_atomic_write_refuses_a_folder_and_names_it(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        atomic_write_bytes(tmp_path / "d", b"x")


def test_check_outputs_refuses_two_outputs_on_one_path(tmp_path):
    with pytest.raises(InputError, match="--vcd and the report would both write"):
        check_outputs({tmp_path / "report.json": "--vcd", tmp_path / "x" / ".." / "report.json":
                       "the report"})


def test_check_outputs_refuses_a_long_name(tmp_path):
    with pytest.raises(InputError, match="too long"):
        check_outputs({tmp_path / ("n" * 300) / "f": "--out"})


def test_check_outputs_refuses_a_file_as_folder(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="is a file, not a folder"):
        check_outputs({tmp_path / "f" / "g" / "report.json": "the report"})


def test_publish_writes_the_set_and_leaves_no_stage(tmp_path):
    out = tmp_path / "a" / "b"
    written = publish({out / "x.bin": b"1", out / "y.bin": b"22", tmp_path / "z.bin": b"333"})
    assert written == [str(out / "x.bin"), str(out / "y.bin"), str(tmp_path / "z.bin")]
    assert sorted(p.name for p in out.iterdir()) == ["x.bin", "y.bin"]
    assert (tmp_path / "z.bin").read_bytes() == b"333"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "z.bin"]


def test_publish_failure_while_writing_keeps_the_old_set(tmp_path, monkeypatch):
    out = tmp_path / "out"
    publish({out / "x.bin": b"old-x", out / "y.bin": b"old-y"})
    real = outputs._write_fd
    calls = []

    def full_disk(fd, data):
        calls.append(1)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(fd, data)

    monkeypatch.setattr(outputs, "_write_fd", full_disk)
    with pytest.raises(InputError, match="No space left on device"):
        publish({out / "x.bin": b"new-x", out / "y.bin": b"new-y"})
    assert (out / "x.bin").read_bytes() == b"old-x"
    assert (out / "y.bin").read_bytes() == b"old-y"
    assert sorted(p.name for p in out.iterdir()) == ["x.bin", "y.bin"]


def test_publish_failure_while_renaming_rolls_back(tmp_path, monkeypatch):
    out = tmp_path / "out"
    publish({out / "x.bin": b"old-x", out / "y.bin": b"old-y"})
    real = os.replace
    calls = []

    def failing(src, dst):
        if str(dst).endswith("y.bin"):
            calls.append(dst)
            raise OSError(errno.EIO, "Input/output error")
        real(src, dst)

    monkeypatch.setattr(outputs.os, "replace", failing)
    with pytest.raises(InputError, match="cannot publish"):
        publish({out / "x.bin": b"new-x", out / "y.bin": b"new-y", out / "z.bin": b"new-z"})
    monkeypatch.setattr(outputs.os, "replace", real)
    assert calls
    assert (out / "x.bin").read_bytes() == b"old-x"
    assert (out / "y.bin").read_bytes() == b"old-y"
    assert sorted(p.name for p in out.iterdir()) == ["x.bin", "y.bin"]


def test_publish_into_a_new_folder_that_fails_leaves_no_folder(tmp_path, monkeypatch):
    def full_disk(fd, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs, "_write_fd", full_disk)
    with pytest.raises(InputError):
        publish({tmp_path / "new" / "deeper" / "x.bin": b"x"})
    assert list(tmp_path.iterdir()) == []


def test_a_stage_left_by_a_dead_process_is_removed(tmp_path):
    dead = 2**22 + 12345  # above the default pid_max of 4,194,304: never a live process
    stale = tmp_path / f"{outputs.STAGE_PREFIX}{dead}-abc"
    stale.mkdir()
    (stale / "report.json").write_text("{")
    publish({tmp_path / "x.bin": b"x"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.bin"]


def test_json_text_is_strict_json():
    text = json_text({"a": math.nan, "b": [math.inf, 1.5], "c": np.float32(2.0), "d": np.int64(3)})
    assert json.loads(text) == {"a": None, "b": [None, 1.5], "c": 2.0, "d": 3}
    assert "NaN" not in text and "Infinity" not in text
