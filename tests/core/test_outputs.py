"""Writing outputs whole or not at all: core.outputs (atomic files, checked sets, publish, JSON)."""

from __future__ import annotations

import errno
import hashlib
import json
import math
import os
import signal
import threading
import time

import numpy as np
import pytest

from stereosim.core import outputs, signals
from stereosim.core.errors import InputError
from stereosim.core.outputs import atomic_write_bytes, check_outputs, json_text, publish


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


# ---------------------------------------------------------------- sets, kills and signals


def _manifest(files: dict) -> bytes:
    return json.dumps({"files": {name: hashlib.sha256(data).hexdigest()
                                 for name, data in sorted(files.items())}}).encode()


def _stream_set(out, tag: str) -> dict:
    """A 15-file set like a stream's: two maps in OUT, 12 frames in OUT/frames, the manifest
    report.json (the SHA-256 of every other file) last."""
    files = {"disparity.pfm": f"{tag}-pfm".encode(), "disparity.png": f"{tag}-png".encode()}
    files.update({f"frames/f{k:02d}.pfm": f"{tag}-frame-{k}".encode() for k in range(12)})
    blobs = {out / name: data for name, data in files.items()}
    blobs[out / "report.json"] = _manifest(files)
    return blobs


def _on_disk(blobs: dict) -> dict:
    return {p: p.read_bytes() if p.exists() else None for p in blobs}


def _stages(out) -> list:
    return sorted(p for p in [*out.iterdir(), *(out / "frames").iterdir()]
                  if p.name.startswith(outputs.STAGE_PREFIX))


def _killed_publish(blobs, manifest, kill_after: int | None = None, kill_writing: int = 0):
    """Fork; the child publishes ``blobs`` and SIGKILLs itself right after the ``kill_after``-th
    step of the switch (a rename that touches a target: 0 = just before the first) or during
    the ``kill_writing``-th staged write. Returns once the child is dead and reaped."""
    targets = {str(p) for p in blobs}
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        try:
            real_replace, real_write = os.replace, outputs._write_fd
            steps, writes = [0], [0]

            def replace(src, dst):
                touches = str(src) in targets or str(dst) in targets
                if touches and steps[0] == kill_after == 0:
                    os.kill(os.getpid(), signal.SIGKILL)
                real_replace(src, dst)
                steps[0] += touches
                if touches and steps[0] == kill_after:
                    os.kill(os.getpid(), signal.SIGKILL)

            def write(fd, data):
                writes[0] += 1
                if writes[0] == kill_writing:
                    os.kill(os.getpid(), signal.SIGKILL)
                real_write(fd, data)

            outputs.os.replace = replace
            outputs._write_fd = write
            publish(blobs, manifest=manifest)
        finally:
            os._exit(3)
    _, status = os.waitpid(pid, 0)
    return status


def test_a_kill_at_any_step_of_a_switch_leaves_a_state_the_next_publish_finishes(tmp_path):
    """SIGKILL after each rename of a 15-file set (and while staging): a report.json on disk
    always describes the files beside it; a half-switched set is marked by its journal; the
    next publish into either folder of the set finishes it (a set killed before its journal
    stays the old one) and removes the staging folders."""
    out = tmp_path / "out"
    old = _stream_set(out, "old")
    new = _stream_set(out, "new")
    steps = len(new) + 1  # the report moved aside, then 15 renames
    cases = [("writing", 3), *(("switching", k) for k in range(steps + 1))]
    outcomes = set()
    for what, k in cases:
        publish(old, manifest=out / "report.json")
        if what == "writing":
            status = _killed_publish(new, out / "report.json", kill_writing=k)
        else:
            status = _killed_publish(new, out / "report.json", kill_after=k)
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (what, k)
        disk = _on_disk(new)
        assert all(disk[p] in (old[p], new[p]) for p in new if p.name != "report.json")
        report = disk[out / "report.json"]
        if report is not None:  # whenever there is a report, it describes the files beside it
            described = json.loads(report)["files"]
            assert described == {n: hashlib.sha256((out / n).read_bytes()).hexdigest()
                                 for n in described}, (what, k)
        journals = [s for s in _stages(out) if (s / "journal.json").exists()]
        data = {p: v for p, v in disk.items() if p.name != "report.json"}
        mixed = all(data != {p: blobs[p] for p in data} for blobs in (old, new))
        assert bool(journals) == (what == "switching"), (what, k)
        assert _stages(out), (what, k)  # the killed process's staging folders are still there
        assert report is not None or journals, (what, k)
        # the next publish, into OUT or into OUT/frames, repairs the killed set first (the
        # staging folders of a set that never switched go with a publish into their folder)
        visit = [out, out / "frames"] if what == "writing" else [[out / "frames", out][k % 2]]
        for folder in visit:
            publish({folder / "other.bin": b"x"})
            (folder / "other.bin").unlink()
        assert _stages(out) == [], (what, k)
        final = _on_disk(new)
        expected = old if what == "writing" else new
        assert final == {p: expected[p] for p in new}, (what, k)
        outcomes.add((what, mixed, report is None))
    # the cases really reached the states that matter: a mixed set, a missing report
    assert ("switching", True, True) in outcomes and ("switching", False, False) in outcomes


def test_a_stage_left_by_a_killed_stream_is_removed(tmp_path):
    """The stream's staging folder (named like the publish's, or like the old
    ``.stereosim-stage-frames-PID-`` ones) of a dead process is removed by the next publish;
    one of a live process is left alone."""
    dead = 2**22 + 12345  # above the default pid_max of 4,194,304: never a live process
    for name in (f"{outputs.STAGE_PREFIX}{dead}-abc", f"{outputs.STAGE_PREFIX}frames-{dead}-x"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "disparity_00000.pfm").write_bytes(b"PF")
    live = outputs.new_stage(tmp_path)
    assert live.name.startswith(f"{outputs.STAGE_PREFIX}{os.getpid()}-")
    publish({tmp_path / "x.bin": b"x"})
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, "x.bin"])


def test_a_failed_rename_puts_the_manifest_back(tmp_path, monkeypatch):
    out = tmp_path / "out"
    old = _stream_set(out, "old")
    publish(old, manifest=out / "report.json")
    real = os.replace

    def failing(src, dst):
        if str(dst).endswith("f05.pfm"):
            raise OSError(errno.EIO, "Input/output error")
        real(src, dst)

    monkeypatch.setattr(outputs.os, "replace", failing)
    with pytest.raises(InputError, match="cannot publish .*f05.pfm"):
        publish(_stream_set(out, "new"), manifest=out / "report.json")
    monkeypatch.setattr(outputs.os, "replace", real)
    assert _on_disk(old) == old
    assert _stages(out) == []


@pytest.mark.parametrize("to_a_thread", [False, True])
def test_signals_are_held_from_the_switch_to_the_end_of_the_clean_up(tmp_path, monkeypatch,
                                                                     to_a_thread):
    """A SIGTERM that comes while the set is switched is delivered once the clean-up is done
    -- also when another thread (torch's, tqdm's) takes it: the new set is whole, no staging
    folder is left, and the handler knows the outputs were written. One that comes while the
    files are staged leaves the old set."""
    out = tmp_path / "out"
    old, new = _stream_set(out, "old"), _stream_set(out, "new")
    publish(old, manifest=out / "report.json")
    real_fsync, real_write = outputs._fsync_folder, outputs._write_fd
    done = threading.Event()
    other = threading.Thread(target=done.wait)
    if to_a_thread:
        other.start()
    try:
        with signals.handling() as handler:
            def fsync_then_signal(folder):
                if to_a_thread:  # a thread that does not block it: the handler must keep it
                    signal.pthread_kill(other.ident, signal.SIGTERM)
                    time.sleep(0.01)
                else:
                    os.kill(os.getpid(), signal.SIGTERM)  # to the process (BLAS threads too)
                real_fsync(folder)

            monkeypatch.setattr(outputs, "_fsync_folder", fsync_then_signal)
            with pytest.raises(signals.Terminated):
                publish(new, manifest=out / "report.json")
            assert handler.published
    finally:
        done.set()
        if to_a_thread:
            other.join()
    assert _on_disk(new) == new and _stages(out) == []
    monkeypatch.setattr(outputs, "_fsync_folder", real_fsync)
    calls = []

    def write_then_signal(fd, data):
        calls.append(1)
        if len(calls) == 4:
            os.kill(os.getpid(), signal.SIGTERM)  # not held while staging: delivered at once
        real_write(fd, data)

    monkeypatch.setattr(outputs, "_write_fd", write_then_signal)
    with signals.handling() as handler, pytest.raises(signals.Terminated):
        publish(old, manifest=out / "report.json")
    assert not handler.published
    assert _on_disk(new) == new and _stages(out) == []


def test_check_outputs_refuses_an_output_on_an_input(tmp_path):
    (tmp_path / "l.png").write_bytes(b"x")
    (tmp_path / "link.png").symlink_to(tmp_path / "l.png")
    for output in (tmp_path / "l.png", tmp_path / "sub" / ".." / "l.png", tmp_path / "link.png"):
        with pytest.raises(InputError, match="--html path .* is the input --left .*l.png: "
                                             "write it elsewhere"):
            check_outputs([(output, "--html")], [(tmp_path / "l.png", "--left"), (None, "--gt")])
    check_outputs([(tmp_path / "r.png", "--html")], [(tmp_path / "l.png", "--left")])


def test_check_outputs_refuses_an_output_that_is_the_folder_of_another(tmp_path):
    for pairs in ([(tmp_path / "x", "--out"), (tmp_path / "x" / "A" / "disp0.pfm", "--save")],
                  [(tmp_path / "x" / "A" / "disp0.pfm", "--save"), (tmp_path / "x", "--out")]):
        with pytest.raises(InputError, match=r"--out path .*x is a folder --save writes into"):
            check_outputs(pairs)


def test_the_repair_waits_while_another_process_holds_a_folder_of_the_killed_set(tmp_path):
    """Rolling a killed set forward needs the lock of each of its folders: while another
    process holds one (here: another open file, which flock treats alike), the set is left as
    it is and the publish goes on; the next publish finishes it."""
    out = tmp_path / "out"
    publish(_stream_set(out, "old"), manifest=out / "report.json")
    new = _stream_set(out, "new")
    _killed_publish(new, out / "report.json", kill_after=3)
    half = _on_disk(new)
    with outputs.folder_lock(out / "frames"):
        publish({out / "other.bin": b"x"})
        assert _on_disk(new) == half and any((s / "journal.json").exists() for s in _stages(out))
    publish({out / "other.bin": b"y"})
    assert _on_disk(new) == new and _stages(out) == []
