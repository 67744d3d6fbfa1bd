"""The ``stereosim wave`` subcommand: draw signals of a VCD as a PNG waveform.

``sim/cli.py`` registers it with :func:`add_wave_parser`; errors are :class:`sim.errors.UserError`
(one line, exit status 2, from ``sim.cli.main``) and the PNG is written atomically, only after
it has been drawn.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from stereosim.sim.errors import ConfigError
from stereosim.sim.outputs import atomic_write_bytes
from stereosim.traces.vcdread import read_vcd
from stereosim.traces.wave import match_vars, wave_png, window_units


def add_wave_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``wave`` to the ``stereosim`` subparsers; returns the new parser."""
    w = subparsers.add_parser(
        "wave", help="draw signals of a VCD as a waveform PNG",
        description="Draw the signals of a VCD file that match glob patterns as a waveform.",
    )
    w.add_argument("vcd", metavar="FILE.vcd", help="a VCD file (e.g. from stereosim run --vcd)")
    w.add_argument(
        "--signals", "--trace", dest="signals", action="append", metavar="PATTERNS",
        help="comma-separated glob patterns on dotted signal paths, repeatable, e.g. "
        "'clocks.sva,top.sva.output.*' (default: all; at most 64 rows; --trace is the same "
        "option, named as in stereosim run)",
    )
    w.add_argument(
        "--window", "--trace-window", dest="window", metavar="A:B",
        help="time window, as stereosim run --trace-window: numbers with fs/ps/ns/us/ms/s "
        "(e.g. 0:40us, 1.5ns:2us) or integers in the VCD's time unit (fs for stereosim); a "
        "missing bound is the dump's start or end",
    )
    w.add_argument("--png", metavar="OUT.png", required=True, help="output PNG file")
    w.add_argument("--title", help="title above the waveform")
    w.set_defaults(func=cmd_wave)
    return w


def cmd_wave(args) -> int:
    items = ["*"] if args.signals is None else args.signals
    patterns = [p.strip() for item in items for p in item.split(",") if p.strip()]
    if not patterns:
        raise ConfigError("--signals is empty: give glob patterns, e.g. 'top.sva.*'")
    out = Path(args.png)
    chosen = []

    def select(variables):
        chosen.extend(match_vars(variables, patterns))
        return chosen

    data = read_vcd(args.vcd, select)
    a, b = window_units(args.window, data)
    png = wave_png(data, chosen, a, b, title=args.title)
    atomic_write_bytes(out, png)
    print(f"wrote {out} ({len(chosen)} signals, {a}..{b} x {data.unit_fs} fs)")
    return 0
