"""Writing outputs: whole or absent.

Three tools, used by every command that writes files:

* :func:`atomic_write_bytes` -- one file: a temporary file in the same folder, flushed to disk,
  then renamed over the target, so a reader sees the old file or the whole new one.
* :func:`check_outputs` and :func:`publish` -- a *set* of files (a run's disparity maps, report
  and traces). The paths are checked before any work starts (writable folder, not a folder
  themselves, no two outputs on one path, names the file system accepts); the files are then
  written into a hidden staging folder beside their destination and published with renames while
  holding an advisory lock on every destination folder, with SIGINT/SIGTERM/SIGHUP held back for
  the few microseconds the renames take. If any rename fails, the files already published are put
  back from hard-link backups: the old set stays intact unless the whole new set is in place.
  A staging folder left by a killed process (SIGKILL cannot be caught) is removed by the next
  publish into that folder.
* :func:`folder_lock` -- the advisory lock (``flock``) on a folder; also used by sweeps that
  append rows to a shared ``results.csv``.

:func:`json_text` is the project's one JSON encoder: non-finite numbers become ``null`` and the
result is always strict JSON (``allow_nan=False``).

Every ``OSError`` becomes an :class:`sim.errors.InputError` with one line naming the path.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import math
import os
import shutil
import signal
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np

from stereosim.sim.errors import InputError

STAGE_PREFIX = ".stereosim-stage-"
LOCK_TIMEOUT_S = 60.0
_HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}


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
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name[:200]}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise _fail("write into", folder, exc) from None
    try:
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


def check_outputs(paths: Mapping[str | os.PathLike, str] | Iterable[tuple]) -> None:
    """Refuse, before anything is computed, a set of output files that cannot all be written.

    ``paths``: ``(path, label)`` pairs (or a mapping path -> label), the label being what the user
    knows the file as (e.g. ``"--vcd"``). Checks: no
    two outputs on one path; none is an existing folder; the nearest existing ancestor of each
    folder is a folder we may write into (missing folders are created at publish time); every
    name fits the file system's limits.
    """
    seen: dict[str, str] = {}
    pairs = paths.items() if isinstance(paths, Mapping) else paths
    for raw, label in pairs:
        p = Path(raw)
        if not p.name or p.name in (".", ".."):
            raise InputError(f"{label} path {raw!s} names no file: give a file name")
        real = os.path.realpath(p)
        if real in seen:
            raise InputError(
                f"{seen[real]} and {label} would both write {p}: give them different paths"
            )
        seen[real] = label
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


def _read_only(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


# ----------------------------------------------------------------------------------------------
# the lock and the publish step


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike, timeout_s: float = LOCK_TIMEOUT_S) -> Iterator[None]:
    """Hold an exclusive advisory lock (``flock``) on ``folder`` (which must exist). Waits up to
    ``timeout_s`` for another stereosim process to release it, then raises InputError."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError as exc:
        raise _fail("lock", folder, exc) from None
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise InputError(
                        f"another process has held the lock on {folder} for more than "
                        f"{timeout_s:g} s: wait for it or write elsewhere"
                    ) from None
                time.sleep(0.01)
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


def _remove_stale_stages(folder: Path) -> None:
    """Staging folders of processes that died (under the folder's lock)."""
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            if not entry.name.startswith(STAGE_PREFIX) or not entry.is_dir(follow_symlinks=False):
                continue
            pid_text = entry.name[len(STAGE_PREFIX):].split("-", 1)[0]
            if pid_text.isdigit() and not _pid_alive(int(pid_text)):
                shutil.rmtree(entry.path, ignore_errors=True)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def publish(files: Mapping[str | os.PathLike, object]) -> list[str]:
    """Write a set of files (path -> bytes-like, or the :class:`~pathlib.Path` of a file
    written already on the same file system, which is moved, or None: the file is removed) as
    one transaction; returns the paths.

    Either every file is replaced by its new content or (on any error, interrupt or signal) every
    old file is left as it was and no temporary file remains. Missing destination folders are
    created (and removed again if the publish fails before anything is in them).
    """
    check_outputs([(p, "output") for p in files])
    targets = [Path(p) for p in files]
    blobs = list(files.values())
    folders = sorted({t.parent for t in targets}, key=lambda f: os.path.realpath(f))
    created: list[Path] = []
    stages: dict[Path, Path] = {}
    try:
        for folder in folders:
            missing = []
            probe = folder
            while not probe.exists():
                missing.append(probe)
                probe = probe.parent
            try:
                folder.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise _fail("create the folder", folder, exc) from None
            created += reversed(missing)
            try:
                stages[folder] = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{os.getpid()}-",
                                                       dir=folder))
            except OSError as exc:
                raise _fail("write into", folder, exc) from None
        staged = []
        for target, blob in zip(targets, blobs, strict=True):
            tmp = stages[target.parent] / target.name
            if blob is None:  # removed at the swap
                staged.append(None)
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
                _remove_stale_stages(folder)
            with _signals_held():
                _swap_in(targets, staged, stages)
            for folder in folders:
                _fsync_folder(folder)
        created = []
        return [str(t) for t in targets]
    finally:
        for stage in stages.values():
            shutil.rmtree(stage, ignore_errors=True)
        for folder in reversed(created):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if still empty


def _swap_in(targets: list[Path], staged: list[Path | None], stages: dict[Path, Path]) -> None:
    """Rename every staged file over its target (None: remove the target); on a failure put
    the old files back."""
    done: list[tuple[Path, Path | None]] = []
    try:
        for target, tmp in zip(targets, staged, strict=True):
            backup = None
            if target.exists():
                backup = stages[target.parent] / f"{target.name}.old"
                try:
                    os.link(target, backup)
                except OSError:
                    backup = None  # no hard links here: this file cannot be rolled back
            if tmp is None:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(target)
            else:
                os.replace(tmp, target)
            done.append((target, backup))
    except OSError as exc:
        for target, backup in reversed(done):
            with contextlib.suppress(OSError):
                if backup is not None:
                    os.replace(backup, target)
                else:
                    os.unlink(target)
        raise _fail("publish", targets[len(done)], exc) from None


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
