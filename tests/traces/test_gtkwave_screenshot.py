"""GTKWave (the Debian package) under Xvfb opens the .gtkw that `stereosim run --vcd` writes:
the view is zoomed to fit the trace window and every row has a unique, readable name. GTKWave's
Tcl interface reports what it shows; a picture of its window shows signal transitions across
the whole width of the wave pane. docs/make_gtkwave_screenshot.py starts the programs; this
test skips when one of them is not installed."""

import importlib.util
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from stereosim.sim.synthetic_trace import synthetic_log
from stereosim.sim.tracing import TraceRequest, trace_files, write_traces
from stereosim.traces.gtkw import aliases
from stereosim.traces.log import window

DOCS = Path(__file__).resolve().parents[2] / "docs"


def _script():
    spec = importlib.util.spec_from_file_location("make_gtkwave_screenshot",
                                                  DOCS / "make_gtkwave_screenshot.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SCRIPT = _script()
pytestmark = pytest.mark.skipif(
    bool(SCRIPT.missing_programs()),
    reason=f"needs {', '.join(SCRIPT.missing_programs())} (Debian: gtkwave xvfb xdotool "
    "imagemagick)",
)


RULER_PX = 30  # the time ruler at the top of the wave pane (tick labels), not a trace


def _wave_pane(rgb: np.ndarray) -> tuple[slice, slice]:
    """Rows and columns of GTKWave's wave pane: the one black area of the window."""
    black = (rgb == 0).all(axis=2)
    cols = np.flatnonzero(black.mean(axis=0) > 0.3)
    rows = np.flatnonzero(black.mean(axis=1) > 0.3)
    assert cols.size > 500 and rows.size > 300, "no wave pane in the picture"
    return slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1)


def transition_columns(png: Path) -> np.ndarray:
    """For each pixel column of the wave pane: does some trace change there? A column that
    differs from its left neighbour in at least 4 rows below the time ruler does (a vertical
    grid line changes two columns; a flat trace changes none)."""
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(np.int16)
    rows, cols = _wave_pane(rgb)
    pane = rgb[rows.start + RULER_PX : rows.stop, cols]
    return (np.abs(np.diff(pane, axis=1)).sum(axis=2) > 60).sum(axis=0) >= 4


def per_bin(changed: np.ndarray, bins: int = 40) -> np.ndarray:
    """The number of changing columns in each of ``bins`` equal slices of the pane (about 26
    columns each)."""
    edges = np.linspace(0, changed.size, bins + 1).astype(int)
    return np.array([changed[a:b].sum() for a, b in pairwise(edges)])


@pytest.fixture(scope="module")
def display():
    with SCRIPT.xvfb() as name:
        yield name


@pytest.fixture(scope="module")
def traced(tmp_path_factory):
    """A 4 us window (1 us to 5 us) of the synthetic chip, written as `stereosim run` does."""
    tmp = tmp_path_factory.mktemp("gtkwave")
    log = window(synthetic_log(3000, seed=4), 1_000_000_000, 5_000_000_000)
    request = TraceRequest(vcd=str(tmp / "t.vcd"))
    write_traces(log, request)
    return tmp, log


def test_gtkwave_shows_the_window_zoomed_to_fit_with_unique_names(display, traced):
    tmp, log = traced
    png = tmp / "view.png"
    shown = SCRIPT.gtkwave_view(tmp / "t.gtkw", png, display)
    # zoomed to fit: the view starts at the window's start and ends just after its end
    span = log.end_fs - log.start_fs
    assert shown["start"] == log.start_fs == 1_000_000_000
    assert log.end_fs <= shown["end"] <= log.end_fs + 0.06 * span
    # every signal and clock is in the signal pane once, under its own name
    names = aliases([f"clocks.{c.name}" for c in log.clocks] + [s.path for s in log.signals])
    assert len(set(names)) == len(names) == 78
    assert sorted(n for n in shown["traces"] if n in set(names)) == sorted(names)
    assert "nna/left/sub0/status" in names and "nna/right/sub0/status" in names
    labels = [n for n in shown["traces"] if n not in set(names)]  # group opens and closes
    assert all(labels.count(g) == 2 for g in labels) and "nna/left/sub0" in labels
    # the picture: transitions in every slice of the wave pane, the last one near its right
    # edge (the window is fitted to 1000 of the pane's 1036 columns)
    changed = transition_columns(png)
    counts = per_bin(changed)
    assert (counts[:-2] >= 8).all(), counts
    last = np.flatnonzero(changed).max() / changed.size
    assert 0.93 < last < 0.99, last


def test_the_picture_check_fails_on_a_flat_view(display, traced, tmp_path):
    """The same save file zoomed to about 2 fs: flat traces, which the picture check must
    refuse."""
    tmp, _ = traced
    text = (tmp / "t.gtkw").read_text().splitlines()
    k = next(i for i, ln in enumerate(text) if ln.startswith("*"))
    text[k] = "*0.000000" + text[k][text[k].index(" "):]
    (tmp_path / "flat.gtkw").write_text("\n".join(text) + "\n")
    png = tmp_path / "flat.png"
    shown = SCRIPT.gtkwave_view(tmp_path / "flat.gtkw", png, display)
    assert shown["end"] - shown["start"] < 10  # femtoseconds
    counts = per_bin(transition_columns(png))
    assert (counts[:-2] < 4).sum() > 30, counts


def test_the_files_gtkwave_opens_are_the_run_outputs(traced):
    """The test opens what `stereosim run --vcd` publishes: the dump, its .gtkw and the status
    filter, the .gtkw naming the other two by absolute path."""
    tmp, log = traced
    files = trace_files(log, TraceRequest(vcd=str(tmp / "t.vcd")))
    assert sorted(Path(p).name for p in files) == ["t.gtkw", "t.status.txt", "t.vcd"]
    for path, data in files.items():
        assert Path(path).read_bytes() == data
    text = files[str(tmp / "t.gtkw")].decode()
    assert f'[dumpfile] "{tmp / "t.vcd"}"' in text and f"^1 {tmp / 't.status.txt'}" in text
