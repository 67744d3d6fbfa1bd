"""The checks of a configuration, run once where it enters.

One rule set for every configuration, however it was built: each value against its declaration
in :mod:`core.config.schema` (type, range, choices, oddness), then the rules that involve several
keys (:func:`check_combinations`). :func:`core.config.load_config` runs them on the tree it read,
:func:`check_config` on a :class:`ChipConfig` built by hand or with ``dataclasses.replace``,
:func:`check_section` on one section given to a stage's entry point.

Each entry point runs them once on the configuration it is given -- ``stereosim.run`` and
``build_plan`` on a ``ChipConfig``, the NNA's and the SVA's functional entry points on a
section -- and hands down a resolved spec (:class:`sim.cycle.spec.ChipSpec`, with the NNA's
:class:`nna.descriptor.NnaSpec` and the SVA's :class:`sva.spec.SvaSpec`), whose type says it is
checked: the code below an entry takes the spec and checks nothing again. No object is
remembered as checked: a configuration handed to an entry is checked there, every time.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import typing
from typing import Any

import numpy as np

from stereosim.core.config.lent import read_lent_network
from stereosim.core.config.schema import RETIRED, SECTIONS, ChipConfig
from stereosim.core.errors import ConfigError


def checked_chip(tree: dict) -> ChipConfig:
    """The checked configuration of the nested dict ``tree`` (every value, then the
    combinations); raises :class:`ConfigError` naming the first bad key."""
    return check_combinations(_build(ChipConfig, tree, ""))


def check_config(cfg) -> ChipConfig:
    """The same checks as :func:`core.config.load_config` for a configuration built any other
    way (by hand, with ``dataclasses.replace``): every section of the right class, every value of
    its declared type and in range, every combination legal. Returns the checked configuration,
    a new object (values normalised: numpy scalars become Python numbers, lists become tuples);
    raises :class:`ConfigError` naming the first bad key."""
    if not isinstance(cfg, ChipConfig):
        raise ConfigError("a chip configuration must be a sim.ChipConfig; got "
                          f"{type(cfg).__name__}")
    return checked_chip(_tree_of(cfg, ChipConfig, ""))


def check_section(section, prefix: str):
    """:func:`check_config` for one section (``prefix`` ``"sva."``, ``"nna."``, ...): the check a
    stage's entry point runs before any kernel sees the values. Returns the checked section, a
    new object."""
    cls = SECTIONS[prefix]
    return _build(cls, _tree_of(section, cls, prefix), prefix)


def _is_config_class(tp) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


@functools.lru_cache(maxsize=None)
def _field_types(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)  # slow, and the same for every configuration


def _coerce(dotted: str, value, tp, meta) -> Any:
    """Check one leaf value against its declared type and rules; return the typed value."""
    origin = typing.get_origin(tp)
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:  # a list of any length
            if not isinstance(value, (list, tuple)):
                raise ConfigError(f"config key '{dotted}' must be a list, e.g. {dotted} = "
                                  f"[1, 2]; got {value!r}")
            return tuple(_coerce(dotted, v, args[0], meta) for v in value)
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            raise ConfigError(
                f"config key '{dotted}' must be a list of {len(args)} values, e.g. "
                f"{dotted} = [9, 7]; got {value!r}"
            )
        return tuple(_coerce(dotted, v, a, meta) for v, a in zip(value, args))
    if tp is bool:
        if isinstance(value, np.bool_):
            value = bool(value)
        if not isinstance(value, bool):
            raise ConfigError(f"config key '{dotted}' must be true or false; got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise ConfigError(f"config key '{dotted}' must be an integer; got {value!r}")
        value = int(value)
    elif tp is float:
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ConfigError(f"config key '{dotted}' must be a number; got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"config key '{dotted}' must be a finite number; got {value!r}")
    elif tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"config key '{dotted}' must be a string; got {value!r}")
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        shown = ", ".join(str(c) for c in choices)
        raise ConfigError(f"config key '{dotted}' must be one of {shown}; got {value!r}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and value < lo or hi is not None and value > hi:
        raise ConfigError(f"config key '{dotted}' must be in [{lo}, {hi}]; got {value!r}")
    if meta.get("odd") and value % 2 == 0:
        raise ConfigError(f"config key '{dotted}' must be odd; got {value!r}")
    return value


def _build(cls, data: dict, prefix: str):
    """An instance of the config class ``cls`` from the nested dict ``data`` (the keys under
    ``prefix``), every value checked against its declaration; unset keys take their defaults."""
    hints = _field_types(cls)
    names = {f.name: f for f in dataclasses.fields(cls)}
    for key in data:
        if key not in names:
            dotted = f"{prefix}{key}"
            if dotted in RETIRED:
                raise ConfigError(RETIRED[dotted])
            known = ", ".join(f"{prefix}{n}" for n in names)
            raise ConfigError(f"unknown config key '{dotted}' (known here: {known})")
    kwargs = {}
    for name, f in names.items():
        tp = hints[name]
        dotted = f"{prefix}{name}"
        if _is_config_class(tp):
            sub = data.get(name, {})
            if not isinstance(sub, dict):
                raise ConfigError(f"config key '{dotted}' is a table; set its keys, e.g. "
                                  f"{dotted}.<key>")
            kwargs[name] = _build(tp, sub, dotted + ".")
        elif name in data:
            if isinstance(data[name], dict):
                raise ConfigError(f"config key '{dotted}' is a value, not a table")
            kwargs[name] = _coerce(dotted, data[name], tp, f.metadata)
    return cls(**kwargs)


def _tree_of(obj, cls, prefix: str) -> dict:
    """The nested dict of a config object, checking that every section has its class."""
    if type(obj) is not cls:
        raise ConfigError(
            f"config section '{prefix.rstrip('.') or 'chip'}' must be a {cls.__name__}; got "
            f"{type(obj).__name__}"
        )
    hints = _field_types(cls)
    tree = {}
    for f in dataclasses.fields(cls):
        value = getattr(obj, f.name)
        if _is_config_class(hints[f.name]):
            tree[f.name] = _tree_of(value, hints[f.name], f"{prefix}{f.name}.")
        else:
            tree[f.name] = value
    return tree


def check_combinations(cfg: ChipConfig) -> ChipConfig:
    """Rules that involve more than one key."""
    nna = cfg.nna
    if nna.stereo_submodules % 2:
        raise ConfigError(
            f"nna.stereo_submodules={nna.stereo_submodules} must be even (half per camera)"
        )
    if nna.stereo_submodules > nna.submodules:
        raise ConfigError(
            f"nna.stereo_submodules={nna.stereo_submodules} exceeds nna.submodules="
            f"{nna.submodules}: raise nna.submodules or use fewer for the stereo pair"
        )
    if nna.stereo_submodules + nna.lent_submodules > nna.submodules:
        raise ConfigError(
            f"nna.lent_submodules={nna.lent_submodules} with nna.stereo_submodules="
            f"{nna.stereo_submodules} exceeds nna.submodules={nna.submodules}: lend at most "
            f"{nna.submodules - nna.stereo_submodules}"
        )
    if cfg.sva.pairs > 1 and (cfg.source.kind != "camera" or cfg.source.frame_buffers == 0):
        raise ConfigError(
            f"sva.pairs={cfg.sva.pairs} shares the chip between camera pairs frame by frame, "
            "which needs each pair's frames in DRAM frame buffers: add --set source.kind=camera "
            "--set source.frame_buffers=2 (or use sva.pairs=1)"
        )
    src = cfg.source
    if bool(src.camera_width) != bool(src.camera_height):
        raise ConfigError(
            f"source.camera_width={src.camera_width} and source.camera_height="
            f"{src.camera_height}: give both (the camera's frame size) or set both to 0 (the "
            "pair's own size)")
    _check_weights(cfg)
    d = cfg.dram
    if d.model == "none" and d.spill != "none":
        raise ConfigError("dram.spill needs the DRAM channel: add --set dram.model=tdm")
    if nna.lent_submodules and not nna.lent_network:
        raise ConfigError(
            f"nna.lent_submodules={nna.lent_submodules} lends submodules to a network, but "
            "nna.lent_network names none: give its TOML file (docs/lent.md) or lend none")
    if nna.lent_network:
        if not nna.lent_submodules:
            raise ConfigError(
                f"nna.lent_network={nna.lent_network!r} needs submodules to run on: add --set "
                "nna.lent_submodules=N")
        read_lent_network(nna.lent_network)  # the file's every field, one line per mistake
    if cfg.source.on_overflow == "drop_frame" and (cfg.source.kind != "camera"
                                                   or cfg.source.frame_buffers == 0):
        raise ConfigError(
            "source.on_overflow=drop_frame needs a camera with frame buffers "
            "(--set source.kind=camera --set source.frame_buffers=2): a camera streaming "
            "straight into the NNA cannot take back a frame it has started sending")
    return cfg


def _check_weights(cfg: ChipConfig) -> None:
    """The hybrid descriptor's weight registers: a cost needs a weight that is not 0, and a
    descriptor of one part has no weights to set (a value would be ignored)."""
    s = cfg.sva
    defaults = {f.name: f.default for f in dataclasses.fields(type(s))}
    if cfg.nna.descriptor != "hybrid":
        for key in ("cost_weights", "weight_mode", "noisy_weights"):
            if getattr(s, key) != defaults[key]:
                raise ConfigError(
                    f"sva.{key} weighs the two parts of the hybrid descriptor, but "
                    f"nna.descriptor is {cfg.nna.descriptor}: add --set nna.descriptor=hybrid "
                    f"or leave sva.{key} unset")
        return
    sets = [("cost_weights", s.cost_weights)]
    if s.weight_mode == "auto":
        sets.append(("noisy_weights", s.noisy_weights))
    for key, weights in sets:
        if not any(weights):
            raise ConfigError(f"sva.{key} = {list(weights)} weighs both distances by 0, so "
                              "every disparity would cost the same: give one a weight of 1..3")
