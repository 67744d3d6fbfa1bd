"""Loading the configuration: defaults, then a TOML file, then dotted-key overrides.

:func:`load_config` reads the file (:func:`~core.config.files.read_toml`: one line for every
way a file can be unusable), applies ``--set`` overrides, fills the keys left unset that depend
on others -- the descriptor's tuned back end (:data:`~core.config.schema.DESCRIPTOR_DEFAULTS`)
and the register widths that follow the descriptor, box, P2 and paths (:func:`derived_widths`)
-- and checks the result once (:func:`core.config.check.checked_chip`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import tomllib
from pathlib import Path
from typing import Any

from stereosim.core.census_layout import comparison_offsets
from stereosim.core.config.backend import BACKEND_KEYS, carried_backend
from stereosim.core.config.check import _build, checked_chip
from stereosim.core.config.files import read_toml
from stereosim.core.config.schema import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTOR_DEFAULTS,
    CensusConfig,
    ChipConfig,
    CnnConfig,
    SvaConfig,
)
from stereosim.core.config.widths import CNN_BITS, largest_cost, sgm_widths
from stereosim.core.errors import ConfigError


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


def _fields(cls, prefix: str = ""):
    """(dotted key, field) of every leaf key of the config class ``cls``."""
    for f in dataclasses.fields(cls):
        sub = f.default_factory if f.default_factory is not dataclasses.MISSING else None
        if isinstance(sub, type) and dataclasses.is_dataclass(sub):
            yield from _fields(sub, f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}", f


@functools.cache
def _field(dotted: str) -> dataclasses.Field:
    return dict(_fields(ChipConfig))[dotted]


#: The keys whose value names a file (``param(path=True)``).
PATH_KEYS = tuple(k for k, f in _fields(ChipConfig) if f.metadata.get("path"))


def config_paths(path) -> list[str]:
    """The config files ``path`` names, in the order they are layered: one path, a list or
    tuple of them, or None (none)."""
    if path is None:
        return []
    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    for p in paths:
        if not isinstance(p, (str, os.PathLike)) or not os.fspath(p):
            raise ConfigError(f"a config file must be a path; got {p!r}")
    return [os.fspath(p) for p in paths]


def read_layer(path) -> dict:
    """The tree of the config file at ``path``, every file-naming key (``param(path=True)``)
    given relative to the file's folder made absolute -- so a config file means the same
    files from whatever folder it is used, and a file of the working directory cannot shadow
    a preset's."""
    tree = read_toml(path, "config file")
    folder = Path(path).resolve().parent
    for dotted in PATH_KEYS:
        *parents, leaf = dotted.split(".")
        node = tree
        for part in parents:
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, dict):
            continue
        value = node.get(leaf)
        if isinstance(value, str) and value and value != _field(dotted).default:
            node[leaf] = os.path.normpath(folder / os.path.expanduser(value))
    return tree


def _merge(into: dict, layer: dict) -> None:
    """Layer ``layer`` over ``into``: tables merge key by key, a later value wins."""
    for key, value in layer.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _merge(into[key], value)
        else:
            into[key] = value


def _leaves(tree: dict, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in tree.items():
        if isinstance(v, dict):
            out.update(_leaves(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def layer_notes(path) -> list[str]:
    """For several config files ``path`` layered in order, one line for each file that
    replaces keys an earlier file set (per earlier file), naming each key with its old and new
    value: what the user of ``--config A --config B`` should know was replaced."""
    notes, seen = [], {}
    for p in config_paths(path):
        replaced: dict[str, list[str]] = {}
        for key, value in _leaves(read_layer(p)).items():
            if key in seen and seen[key][1] != value:
                replaced.setdefault(seen[key][0], []).append(
                    f"{key} {seen[key][1]!r} -> {value!r}")
            seen[key] = (p, value)
        for earlier, keys in replaced.items():
            notes.append(f"{Path(p).name} replaces {len(keys)} key{'s' if len(keys) > 1 else ''}"
                         f" of {Path(earlier).name}: " + ", ".join(keys))
    return notes


def load_config(
    path: str | Path | list | tuple | None = None, overrides: dict[str, Any] | None = None
) -> ChipConfig:
    """Defaults, then the TOML file(s) at ``path`` (several are layered in order: a later
    file's keys win), then ``overrides`` (dotted keys).

    Override values may be typed Python values or strings in TOML syntax (as given on the
    command line with ``--set key=value``). A file-naming key in a config file is relative to
    that file (:func:`read_layer`); in an override, to the working directory.
    """
    tree: dict = {}
    for p in config_paths(path):
        _merge(tree, read_layer(p))
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
    if not all(key in sva for key in BACKEND_KEYS):  # the file is read for the keys unset
        for key, value in tuned_backend(tree)[0].items():
            sva.setdefault(key, value)
    for key, value in derived_widths(sva, table_largest_cost(nna, sva)).items():
        sva.setdefault(key, value)


def tuned_backend(tree: dict) -> tuple[dict, bool]:
    """The back end (:data:`~core.config.backend.BACKEND_KEYS`) the configuration tree's
    descriptor was tuned with, and whether its CNN weight file carries it
    (:func:`~core.config.backend.carried_backend`); else the descriptor's
    :data:`DESCRIPTOR_DEFAULTS` (none for a malformed tree, left for :func:`_build`)."""
    nna = tree.get("nna", {})
    if not isinstance(nna, dict):
        return {}, False
    descriptor = nna.get("descriptor", DEFAULT_DESCRIPTOR)
    if descriptor == "cnn":
        cnn = nna.get("cnn", {})
        weights = cnn.get("weights", "default") if isinstance(cnn, dict) else None
        if isinstance(weights, str) and weights != "default" and os.path.isfile(weights):
            carried = carried_backend(weights)
            if carried is not None:
                return {**DESCRIPTOR_DEFAULTS["cnn"], **carried}, True
    if not isinstance(descriptor, str):
        return {}, False
    return dict(DESCRIPTOR_DEFAULTS.get(descriptor, {})), False


def _part_bits(nna: dict, key: str) -> int | None:
    """Bits of the descriptor part ``key`` (census or cnn) of the NNA table ``nna`` (defaults
    where unset), as far as the configuration knows it: the census's comparisons
    (:mod:`core.census_layout`; at most 64, more is refused when the census is built), the CNN's
    ``nna.cnn.channels``; None for a malformed table (:func:`_build` reports it)."""
    cls = CensusConfig if key == "census" else CnnConfig
    sub = nna.get(key, {})
    try:  # the keys' own rules (types, ranges, odd sizes), read from their declarations
        table = _build(cls, sub, f"nna.{key}.") if isinstance(sub, dict) else None
    except ConfigError:
        table = None
    if table is None:
        return None
    if key == "cnn":
        return table.channels
    offsets = comparison_offsets(*table.window, table.kind, table.stride)
    return max(1, min(len(offsets), 64))


def descriptor_parts_bits(nna: dict) -> tuple[int, ...]:
    """Bits of each part of the descriptor the NNA table ``nna`` selects: (census,), (cnn,) or
    the hybrid's (cnn, census); a malformed table counts :data:`CNN_BITS` for its part."""
    descriptor = nna.get("descriptor", DEFAULT_DESCRIPTOR)
    keys = {"census": ("census",), "hybrid": ("cnn", "census")}.get(descriptor, ("cnn",))
    return tuple(_part_bits(nna, k) or CNN_BITS for k in keys)


def descriptor_width(nna: dict) -> int:
    """Bits of the descriptor the NNA table ``nna`` selects (defaults where unset): the sum of
    its parts' (:func:`descriptor_parts_bits`)."""
    return sum(descriptor_parts_bits(nna))


def table_largest_cost(nna: dict, sva: dict) -> int:
    """:func:`~core.config.widths.largest_cost` of the NNA and SVA tables (defaults where
    unset; a malformed weight set counts as its default, left for :func:`_build` to
    report)."""
    meta = {f.name: f.default for f in dataclasses.fields(SvaConfig)}
    keys = ["cost_weights"] + (["noisy_weights"] if sva.get("weight_mode") == "auto" else [])
    sets = []
    for key in keys:
        weights = sva.get(key, meta[key])
        ok = (isinstance(weights, (list, tuple)) and len(weights) == 2
              and all(isinstance(w, int) and not isinstance(w, bool) and 0 <= w <= 3
                      for w in weights))
        sets.append(tuple(weights) if ok else meta[key])
    return largest_cost(descriptor_parts_bits(nna), tuple(sets))


def derived_widths(sva: dict, bits: int) -> dict:
    """The register widths :func:`sgm_widths` gives for a largest cost of ``bits`` a pixel (a
    ``bits``-bit descriptor; :func:`largest_cost`) and the box,
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


def keys_set(path: str | Path | list | tuple | None = None,
             overrides: dict[str, Any] | None = None) -> frozenset[str]:
    """The dotted keys the configuration file(s) at ``path`` and ``overrides`` set (the keys
    the user chose, as opposed to defaults)."""
    out = set(overrides or {})
    for p in config_paths(path):
        out.update(_leaves(read_toml(p, "config file")))
    return frozenset(out)
