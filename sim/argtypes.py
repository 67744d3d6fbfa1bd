"""What the subcommands of ``stereosim`` share: argparse types that refuse a bad value by
name (argparse turns the refusal into the command's one-line usage error), and the check of a
long job's one output before it starts."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from stereosim.core.errors import InputError
from stereosim.core.outputs import check_outputs


def finite_float(text: str) -> float:
    """argparse type: a finite number (``nan`` and ``inf`` are refused by name)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return value


def nonnegative_int(text: str) -> int:
    """argparse type: a whole number >= 0."""
    value = int(text) if text.lstrip("-").isdigit() else None
    if value is None or value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a whole number >= 0")
    return value


def nonempty_path(text: str) -> str:
    """argparse type of a file or folder option: the path as given, ``''`` refused (an unset
    shell variable, say) -- taken as unset it would fall back to a default, taken as a path it
    would name the working directory."""
    if text == "":
        raise argparse.ArgumentTypeError("'' is empty: give a path")
    return text


def nonempty_size(text: str) -> str:
    """argparse type of a ``--size`` option: the text as given (parsed by the command, which
    also takes other forms), ``''`` refused like an empty path (:func:`nonempty_path`)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("'' is empty: give WIDTHxHEIGHT, e.g. 1280x720")
    return text


def check_single_output(out: Path, label: str, inputs=()) -> None:
    """Before a long job: its one output can be written (its folder must exist), no input."""
    check_outputs([(out, label)], inputs)
    if not out.parent.is_dir():
        raise InputError(f"output folder {out.parent} does not exist: create it first")
