"""The SVA back end a network was tuned with, carried in its weight file.

A descriptor network is only as good as the penalties and box it is matched with (issue 46
reports the robust network at 6.24 at its own P1/P2 and 6.87 at the single layer's). So a
weight file (an ``.npz``: :mod:`nna.conv.weights`, :mod:`quant.artifact`) may carry a member
``backend``: a TOML table of the :data:`BACKEND_KEYS` it was tuned with. When the configuration
runs that file, the keys it leaves unset take the file's values (:mod:`core.config.loader`), as
they take :data:`~core.config.schema.DESCRIPTOR_DEFAULTS` for a file that carries none, of
which the CLI says one line (:func:`backend_note`). ``stereosim config backend FILE`` shows a
file's back end and writes one into it (:func:`write_backend`).
"""

from __future__ import annotations

import io
import os
import tomllib

import numpy as np

from stereosim.core.config.schema import DESCRIPTOR_DEFAULTS, SvaConfig
from stereosim.core.errors import ConfigError
from stereosim.core.npz import open_npz
from stereosim.core.outputs import atomic_write_bytes, path_text

#: The SVA keys a network's back end sets: those each descriptor has a tuned value of.
BACKEND_KEYS = tuple(DESCRIPTOR_DEFAULTS["cnn"])
MEMBER = "backend"
_FIX = "write it with stereosim quantize, or give another file"
_REWRITE = "store a new one with stereosim config backend FILE --set sva.KEY=VALUE"


def _check(table, name: str) -> dict:
    """The back-end table of the file ``name``: only :data:`BACKEND_KEYS`, each of its key's
    type (the ranges are checked with the whole configuration)."""
    if not isinstance(table, dict) or set(table) - set(BACKEND_KEYS):
        extra = sorted(set(table) - set(BACKEND_KEYS)) if isinstance(table, dict) else table
        raise ConfigError(f"weight file {name!r}: its back end holds {extra!r}; a back end sets "
                          f"only {', '.join(BACKEND_KEYS)}; {_REWRITE}")
    kinds = {f: type(getattr(SvaConfig(), f)) for f in BACKEND_KEYS}
    for key, value in table.items():
        if type(value) is not kinds[key]:
            want = "true or false" if kinds[key] is bool else "a whole number"
            raise ConfigError(f"weight file {name!r}: its back end's {key} = {value!r} is not "
                              f"{want}; {_REWRITE}")
    return dict(table)


def carried_backend(path) -> dict | None:
    """The back end the weight file at ``path`` carries (key -> value), None if it carries
    none; a damaged file or back end raises :class:`ConfigError` naming the file."""
    name = path_text(os.fspath(path))
    archive = open_npz(os.fspath(path), "weight file", _FIX)
    if MEMBER not in archive.files:
        return None
    try:
        text = archive.scalar(MEMBER, "U")
    except ConfigError as exc:
        raise ConfigError(f"{exc}; {_REWRITE}") from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"weight file {name!r}: its back end is not TOML ({exc}); "
                          f"{_REWRITE}") from None
    return _check(table, name)


def backend_text(values: dict) -> str:
    """The TOML text of a back end (keys in :data:`BACKEND_KEYS` order)."""
    def toml(v):
        return str(v).lower() if isinstance(v, bool) else str(v)

    return "".join(f"{k} = {toml(values[k])}\n" for k in BACKEND_KEYS if k in values)


def write_backend(path, values: dict) -> None:
    """Store the back end ``values`` in the weight file at ``path`` (atomically: the old file or
    the whole new one), every other member unchanged."""
    name = path_text(os.fspath(path))
    values = _check(values, name)
    arrays = dict(open_npz(os.fspath(path), "weight file", _FIX))
    arrays[MEMBER] = np.array(backend_text(values))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def describe(values: dict) -> str:
    """``P1 160, P2 1024 (adaptive, slope 256), box 7``."""
    p2 = f"P2 {values['p2']}"
    if values.get("p2_adaptive"):
        p2 += f" (adaptive, slope {values['p2_slope']})"
    return f"P1 {values['p1']}, {p2}, box {values['box_size']}"


def backend_note(weights: str, descriptor: str, set_keys) -> str | None:
    """One line when a configuration runs a weight file that carries no back end and sets none
    of :data:`BACKEND_KEYS` itself: which back end it keeps. None otherwise."""
    if descriptor != "cnn" or weights == "default":
        return None
    if any(f"sva.{k}" in set_keys for k in BACKEND_KEYS):
        return None
    if carried_backend(weights) is not None:
        return None
    return (f"the network {os.path.basename(weights)} carries no tuned back end, so the SVA "
            f"keeps the cnn descriptor's ({describe(DESCRIPTOR_DEFAULTS['cnn'])}): set sva.p1, "
            "sva.p2, sva.p2_slope and sva.box_size for this network (docs/tuning.md), or store "
            "them in its file with stereosim config backend")
