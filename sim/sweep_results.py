"""The results store of a sweep: ``results.csv``, safe against crashes and shared by sweeps.

One row per point x scene with every override, every report figure (nested keys flattened with
dots; FIFO occupancy histograms left out), the analytic estimate (``estimate.*``) and, when the
scene has GT, the accuracy (``metrics.<mask>.<metric>``); no wall-clock figures, so a sweep run
twice gives the same bytes. Columns: ``point, scene, status, error, point_id``, the swept keys,
then every other column sorted.

Each finished task's row is *appended* (:func:`append_rows`: one ``write`` of the whole line)
while holding the output folder's lock (:func:`core.outputs.folder_lock`), so sweeps sharing an
``--out`` keep each other's rows; a row with a column the header lacks makes the file be
rewritten once, atomically, from a fresh read under the lock. A write that fails (disk full) is
cut back to the last whole row and ends the sweep with a one-line error. Readers ignore a torn
last line (no final newline), and the next append removes it. Appends are not flushed to disk
one by one (a crash of stereosim loses no row; a power cut may lose the last ones, which a rerun
redoes). At the end (:func:`finish_results`), under the lock, the file is rewritten once,
flushed to disk, in a fixed order: this sweep's rows in plan order, then the other rows in file
order, one row per ``point_id`` (its last ok row, else its last row), and ``columns.md`` beside
it says what each column is (:mod:`sim.columns`). A rerun skips every row with ``status`` ok
(:func:`done_point_ids`) and retries the failed ones.

A folder, a device, a file that is not UTF-8 or not a CSV, or one whose header is not a
stereosim results file's, is a one-line :class:`InputError` naming it.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import stat
from pathlib import Path

import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.outputs import atomic_write_bytes, describe_os_error, folder_lock
from stereosim.sim.columns import guide_text

LEAD_COLUMNS = ("point", "scene", "status", "error", "point_id")
CSV_NAME = "results.csv"
GUIDE_NAME = "columns.md"  # what each column of results.csv is (sim/columns.py), beside it


def _cell(value) -> str:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    text = str(value)
    # one row per line: the torn-line rule of the reader and the appender rely on it
    return " ".join(text.splitlines()) if "\n" in text or "\r" in text else text


def column_order(keys, axes: list[str]) -> list[str]:
    """The lead columns, the swept keys, then every other key sorted."""
    lead = list(LEAD_COLUMNS) + [a for a in axes if a not in LEAD_COLUMNS]
    return lead + sorted(set(keys) - set(lead))


def _csv_bytes(columns: list[str], rows: list[dict], *, header: bool = True) -> bytes:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    if header:
        writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row[c]) if row.get(c) is not None else "" for c in columns])
    return buf.getvalue().encode()


def _results_error(path: Path, exc: OSError) -> InputError:
    if isinstance(exc, IsADirectoryError):
        return InputError(f"results file {path} is a folder: move it away or give another --out")
    return InputError(f"cannot use the results file {path} ({describe_os_error(exc)}): check it "
                      "and its folder's permissions, or give another --out")


def _check_regular(fd: int, path: Path) -> None:
    mode = os.fstat(fd).st_mode
    if stat.S_ISDIR(mode):
        raise _results_error(path, IsADirectoryError())
    if not stat.S_ISREG(mode):
        raise InputError(f"results file {path} is not a regular file: give another --out")


def _read_results(path: Path) -> bytes | None:
    """The bytes of a results file, None when there is none; a folder, a device or a file that
    cannot be read is a one-line InputError (never a wait: FIFOs are opened non-blocking)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise _results_error(path, exc) from None
    try:
        _check_regular(fd, path)
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise _results_error(path, exc) from None
    finally:
        os.close(fd)


def _parse(data: bytes, path: Path) -> tuple[list[str], list[dict[str, str]]]:
    """(header, rows) of a results file's bytes; a torn last line (a write cut short, no final
    newline) is ignored, and so are blank lines."""
    whole = data[: data.rfind(b"\n") + 1]
    try:
        records = [r for r in csv.reader(io.StringIO(whole.decode(), newline="")) if r]
    except UnicodeDecodeError:
        raise InputError(f"results file {path} is not UTF-8 text: give another --out") from None
    except csv.Error as exc:
        raise InputError(f"results file {path} is not a valid CSV ({exc}): give another --out"
                         ) from None
    if not records:
        return [], []
    header = records[0]
    return header, [dict(zip(header, r)) for r in records[1:]]


def _check_header(header: list[str], path: Path) -> None:
    if header and tuple(header[: len(LEAD_COLUMNS)]) != LEAD_COLUMNS:
        raise InputError(
            f"{path} is not a stereosim results file (its header does not begin with "
            f"{','.join(LEAD_COLUMNS)}): move it away or give another --out"
        )


def read_rows(path: str | Path) -> list[dict[str, str]]:
    """The rows of a results file ([] when there is none), ignoring a torn last line."""
    p = Path(path)
    data = _read_results(p)
    return [] if data is None else _parse(data, p)[1]


def write_rows(path: Path, rows: list[dict], axes: list[str]) -> None:
    """All rows, atomically, with a deterministic column order: the lead columns, the swept
    keys, then every other column sorted."""
    keys = set().union(*rows) if rows else set()
    atomic_write_bytes(path, _csv_bytes(column_order(keys, axes), rows))


def _open_for_append(path: Path) -> int:
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_CLOEXEC, 0o666)
    except OSError as exc:
        raise _results_error(path, exc) from None
    try:
        _check_regular(fd, path)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _drop_torn_tail(fd: int, size: int) -> int:
    """Cut a torn last line (no final newline) off the file; returns the new size."""
    end = size
    while end > 0:
        start = max(0, end - (1 << 16))
        block = os.pread(fd, end - start, start)
        cut = block.rfind(b"\n")
        if cut >= 0:
            end = start + cut + 1
            break
        end = start
    if end != size:
        os.ftruncate(fd, end)
    return end


def _read_header(fd: int, path: Path) -> list[str] | None:
    """The header of the (torn-free) file open at ``fd``, None when it is empty."""
    head, offset = b"", 0
    while b"\n" not in head:
        block = os.pread(fd, 1 << 16, offset)
        if not block:
            break
        head += block
        offset += len(block)
    header, _ = _parse(head, path)
    _check_header(header, path)
    return header or None


def _write_whole(fd: int, data: bytes, size: int, path: Path) -> None:
    """One ``write`` of ``data`` at the end of the file, which is ``size`` bytes long; if it
    fails or falls short, the file is cut back to ``size`` (its last whole row)."""
    try:
        written = os.write(fd, data)
        if written != len(data):
            raise OSError(0, f"only {written} of {len(data)} bytes could be written")
    except BaseException as exc:
        with contextlib.suppress(OSError):
            if os.fstat(fd).st_size != size + len(data):
                os.ftruncate(fd, size)
        if isinstance(exc, OSError):
            raise InputError(
                f"cannot append to {path} ({describe_os_error(exc)}): free some space or write "
                "elsewhere (the rows written so far are kept)"
            ) from None
        raise


def append_rows(path: Path, rows: list[dict], axes: list[str]) -> None:
    """Append ``rows`` to the results file ``path`` while holding its folder's lock: one write
    of the whole lines in the header's column order; when the header lacks a column of the
    rows, the file (re-read under the lock, so other sweeps' rows stay) is rewritten atomically
    with the wider header."""
    with folder_lock(path.parent):
        fd = _open_for_append(path)
        try:
            size = _drop_torn_tail(fd, os.fstat(fd).st_size)
            header = _read_header(fd, path)
            keys = set().union(*rows)
            if header is None:
                _write_whole(fd, _csv_bytes(column_order(keys, axes), rows), size, path)
            elif keys <= set(header):
                _write_whole(fd, _csv_bytes(header, rows, header=False), size, path)
            else:
                old_header, old_rows = _parse(os.pread(fd, size, 0), path)
                columns = column_order(set(old_header) | keys, axes)
                atomic_write_bytes(path, _csv_bytes(columns, old_rows + rows))
        except OSError as exc:
            raise _results_error(path, exc) from None
        finally:
            os.close(fd)


def _in_order(rows: list[dict], tasks: list) -> list[dict]:
    """This sweep's rows in plan order (``tasks``: its :class:`~sim.sweep.Task` objects), then
    the other rows in file order; one row per point_id: its last ok row, else its last row."""
    planned = {t.point_id for t in tasks}
    mine: dict[str, dict] = {}
    others: dict[str, dict] = {}
    for n, row in enumerate(rows):
        pid = row.get("point_id", "")
        table = mine if pid in planned else others
        key = pid or f"#{n}"  # a row without a point_id is kept as it is
        old = table.get(key)
        if old is None or row.get("status") == "ok" or old.get("status") != "ok":
            table[key] = row
    return [mine[t.point_id] for t in tasks if t.point_id in mine] + list(others.values())


def finish_results(path: Path, tasks: list, axes: list[str]) -> None:
    """Under the folder's lock, rewrite the results file once in its final order (see
    :func:`_in_order`), so the same sweep gives the same bytes however its tasks finished, and
    write the guide to its columns beside it (:data:`GUIDE_NAME`,
    :func:`sim.columns.guide_text`)."""
    with folder_lock(path.parent):
        data = _read_results(path)
        if data is None:
            return
        header, rows = _parse(data, path)
        _check_header(header, path)
        columns = column_order(header, axes)
        ordered = _in_order(rows, tasks)
        # flushed to disk, then renamed over the appended file
        atomic_write_bytes(path, _csv_bytes(columns, ordered))
        fixed = sorted({k for t in tasks for k in t.overrides} - set(axes))
        guide = guide_text(columns, [r for r in ordered if r.get("status") == "ok"], axes, fixed)
        atomic_write_bytes(path.parent / GUIDE_NAME, guide.encode())


def done_point_ids(path: Path) -> set[str]:
    """The ``point_id`` of every row with ``status`` ok in the results file ``path`` (none when
    there is no file), read under its folder's lock: the tasks a rerun skips."""
    with folder_lock(path.parent):
        data = _read_results(path)
    header, rows = _parse(data, path) if data is not None else ([], [])
    _check_header(header, path)
    return {r.get("point_id") for r in rows if r.get("status") == "ok"}
