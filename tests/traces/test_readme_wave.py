"""README.md's waveform example, run as the README writes it: ``stereosim run --vcd ...`` on the
default scene, then ``stereosim wave`` on that dump; the window the README picks shows the
SVA at work (every SVA signal it draws changes to a nonzero value inside the window), not a
stretch before the first disparity."""

from __future__ import annotations

import shlex
from pathlib import Path

from stereosim.sim.cli import main
from stereosim.traces.dumpread import read_dump
from stereosim.traces.log import parse_patterns
from stereosim.traces.vcdread import value_at
from stereosim.traces.wave import match_vars, window_units

README = Path(__file__).resolve().parents[2] / "README.md"


def _readme_commands() -> tuple[list[str], list[str]]:
    """The arguments of README's ``stereosim wave`` line and of the ``stereosim run`` line that
    writes the dump it draws."""
    lines = [shlex.split(line, comments=True) for line in README.read_text().splitlines()
             if line.startswith("stereosim ")]
    wave = next(words[1:] for words in lines if words[1] == "wave")
    dump = wave[1]
    run = next(words[1:] for words in lines
               if words[1] == "run" and dump in words and words[words.index(dump) - 1] == "--vcd")
    return run, wave


def _option(args: list[str], name: str) -> str:
    return args[args.index(name) + 1]


def test_the_readme_wave_example_shows_the_sva_at_work(tmp_path, monkeypatch, capsys):
    run, wave = _readme_commands()
    monkeypatch.chdir(tmp_path)
    assert main(run) == 0
    assert main(wave) == 0
    assert Path(_option(wave, "--png")).stat().st_size > 0
    capsys.readouterr()
    data = read_dump(wave[1])
    a, b = window_units(_option(wave, "--window"), data)
    drawn = match_vars(data.vars, parse_patterns([_option(wave, "--signals")]))
    sva = [v for v in drawn if v.path.startswith("top.sva.")]
    assert sva, "the README's wave example draws no SVA signal"
    for var in sva:
        times, values = data.changes[var.code]
        inside = [v for t, v in zip(times, values) if a < t <= b]
        assert value_at(times, values, a) or any(inside), (
            f"{var.path} is 0 throughout the README's window {_option(wave, '--window')}")
