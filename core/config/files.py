"""Reading a TOML file of the configuration's kind (a config file, a lent network, an energy
table, a sweep): one line for every way a file can be unusable."""

from __future__ import annotations

import tomllib
from pathlib import Path

from stereosim.core.errors import ConfigError, UserError
from stereosim.core.outputs import path_text


def read_toml(path, what: str, error: type[UserError] = ConfigError) -> dict:
    """The parsed TOML file at ``path``; a missing, unreadable, binary or malformed file (or a
    folder) raises ``error`` with one line naming ``what`` and the file."""
    p = Path(path)
    shown = path_text(p)
    try:
        if p.is_dir():
            raise error(f"{what} {shown} is a folder: give the path of a TOML file")
        if not p.is_file():
            raise error(f"{what} {shown} not found: give the path of a TOML file")
        text = p.read_text()
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise error(f"cannot read {what} {shown} ({reason}): check the file and its "
                    "permissions") from None
    except UnicodeDecodeError:
        raise error(f"{what} {shown} is not UTF-8 text: give a TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {shown} is not valid TOML: {exc}") from None
    except RecursionError:  # the reader recurses once per level of [[[...]]] or {a = {...}}
        raise error(f"{what} {shown} nests arrays or tables too deeply to be read: flatten "
                    "them") from None
