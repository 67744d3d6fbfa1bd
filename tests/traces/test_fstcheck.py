"""Crafted FST files against ``stereosim wave``: a block whose declared length or size the reader
library would trust (it allocates it, and aborts the process when it cannot) and a wrapper
block that inflates past the cap give one line and exit status 2 -- run as a separate process,
so an abort shows as a negative return code -- with the process's peak memory bounded. The
files the project and other writers produce pass the checks."""

from __future__ import annotations

import re
import struct
import subprocess
import sys
import zlib

import pytest

from stereosim.core.errors import InputError
from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.traces.dumpread import read_dump
from stereosim.traces.fst import fst_bytes
from stereosim.traces.fstcheck import MAX_FST_BYTES, checked_fst
from stereosim.traces.vcd import vcd_bytes
from stereosim.traces.vcdread import read_vcd

#: Runs ``stereosim wave FILE --png OUT`` in a child and prints its return code, its stderr
#: and its peak resident memory in kB (the grandchild's, not this test process's).
_WAVE_WITH_PEAK = """
import resource, subprocess, sys
done = subprocess.run([sys.executable, "-m", "stereosim.sim.cli", "wave", sys.argv[1],
                       "--png", sys.argv[2]], capture_output=True, text=True)
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(done.returncode, peak)
sys.stdout.write(done.stderr)
"""
#: Well above what `stereosim wave` needs for the synthetic dump (about 130 MB), well below
#: what inflating the crafted wrapper whole takes.
PEAK_LIMIT_KB = 320 * 1024
#: The crafted wrapper's content: zeros, inflating to this many bytes.
BOMB_BYTES = 384 << 20


def _wave(path, png):
    done = subprocess.run([sys.executable, "-c", _WAVE_WITH_PEAK, str(path), str(png)],
                          capture_output=True, text=True, timeout=300, check=True)
    head, _, err = done.stdout.partition("\n")
    code, peak_kb = (int(x) for x in head.split())
    return code, peak_kb, err


@pytest.fixture(scope="module")
def fst(tmp_path_factory):
    log = synthetic_log(400, seed=8)
    folder = tmp_path_factory.mktemp("fstcheck")
    (folder / "t.fst").write_bytes(fst_bytes(log))
    (folder / "t.vcd").write_bytes(vcd_bytes(log))
    return folder / "t.fst", folder / "t.vcd"


def _blocks(data: bytes) -> dict[int, int]:
    """The offset of each block of ``data`` by its type byte (the writer writes one of each)."""
    blocks, pos = {}, 0
    while pos < len(data):
        blocks[data[pos]] = pos
        pos += 1 + struct.unpack_from(">Q", data, pos + 1)[0]
    return blocks


def _with_u64(data: bytes, at: int, value: int) -> bytes:
    out = bytearray(data)
    struct.pack_into(">Q", out, at, value)
    return bytes(out)


def _crafted(body: bytes) -> dict[str, bytes]:
    """What a hostile file declares: 2**40 as a block's length, as the geometry's and the
    hierarchy's uncompressed length, and as the time table's count of instants."""
    blocks = _blocks(body)
    vc, geometry, hierarchy = blocks[8], blocks[3], blocks[6]
    vc_end = vc + 1 + struct.unpack_from(">Q", body, vc + 1)[0]
    return {
        "geometry length": _with_u64(body, geometry + 1, 2**40),
        "hierarchy length": _with_u64(body, hierarchy + 1, 2**40),
        "value-change length": _with_u64(body, vc + 1, 2**40),
        "hierarchy size": _with_u64(body, hierarchy + 9, 2**40),
        "geometry size": _with_u64(body, geometry + 9, 2**40),
        "instants": _with_u64(body, vc_end - 8, 2**40),
    }


def test_the_writers_layout_is_what_the_crafting_assumes(fst):
    """libfst writes the header, one value-change block, the geometry, the hierarchy."""
    assert list(_blocks(fst[0].read_bytes())) == [0, 8, 3, 6]


def test_declared_lengths_are_refused_in_one_line_by_wave(fst, tmp_path):
    """Each crafted file gives one line and exit status 2 (the reader library, given them,
    aborts the process on most)."""
    for name, data in _crafted(fst[0].read_bytes()).items():
        path = tmp_path / (name.replace(" ", "_") + ".fst")
        path.write_bytes(data)
        code, peak_kb, err = _wave(path, tmp_path / "w.png")
        assert code == 2, (name, code, err)
        assert err.startswith(f"stereosim: error: FST file {path}") and err.count("\n") == 1, err
        assert peak_kb < PEAK_LIMIT_KB, (name, peak_kb)
        assert not (tmp_path / "w.png").exists()


@pytest.fixture(scope="module")
def bomb(tmp_path_factory):
    """A gzip stream of :data:`BOMB_BYTES` zeros (a few hundred kB)."""
    deflate = zlib.compressobj(1, zlib.DEFLATED, 16 + zlib.MAX_WBITS)
    zeros = bytes(1 << 20)
    return b"".join([deflate.compress(zeros) for _ in range(BOMB_BYTES >> 20)]
                    + [deflate.flush()])


@pytest.mark.parametrize("declared, message", [
    (2**40, "declares 1,099,511,627,776 bytes inside its wrapper block, above the"),
    (MAX_FST_BYTES + 1, "inside its wrapper block, above the 1,073,741,824"),
    (BOMB_BYTES, r"is corrupt \(the header block"),  # inflated in chunks, then checked
    (1 << 20, "inflates past the 1,048,576 bytes it declares"),
])
def test_a_wrapper_that_inflates_past_the_cap(bomb, tmp_path, declared, message):
    """A wrapper is inflated in chunks and refused once its declared size or what it inflates
    to passes the cap; memory stays bounded (the reader library inflates it whole: 1.3 GB of
    resident memory for a file of 1.2 GB inside)."""
    path = tmp_path / "bomb.fst"
    path.write_bytes(bytes([254]) + struct.pack(">QQ", 16 + len(bomb), declared) + bomb)
    code, peak_kb, err = _wave(path, tmp_path / "w.png")
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"stereosim: error: FST file {path}")
    assert re.search(message, err), err
    assert peak_kb < PEAK_LIMIT_KB, peak_kb
    assert list(tmp_path.iterdir()) == [path]


def test_a_wrapper_shorter_than_it_declares(fst, tmp_path):
    body = fst[0].read_bytes()
    packed = zlib.compress(body, wbits=16 + zlib.MAX_WBITS)
    path = tmp_path / "short.fst"
    path.write_bytes(bytes([254]) + struct.pack(">QQ", 16 + len(packed), len(body) + 1) + packed)
    with pytest.raises(InputError, match=r"inflates to [\d,]+ bytes, not the"):
        read_dump(path)


def test_a_wrapped_file_is_read_from_a_scratch_file_that_goes(fst, tmp_path):
    body = fst[0].read_bytes()
    packed = zlib.compress(body, wbits=16 + zlib.MAX_WBITS)
    path = tmp_path / "w.fst"
    path.write_bytes(bytes([254]) + struct.pack(">QQ", 16 + len(packed), len(body)) + packed)
    with checked_fst(path) as inner:
        assert inner != path and inner.read_bytes() == body
    assert not inner.exists()
    assert [v.path for v in read_dump(path).vars] == [v.path for v in read_vcd(fst[1]).vars]
    with checked_fst(fst[0]) as same:
        assert same == fst[0]


@pytest.mark.parametrize("name", ["unknown type", "two headers", "wrapper inside"])
def test_blocks_fst_does_not_define_there(fst, tmp_path, name):
    body = fst[0].read_bytes()
    tail = {"unknown type": bytes([77]) + struct.pack(">Q", 8),
            "two headers": body[:330],
            "wrapper inside": bytes([254]) + struct.pack(">QQ", 16, 0)}[name]
    path = tmp_path / "x.fst"
    path.write_bytes(body + tail)
    with pytest.raises(InputError, match=f"FST file {path} is corrupt"):
        read_dump(path)
