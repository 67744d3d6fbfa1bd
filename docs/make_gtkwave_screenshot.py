"""Regenerate docs/img/gtkwave_view.png: GTKWave opening the .gtkw of a real `stereosim run`.

    python docs/make_gtkwave_screenshot.py

Needs GTKWave, Xvfb, xdotool and ImageMagick's ``import`` (Debian: ``apt install gtkwave xvfb
xdotool imagemagick``). The script runs (the command is printed, so it can be repeated by hand)

    stereosim run --vcd TMP/t.vcd --trace-window rows:0:2 --signals PATTERNS --out TMP/out

on the embedded default scene (Middlebury 2014 Motorcycle), starts a private X server (Xvfb on a
free display), opens ``TMP/t.gtkw`` with ``gtkwave`` exactly as a user would -- no option but
the save file -- and saves a picture of GTKWave's window. tests/traces/test_gtkwave_screenshot.py
uses :func:`gtkwave_view` the same way and checks the picture.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PICTURE = HERE / "img" / "gtkwave_view.png"
PROGRAMS = ("gtkwave", "Xvfb", "xdotool", "import")
SIGNALS = ("top.nna.*.sub0.status,top.nna.*.sub0.line_buffer.*,top.nna.*.sub0.out.valid,"
           "top.fifo.nna_*_to_sva.occupancy,top.sva.status,top.sva.input.row,"
           "top.sva.output.*,top.sink.count")

# Tcl run by GTKWave once the save file is loaded: what it shows, written to a file.
PROBE_TCL = """set f [open {%(tmp)s} w]
puts $f "start [gtkwave::getWindowStartTime]"
puts $f "end [gtkwave::getWindowEndTime]"
set n [gtkwave::getTotalNumTraces]
for {set i 0} {$i < $n} {incr i} { puts $f "trace [gtkwave::getTraceNameFromIndex $i]" }
close $f
file rename {%(tmp)s} {%(out)s}
"""


def missing_programs() -> list[str]:
    """The programs of :data:`PROGRAMS` not on the PATH."""
    return [p for p in PROGRAMS if shutil.which(p) is None]


@contextlib.contextmanager
def xvfb(width: int = 1600, height: int = 1000, timeout: float = 10.0):
    """A private X server on a free display (Xvfb picks it); yields the DISPLAY value."""
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(
        ["Xvfb", "-displayfd", str(write_fd), "-screen", "0", f"{width}x{height}x24",
         "-nolisten", "tcp"],
        pass_fds=(write_fd,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_fd)
    try:
        number = b""
        deadline = time.monotonic() + timeout
        os.set_blocking(read_fd, False)
        while not number.endswith(b"\n"):
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError("Xvfb did not start")
            try:
                number += os.read(read_fd, 16)
            except BlockingIOError:
                time.sleep(0.05)
        yield f":{int(number)}"
    finally:
        os.close(read_fd)
        _stop(proc)


def _stop(proc: subprocess.Popen) -> None:
    """End a program we started: politely, then for sure."""
    proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _run(args: list[str], env: dict, timeout: float) -> str:
    return subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout,
                          check=False).stdout


def _largest_window(env: dict, pid: int, timeout: float) -> str | None:
    """The id of GTKWave's main window (its largest visible one), or None."""
    best, best_area = None, 0
    for wid in _run(["xdotool", "search", "--onlyvisible", "--pid", str(pid)], env,
                    timeout).split():
        geometry = _run(["xdotool", "getwindowgeometry", wid], env, timeout)
        for line in geometry.splitlines():
            if "Geometry:" in line:
                w, h = (int(v) for v in line.split()[-1].split("x"))
                if w * h > best_area:
                    best, best_area = wid, w * h
    return best if best_area > 100 * 100 else None


def gtkwave_view(gtkw: Path, png: Path, display: str, *, timeout: float = 20.0,
                 settle: float = 1.0) -> dict:
    """Open ``gtkw`` with GTKWave on ``display``, save a picture of its window to ``png`` and
    return what GTKWave reports it shows: ``{"start": fs, "end": fs, "traces": [names]}``
    (the names in the signal pane, group labels included). Everything is bounded by
    ``timeout`` seconds; GTKWave is closed before returning."""
    work = Path(tempfile.mkdtemp(prefix="gtkwave-view-"))
    probe, report = work / "probe.tcl", work / "probe.txt"
    probe.write_text(PROBE_TCL % {"tmp": work / "probe.part", "out": report})
    env = dict(os.environ, DISPLAY=display)
    env.pop("WAYLAND_DISPLAY", None)
    proc = subprocess.Popen(["gtkwave", "-S", str(probe), str(gtkw)], env=env, cwd=work,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    try:
        while not report.exists():
            if proc.poll() is not None:
                raise RuntimeError(f"gtkwave exited with status {proc.returncode}")
            if time.monotonic() > deadline:
                raise TimeoutError("GTKWave did not load the save file in time")
            time.sleep(0.1)
        wid = None
        while wid is None:
            if time.monotonic() > deadline:
                raise TimeoutError("GTKWave's window did not appear in time")
            wid = _largest_window(env, proc.pid, max(1.0, deadline - time.monotonic()))
        time.sleep(settle)  # let GTKWave finish drawing
        subprocess.run(["import", "-window", wid, str(png)], env=env, check=True,
                       timeout=max(1.0, deadline - time.monotonic()), capture_output=True)
    finally:
        _stop(proc)
    shown = {"start": None, "end": None, "traces": []}
    for line in report.read_text().splitlines():
        key, _, value = line.partition(" ")
        if key == "trace":
            shown["traces"].append(value)
        else:
            shown[key] = int(value)
    shutil.rmtree(work, ignore_errors=True)
    return shown


def strip_metadata(png: Path) -> None:
    """Re-save a PNG without ImageMagick's dates and software text."""
    from PIL import Image

    with Image.open(png) as img:
        pixels = img.convert("RGB")
    pixels.save(png, optimize=True)


def main() -> int:
    if missing_programs():
        print(f"needs {', '.join(missing_programs())} (apt install gtkwave xvfb xdotool "
              "imagemagick)", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        vcd = Path(tmp) / "t.vcd"
        run = [sys.executable, "-m", "stereosim.sim.cli", "run", "--out", str(Path(tmp) / "out"),
               "--vcd", str(vcd), "--trace-window", "rows:0:2", "--signals", SIGNALS]
        print("$ " + " ".join(shlex.quote(a) for a in run), flush=True)
        subprocess.run(run, check=True)
        with xvfb() as display:
            shown = gtkwave_view(vcd.with_suffix(".gtkw"), PICTURE, display)
        strip_metadata(PICTURE)
    print(f"wrote {PICTURE}: GTKWave shows {shown['start']}..{shown['end']} fs, "
          f"{len(shown['traces'])} rows")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
