"""Loading the configuration: defaults, then a TOML file, then dotted-key overrides.

:func:`load_config` reads the file (:func:`~sim.config.files.read_toml`: one line for every
way a file can be unusable), applies ``--set`` overrides, fills the keys left unset that depend
on others -- the descriptor's tuned back end (:data:`~sim.config.schema.DESCRIPTOR_DEFAULTS`)
and the register widths that follow the descriptor, box, P2 and paths (:func:`derived_widths`)
-- and checks the result once (:func:`sim.config.check.checked_chip`).
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from typing import Any

from stereosim.sim.census_layout import comparison_offsets
from stereosim.sim.config.check import _build, checked_chip
from stereosim.sim.config.files import read_toml
from stereosim.sim.config.schema import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTOR_DEFAULTS,
    CensusConfig,
    ChipConfig,
    CnnConfig,
    SvaConfig,
)
from stereosim.sim.config.widths import CNN_BITS, sgm_widths
from stereosim.sim.errors import ConfigError


def _parse_value(text: str, key: str):
    """A --set value: TOML syntax (numbers, true/false, [a, b], "str"), else a bare string;
    one nested deeper than the TOML reader can recurse is refused by its key."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise ConfigError(f"the value of {key} nests arrays or tables too deeply to be read: "
                          "give a plain value") from None


def _insert(tree: dict, dotted: str, value) -> None:
    parts = dotted.split(".")
    node = tree
    for i, part in enumerate(parts[:-1]):
        nxt = node.setdefault(part, {})
        if not isinstance(nxt, dict):
            raise ConfigError(f"config key '{'.'.join(parts[: i + 1])}' is a value, not a table")
        node = nxt
    node[parts[-1]] = value


def load_config(
    path: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> ChipConfig:
    """Defaults, then the TOML file at ``path``, then ``overrides`` (dotted keys).

    Override values may be typed Python values or strings in TOML syntax (as given on the
    command line with ``--set key=value``).
    """
    tree: dict = {}
    if path is not None:
        tree = read_toml(path, "config file")
    for key, value in (overrides or {}).items():
        if not isinstance(key, str) or not key:
            raise ConfigError(f"override key {key!r} must be a dotted name such as sva.p1")
        if isinstance(value, str):
            value = _parse_value(value, key)
        _insert(tree, key, value)
    _descriptor_defaults(tree)
    return checked_chip(tree)


def _descriptor_defaults(tree: dict) -> None:
    """Fill the SVA keys the configuration leaves unset with the tuned values of its
    descriptor (:data:`DESCRIPTOR_DEFAULTS`). A malformed tree is left for :func:`_build` to
    report."""
    nna = tree.get("nna", {})
    sva = tree.setdefault("sva", {})
    if not isinstance(nna, dict) or not isinstance(sva, dict):
        return
    descriptor = nna.get("descriptor", DEFAULT_DESCRIPTOR)
    if not isinstance(descriptor, str):
        return
    for key, value in DESCRIPTOR_DEFAULTS.get(descriptor, {}).items():
        sva.setdefault(key, value)
    for key, value in derived_widths(sva, descriptor_width(nna)).items():
        sva.setdefault(key, value)


def descriptor_width(nna: dict) -> int:
    """Bits of the descriptor the NNA table ``nna`` selects (defaults where unset), as far as the
    configuration knows it: the census's comparisons (:mod:`sim.census_layout`; at most 64, more
    is refused when the census is built), else the CNN's ``nna.cnn.channels``. A malformed table
    gives :data:`CNN_BITS`; :func:`_build` reports it when the whole tree is built."""
    is_census = nna.get("descriptor", DEFAULT_DESCRIPTOR) == "census"
    cls, key = (CensusConfig, "census") if is_census else (CnnConfig, "cnn")
    sub = nna.get(key, {})
    try:  # the keys' own rules (types, ranges, odd sizes), read from their declarations
        table = _build(cls, sub, f"nna.{key}.") if isinstance(sub, dict) else None
    except ConfigError:
        table = None
    if table is None:
        return CNN_BITS
    if not is_census:
        return table.channels
    offsets = comparison_offsets(*table.window, table.kind, table.stride)
    return max(1, min(len(offsets), 64))


def derived_widths(sva: dict, bits: int) -> dict:
    """The register widths :func:`sgm_widths` gives for a ``bits``-bit descriptor and the box,
    P2 and paths of the SVA table ``sva`` (their defaults where unset), each clamped into its
    key's legal range (a P2 too large for the widest path register saturates it); none when one
    of them is malformed (left for :func:`_build` to report)."""
    meta = {f.name: f for f in dataclasses.fields(SvaConfig)}
    values = {k: sva.get(k, meta[k].default) for k in ("box_size", "p2", "paths")}
    if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in values.values()):
        return {}
    widths = sgm_widths(values["p2"], values["box_size"], bits, paths=max(values["paths"], 1))
    return {k: min(max(v, meta[k].metadata["lo"]), meta[k].metadata["hi"])
            for k, v in widths.items()}


def parse_set_options(items: list[str] | None) -> dict[str, str]:
    """``["sva.p1=10", ...]`` from the CLI into an override dict (values parsed later)."""
    out: dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set expects KEY=VALUE (e.g. --set sva.p1=10); got {item!r}")
        out[key.strip()] = value.strip()
    return out


def keys_set(path: str | Path | None = None, overrides: dict[str, Any] | None = None
             ) -> frozenset[str]:
    """The dotted keys a configuration file at ``path`` and ``overrides`` set (the keys the
    user chose, as opposed to defaults)."""
    out = set(overrides or {})

    def walk(tree: dict, prefix: str) -> None:
        for k, v in tree.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            else:
                out.add(f"{prefix}{k}")

    if path is not None:
        walk(read_toml(path, "config file"), "")
    return frozenset(out)
