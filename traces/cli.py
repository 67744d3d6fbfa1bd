"""The ``stereosim wave`` subcommand: draw signals of a VCD or FST dump as a PNG waveform.

``sim/cli.py`` registers it with :func:`add_wave_parser`; errors are :class:`core.errors.UserError`
(one line, exit status 2, from ``sim.cli.main``). The output path is checked before the dump is
read -- writable, and not the dump itself (compared by real path and by file identity, so a
symbolic or hard link to the dump is refused too) -- and the PNG is written atomically, only
after it has been drawn.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from stereosim.core.outputs import atomic_write_bytes, check_outputs
from stereosim.traces.dumpread import read_dump
from stereosim.traces.log import parse_patterns
from stereosim.traces.wave import (
    clock_var,
    match_vars,
    parse_wave_window,
    wave_png,
    window_clock,
    window_units,
)


def add_wave_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``wave`` to the ``stereosim`` subparsers; returns the new parser."""
    w = subparsers.add_parser(
        "wave", help="draw signals of a VCD or FST dump as a waveform PNG",
        description="Draw the signals of a VCD or FST dump that match glob patterns as a "
        "waveform: status signals by name and colour, counts in decimal.",
    )
    w.add_argument("dump", metavar="FILE",
                   help="a VCD or FST dump (e.g. from stereosim run --vcd t.vcd or t.fst)")
    w.add_argument(
        "--signals", "--trace", dest="signals", action="append", metavar="PATTERNS",
        help="comma-separated glob patterns on dotted signal paths, repeatable, e.g. "
        "'clocks.sva,top.sva.output.*'; each must match a signal (default: every status "
        "signal, or every signal of a dump without any; at most 64 rows; --trace is the same "
        "option, named as in stereosim run)",
    )
    w.add_argument(
        "--window", "--trace-window", dest="window", metavar="A:B",
        help="window, as stereosim run --trace-window: a time with units fs/ps/ns/us/ms/s "
        "(e.g. 0:40us, 1.5ns:2us), integers in the dump's time unit (fs for stereosim), or "
        "cycles of a clock in the dump (sva:A:B, nna:A:B, camera:A:B); a missing bound is the "
        "dump's start or end",
    )
    w.add_argument("--png", metavar="OUT.png", required=True, help="output PNG file")
    w.add_argument("--title", help="title above the waveform")
    w.set_defaults(func=cmd_wave)
    return w


def cmd_wave(args) -> int:
    patterns = parse_patterns(args.signals)  # () = the overview
    out = Path(args.png)
    check_outputs({out: "--png"}, {args.dump: "dump"})  # never the dump it reads
    parse_wave_window(args.window)  # a bad window fails before the dump is read
    chosen = []

    def select(variables):
        chosen.extend(match_vars(variables, patterns))
        clock = clock_var(args.window, variables)
        return chosen + ([clock] if clock is not None and clock not in chosen else [])

    data = read_dump(args.dump, select)
    a, b = window_units(args.window, data)
    png = wave_png(data, chosen, a, b, title=args.title, clock=window_clock(args.window, data))
    atomic_write_bytes(out, png)
    print(f"wrote {out} ({len(chosen)} signals, {a}..{b} x {data.unit_fs} fs)")
    return 0
