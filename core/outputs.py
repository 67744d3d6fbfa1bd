"""Writing outputs: whole or absent.

Three tools, used by every command that writes files:

* :func:`atomic_write_bytes` -- one file: a temporary file in the same folder, flushed to disk,
  then renamed over the target, so a reader sees the old file or the whole new one.
* :func:`check_outputs` and :func:`publish` -- a *set* of files (a run's disparity maps, report
  and traces). The paths are checked before any work starts (writable folder, not a folder
  themselves, no two outputs on one path and none the folder of another, none an input, names
  the file system accepts). The files are then written into a hidden staging folder beside
  their destination and switched in with renames, under an advisory lock on every destination
  folder; the set's manifest (``report.json``, which lists the SHA-256 of every other file) is
  moved aside first and renamed in last, so a manifest is there only when every file it
  describes is. The switch is journalled: before the first rename the primary staging folder
  (the manifest's) gets ``journal.json``, every rename in order. From the journal to the end
  of the clean-up SIGINT/SIGTERM/SIGHUP are held back (:func:`core.signals.held`). If a rename
  fails, the files switched already are put back from hard-link backups. A process killed
  mid-switch (SIGKILL cannot be held back) leaves its staging folders; the next publish into
  any folder of the set finds them (the process id in their name is dead) and rolls a
  journalled set forward -- its remaining renames, in order -- or removes the staging folder of
  a set that had not started switching. docs/reliability.md says what a reader can see
  meanwhile.
* :func:`folder_lock` -- the advisory lock (``flock``) on a folder; also used by sweeps that
  append rows to a shared ``results.csv``.

:func:`json_text` is the project's one JSON encoder: non-finite numbers become ``null`` and the
result is always strict JSON (``allow_nan=False``).

Every ``OSError`` becomes an :class:`core.errors.InputError` with one line naming the path.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np

from stereosim.core import signals
from stereosim.core.errors import InputError

STAGE_PREFIX = ".stereosim-stage-"
LOCK_TIMEOUT_S = 60.0
_POINTER = "set"  # in every staging folder of a set: the path of the set's primary one
_JOURNAL = "journal.json"  # in the primary staging folder once the switch starts


def describe_os_error(exc: OSError) -> str:
    """``strerror`` (or the exception text) of an OSError, without the errno number."""
    return exc.strerror or str(exc) or type(exc).__name__


def path_text(path: str | bytes | os.PathLike) -> str:
    """A path as it goes into a one-line message: control characters escaped and the middle of
    a very long path (a 5000-character name, say) elided."""
    text = os.fsdecode(os.fspath(path))
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    if len(text) > 200:
        text = f"{text[:120]}...{text[-60:]} ({len(text)} characters)"
    return text


def _fail(action: str, path, exc: OSError) -> InputError:
    reason = describe_os_error(exc)
    path = path_text(path)
    hint = {
        errno.ENOSPC: "free some space or write elsewhere",
        errno.EDQUOT: "free some space or write elsewhere",
        errno.EACCES: "check the folder's permissions or write elsewhere",
        errno.EPERM: "check the folder's permissions or write elsewhere",
        errno.EROFS: "the file system is read-only: write elsewhere",
        errno.ENAMETOOLONG: "use a shorter path",
        errno.EISDIR: "give a file name, not a folder",
        errno.ENOTDIR: "a part of the path is a file, not a folder",
    }.get(exc.errno, "check the path")
    return InputError(f"cannot {action} {path} ({reason}): {hint}")


def _current_umask() -> int:
    """The process umask (reading it means setting it, so it is set straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _write_fd(fd: int, data) -> None:
    """Write all of ``data`` to ``fd`` and flush it to disk."""
    view = memoryview(data).cast("B")
    while view:
        n = os.write(fd, view)
        view = view[n:]
    os.fsync(fd)


def _write_file(path: str, data) -> None:
    """Write ``data`` to a new file ``path`` and flush it to disk (0666 minus the umask)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666 & ~_current_umask())
    try:
        _write_fd(fd, data)
    finally:
        os.close(fd)


def atomic_write_bytes(path: str | os.PathLike, data) -> None:
    """Write ``data`` (bytes-like) to ``path`` so that readers see either the old file or the
    whole new one; on any error nothing is left behind and an InputError names the path."""
    p = Path(path)
    check_outputs([(p, "output")])
    folder = p.parent
    if not folder.is_dir():
        raise InputError(f"output folder {folder} does not exist: create it first")
    tmp_name = None
    try:
        # the temporary file and the name that removes it come together: a signal waits for
        # the end of the stretch (one just after mkstemp left the file behind)
        with signals.held():
            try:
                fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name[:200]}.", suffix=".tmp",
                                                dir=folder)
            except OSError as exc:
                raise _fail("write into", folder, exc) from None
        try:
            os.fchmod(fd, 0o666 & ~_current_umask())
            _write_fd(fd, data)
        finally:
            os.close(fd)
        os.replace(tmp_name, p)
    except OSError as exc:
        _remove_quietly(tmp_name)
        raise _fail("write", p, exc) from None
    except BaseException:
        if tmp_name is not None:
            _remove_quietly(tmp_name)
        raise


def _remove_quietly(path: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


# ----------------------------------------------------------------------------------------------
# checking a set of output paths before the work starts


def _nearest_existing(folder: Path) -> Path:
    probe = folder
    while True:
        try:
            probe.lstat()
            return probe
        except FileNotFoundError:
            if probe.parent == probe:
                return probe
            probe = probe.parent
        except OSError as exc:
            raise _fail("use the folder", folder, exc) from None


def _pairs(paths) -> list[tuple]:
    return list(paths.items() if isinstance(paths, Mapping) else paths)


def _file_id(path: str) -> tuple[int, int] | None:
    """(device, inode) of an existing file, None otherwise."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino)


def check_outputs(paths: Mapping[str | os.PathLike, str] | Iterable[tuple],
                  inputs: Mapping[str | os.PathLike, str] | Iterable[tuple] = ()) -> None:
    """Refuse, before anything is computed, a set of output files that cannot all be written.

    ``paths``: ``(path, label)`` pairs (or a mapping path -> label), the label being what the user
    knows the file as (e.g. ``"--vcd"``); ``inputs`` the same for the files the command reads
    (None or empty paths are skipped). Checks: no two outputs on one path, and none is the
    folder of another; none is an input (same real path or a hard link to one: an output never
    replaces what the command reads); none is an existing folder; the nearest existing ancestor of
    each folder is a folder we may write into (missing folders are created at publish time); every
    name fits the file system's limits.
    """
    read = {os.path.realpath(p): (p, label) for p, label in _pairs(inputs)
            if p is not None and os.fspath(p) != ""}
    read_ids = {ident: entry for ident, entry in ((_file_id(r), e) for r, e in read.items())
                if ident is not None}  # a hard link to an input is that input too
    seen: dict[str, tuple[str, Path]] = {}
    for raw, label in _pairs(paths):
        p = Path(raw)
        if not p.name or p.name in (".", ".."):
            raise InputError(f"{label} path {raw!s} names no file: give a file name")
        real = os.path.realpath(p)
        if real in seen:
            raise InputError(
                f"{seen[real][0]} and {label} would both write {p}: give them different paths"
            )
        if real in read or _file_id(real) in read_ids:
            source, what = read[real] if real in read else read_ids[_file_id(real)]
            raise InputError(f"{label} path {path_text(p)} is the input {what} "
                             f"{path_text(source)}: write it elsewhere")
        seen[real] = (label, p)
        folder = p.parent
        base = _nearest_existing(folder)
        try:
            name_max = os.pathconf(base if base.is_dir() else base.parent, "PC_NAME_MAX")
        except (OSError, ValueError):
            name_max = 255
        long = [part for part in p.parts if len(os.fsencode(part)) > name_max]
        if long or len(os.fsencode(real)) >= 4096:
            raise InputError(f"{label} path {path_text(p)} is too long for the file system: "
                             "use a shorter path")
        try:
            if p.is_dir():
                raise InputError(f"{label} path {p} is a folder: give a file name")
            if not base.is_dir():
                raise InputError(f"{label} path {p}: {base} is a file, not a folder")
        except OSError as exc:
            raise _fail("use", p, exc) from None
        if not os.access(base, os.W_OK | os.X_OK):
            why = "read-only file system" if _read_only(base) else "permission denied"
            raise InputError(f"cannot write {label} into {base} ({why}): write elsewhere")
    for real, (label, p) in seen.items():
        folder = os.path.dirname(real)
        while folder not in seen and os.path.dirname(folder) != folder:
            folder = os.path.dirname(folder)
        if folder in seen:
            above, q = seen[folder]
            raise InputError(f"{above} path {path_text(q)} is a folder {label} writes into "
                             f"({path_text(p)}): give them different paths")


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


# ----------------------------------------------------------------------------------------------
# the lock and the publish step


def _try_lock(folder: str | os.PathLike) -> int | None:
    """An open descriptor of ``folder`` holding its exclusive ``flock``, or None while another
    process holds it."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError as exc:
        raise _fail("lock", folder, exc) from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return fd
    except BlockingIOError:
        os.close(fd)
        return None
    except BaseException:
        os.close(fd)
        raise


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike, timeout_s: float = LOCK_TIMEOUT_S) -> Iterator[None]:
    """Hold an exclusive advisory lock (``flock``) on ``folder`` (which must exist). Waits up to
    ``timeout_s`` for another stereosim process to release it, then raises InputError."""
    deadline = time.monotonic() + timeout_s
    while (fd := _try_lock(folder)) is None:
        if time.monotonic() > deadline:
            raise InputError(
                f"another process has held the lock on {folder} for more than "
                f"{timeout_s:g} s: wait for it or write elsewhere"
            )
        time.sleep(0.01)
    try:
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def new_stage(folder: str | os.PathLike) -> Path:
    """A new hidden staging folder in ``folder`` (which must exist), named for this process:
    once the process is dead, the next publish into ``folder`` removes it."""
    try:
        return Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{os.getpid()}-", dir=folder))
    except OSError as exc:
        raise _fail("write into", folder, exc) from None


def _stage_pid(name: str) -> int | None:
    """The process id in a staging folder's name (older streams put ``frames-`` before it)."""
    if not name.startswith(STAGE_PREFIX):
        return None
    pid_text = name[len(STAGE_PREFIX):].removeprefix("frames-").split("-", 1)[0]
    return int(pid_text) if pid_text.isdigit() else None


def _fsync_folder(folder: str | os.PathLike) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _write_journal(primary: Path, moves: list[tuple[Path, Path]], stages: list[Path]) -> None:
    """The commit point of a set: every rename (staged file -> target, in order) and every
    staging folder (the primary last), written whole into the primary staging folder."""
    doc = {"stages": [os.fsdecode(os.path.abspath(s)) for s in stages],
           "moves": [[os.fsdecode(os.path.abspath(a)), os.fsdecode(os.path.abspath(b))]
                     for a, b in moves]}
    tmp = primary / f"{_JOURNAL}.tmp"
    _write_file(str(tmp), json.dumps(doc).encode())
    os.replace(tmp, primary / _JOURNAL)
    _fsync_folder(primary)


def _read_journal(stage: Path) -> dict | None:
    """The journal of the set ``stage`` belongs to, or None (the set never started switching,
    or the stage is not a publish's)."""
    try:
        primary = Path(os.fsdecode((stage / _POINTER).read_bytes()))
        doc = json.loads((primary / _JOURNAL).read_bytes())
        moves = [(Path(a), Path(b)) for a, b in doc["moves"]]
        return {"stages": [Path(s) for s in doc["stages"]], "moves": moves}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _roll_forward(journal: dict, locked: set[str]) -> bool:
    """Finish a killed process's switch: its remaining renames, in order, then its staging
    folders. False (nothing changed) while another process holds a folder of the set."""
    folders = sorted({os.path.dirname(b) for _, b in journal["moves"]}, key=os.path.realpath)
    with contextlib.ExitStack() as stack:
        for folder in folders:
            if os.path.realpath(folder) in locked or not os.path.isdir(folder):
                continue  # locked by this publish; or removed since (its files are lost)
            fd = _try_lock(folder)
            if fd is None:
                return False
            stack.callback(os.close, fd)
        try:
            for staged, target in journal["moves"]:
                if os.path.lexists(staged) and os.path.isdir(os.path.dirname(target)):
                    os.replace(staged, target)
        except OSError:
            return False
        for folder in folders:
            _fsync_folder(folder)
        for stage in journal["stages"]:  # the primary, which holds the journal, last
            shutil.rmtree(stage, ignore_errors=True)
    return True


def _repair(folder: Path, locked: set[str]) -> None:
    """The staging folders in ``folder`` of processes that died (``folder`` is locked): a set
    that had started switching is rolled forward, any other staging folder removed."""
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            pid = _stage_pid(entry.name)
            if pid is None or _pid_alive(pid) or not entry.is_dir(follow_symlinks=False):
                continue
            journal = _read_journal(Path(entry.path))
            if journal is None or _roll_forward(journal, locked):
                shutil.rmtree(entry.path, ignore_errors=True)


def _make_folder(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; returns the ones created, outermost first."""
    missing = []
    probe = folder
    while not probe.exists():
        missing.append(probe)
        probe = probe.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _fail("create the folder", folder, exc) from None
    return missing[::-1]


def publish(files: Mapping[str | os.PathLike, object], *,
            manifest: str | os.PathLike | None = None) -> list[str]:
    """Write a set of files (path -> bytes-like, the :class:`~pathlib.Path` of a file written
    already on the same file system, which is moved, or None: the file is removed, if it
    exists, and its folder too if that leaves it empty) as one transaction; returns the paths.

    Either every file is replaced by its new content or (on any error, interrupt or signal) every
    old file is left as it was and no temporary file remains. Missing destination folders are
    created (and removed again if the publish fails before anything is in them). ``manifest``
    (one of the paths; e.g. ``report.json``) is moved aside before the first rename and renamed
    in last: it is never beside files it does not describe. A process killed while switching
    leaves a state the next publish into any folder of the set finishes (module docstring).
    """
    check_outputs([(p, "output") for p in files])
    targets = [Path(p) for p in files]
    blobs = list(files.values())
    order = list(range(len(targets)))
    if manifest is not None:
        last = targets.index(Path(manifest))
        order = [i for i in order if i != last] + [last]
    folders = sorted({t.parent for t in targets}, key=os.path.realpath)
    primary = targets[order[-1]].parent
    created: list[Path] = []
    stages: dict[Path, Path] = {}
    try:
        for folder in [primary, *(f for f in folders if f != primary)]:
            created += _make_folder(folder)
            stages[folder] = new_stage(folder)
            pointer = os.fsencode(os.path.abspath(stages[primary]))
            try:
                _write_file(str(stages[folder] / _POINTER), pointer)
            except OSError as exc:
                raise _fail("write into", folder, exc) from None
        staged = []
        for i, (target, blob) in enumerate(zip(targets, blobs, strict=True)):
            tmp = stages[target.parent] / f"{i}.new"
            if blob is None:  # removed at the switch: moved into the stage, removed with it
                staged.append(tmp.with_suffix(".gone"))
                continue
            try:
                if isinstance(blob, Path):  # written already (on this file system): moved
                    os.replace(blob, tmp)
                else:
                    _write_file(str(tmp), blob)
            except OSError as exc:
                raise _fail("write", target, exc) from None
            staged.append(tmp)
        with contextlib.ExitStack() as locks:
            for folder in folders:
                locks.enter_context(folder_lock(folder))
            with signals.held():  # from the repair to the end of the clean-up
                locked = {os.path.realpath(f) for f in folders}
                for folder in folders:
                    _repair(folder, locked)
                moves = [(targets[i], staged[i]) if blobs[i] is None else (staged[i], targets[i])
                         for i in order if blobs[i] is not None or os.path.lexists(targets[i])]
                if moves:
                    _switch(moves, [*(s for f, s in stages.items() if f != primary),
                                    stages[primary]], manifest is not None)
                for folder in folders:
                    _fsync_folder(folder)
                created = []
                signals.note_published()
                _remove_stages(stages, primary)
                for folder in {t.parent for t, b in zip(targets, blobs) if b is None}:
                    with contextlib.suppress(OSError):
                        folder.rmdir()  # a folder the removals emptied (only if empty)
        return [str(t) for t in targets]
    finally:
        with signals.held():
            _remove_stages(stages, primary)
            for folder in reversed(created):
                with contextlib.suppress(OSError):
                    folder.rmdir()  # only if still empty


def _remove_stages(stages: dict[Path, Path], primary: Path) -> None:
    """The staging folders of a set, the primary (which may hold the journal) last."""
    for _folder, stage in sorted(stages.items(), key=lambda item: item[0] == primary):
        shutil.rmtree(stage, ignore_errors=True)


def _switch(moves: list[tuple[Path, Path]], stages: list[Path], manifest: bool) -> None:
    """Journal the renames, then do them (the manifest, the last move, moved aside first);
    on a failure put the old files back and drop the journal."""
    try:
        _write_journal(stages[-1], moves, stages)
    except OSError as exc:
        raise _fail("write into", stages[-1].parent, exc) from None
    done: list[tuple[Path, Path, Path | None]] = []
    aside = None
    manifest_target = moves[-1][1] if manifest else None
    current = moves[0][1]
    try:
        if manifest_target is not None and os.path.lexists(manifest_target):
            current = manifest_target
            os.replace(manifest_target, moves[-1][0].with_suffix(".old"))
            aside = moves[-1][0].with_suffix(".old")
        for staged, target in moves:
            current = target
            backup = aside if target == manifest_target else None
            if backup is None and os.path.lexists(target):
                backup = staged.with_suffix(".old")
                try:
                    os.link(target, backup, follow_symlinks=False)
                except OSError:
                    backup = None  # no hard links here: this file cannot be rolled back
            os.replace(staged, target)
            done.append((staged, target, backup))
    except OSError as exc:
        for staged, target, backup in reversed(done):  # each new file back into its stage
            with contextlib.suppress(OSError):
                os.replace(target, staged)
                if backup is not None:
                    os.replace(backup, target)
        if aside is not None and len(done) < len(moves):  # the old manifest back in place
            with contextlib.suppress(OSError):
                os.replace(aside, manifest_target)
        with contextlib.suppress(OSError):
            os.unlink(stages[-1] / _JOURNAL)
        raise _fail("publish", current, exc) from None


# ----------------------------------------------------------------------------------------------
# JSON


def _finite(obj):
    """``obj`` with every non-finite float replaced by None and numpy scalars made plain."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def json_text(obj, *, indent: int | None = 2) -> str:
    """Strict JSON of ``obj`` (sorted keys, NaN and infinities as ``null``), ending in a
    newline when indented."""
    text = json.dumps(_finite(obj), indent=indent, sort_keys=True, allow_nan=False)
    return text + "\n" if indent is not None else text
