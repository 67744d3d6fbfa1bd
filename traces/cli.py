"""The ``stereosim wave`` subcommand: draw signals of a VCD as a PNG waveform.

``sim/cli.py`` registers it with :func:`add_wave_parser`; errors are :class:`sim.errors.UserError`
(one line, exit status 2, from ``sim.cli.main``) and the PNG is written atomically, only after
it has been drawn.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.errors import ConfigError
from sim.outputs import atomic_write_bytes
from traces.vcdread import read_vcd
from traces.wave import match_vars, parse_window, wave_png


def add_wave_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``wave`` to the ``stereosim`` subparsers; returns the new parser."""
    w = subparsers.add_parser(
        "wave", help="draw signals of a VCD as a waveform PNG",
        description="Draw the signals of a VCD file that match glob patterns as a waveform.",
    )
    w.add_argument("vcd", metavar="FILE.vcd", help="a VCD file (e.g. from stereosim run --vcd)")
    w.add_argument(
        "--signals", metavar="PATTERNS", default="*",
        help="comma-separated glob patterns on dotted signal paths, e.g. "
        "'clocks.sva,top.sva.output.*' (default: all; at most 64 rows)",
    )
    w.add_argument(
        "--window", metavar="A:B",
        help="time window: integers in the VCD's time unit (fs for stereosim) or numbers with "
        "fs/ps/ns/us/ms/s, e.g. 0:20ns; a missing bound is the dump's start or end",
    )
    w.add_argument("--png", metavar="OUT.png", required=True, help="output PNG file")
    w.add_argument("--title", help="title above the waveform")
    w.set_defaults(func=cmd_wave)
    return w


def cmd_wave(args) -> int:
    patterns = [p.strip() for p in args.signals.split(",") if p.strip()]
    if not patterns:
        raise ConfigError("--signals is empty: give glob patterns, e.g. 'top.sva.*'")
    out = Path(args.png)
    chosen = []

    def select(variables):
        chosen.extend(match_vars(variables, patterns))
        return chosen

    data = read_vcd(args.vcd, select)
    a, b = parse_window(args.window, data)
    png = wave_png(data, chosen, a, b, title=args.title)
    atomic_write_bytes(out, png)
    print(f"wrote {out} ({len(chosen)} signals, {a}..{b} x {data.unit_fs} fs)")
    return 0
