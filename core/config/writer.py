"""The configuration as TOML (``stereosim config show``), as a nested dict, and the difference
of two configurations (``stereosim config diff``)."""

from __future__ import annotations

import dataclasses
from typing import Any

from stereosim.core.config.loader import derived_widths, table_largest_cost, tuned_backend
from stereosim.core.config.schema import DESCRIPTOR_DEFAULTS, ChipConfig


def config_to_dict(cfg) -> dict:
    out = {}
    for f in dataclasses.fields(cfg):
        v = getattr(cfg, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = config_to_dict(v)
        elif isinstance(v, tuple):
            out[f.name] = list(v)
        else:
            out[f.name] = v
    return out


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(v)


def _auto_keys(cfg, set_keys) -> dict[str, str]:
    """The keys left to be worked out that hold the worked-out value and were not set by the
    user: the descriptor's tuned values (:data:`DESCRIPTOR_DEFAULTS`) and the register widths
    that follow the box, P2 and paths (:func:`~core.config.loader.derived_widths`): dotted key
    -> why."""
    defaults, carried = tuned_backend({"nna": dataclasses.asdict(cfg.nna)})

    def choices(key: str) -> str:
        return ", ".join(f"{d} {str(v[key]).lower()}" for d, v in DESCRIPTOR_DEFAULTS.items()
                         if key in v)

    def why(key: str) -> str:
        if carried:
            return "auto: the tuned value the network's weight file carries"
        return f"auto: nna.descriptor's tuned value ({choices(key)})"

    auto = {f"sva.{k}": why(k)
            for k, v in defaults.items()
            if f"sva.{k}" not in set_keys and getattr(cfg.sva, k) == v}
    sva = dataclasses.asdict(cfg.sva)
    derived = derived_widths(sva, table_largest_cost(dataclasses.asdict(cfg.nna), sva))
    widths = "auto: the narrowest that never saturates at this descriptor, box, P2 and paths"
    auto.update({f"sva.{k}": widths
                 for k, v in derived.items()
                 if f"sva.{k}" not in set_keys and getattr(cfg.sva, k) == v})
    return auto


def config_to_toml(cfg, *, comments: bool = True, set_keys=frozenset()) -> str:
    """The effective configuration as TOML (loadable again with :func:`load_config`).

    A key whose default depends on the descriptor (``sva.p1``, ``sva.p2``) that holds that
    default and is not in ``set_keys`` (the keys the user set, :func:`keys_set`) is written
    commented out, so that loading the file with another ``nna.descriptor`` gives that
    descriptor's values rather than pinning these."""
    lines: list[str] = []
    auto = _auto_keys(cfg, set_keys)

    def emit(obj, prefix: str):
        fields = dataclasses.fields(obj)
        scalars = [f for f in fields if not dataclasses.is_dataclass(getattr(obj, f.name))]
        tables = [f for f in fields if dataclasses.is_dataclass(getattr(obj, f.name))]
        if scalars and prefix:
            if lines:
                lines.append("")
            lines.append(f"[{prefix}]")
        for f in scalars:
            text = f"{f.name} = {_toml_value(getattr(obj, f.name))}"
            dotted = f"{prefix}.{f.name}" if prefix else f.name
            if dotted in auto:
                text = f"# {text:<26} # {auto[dotted]}"
            elif comments and f.metadata.get("help"):
                text = f"{text:<28} # {f.metadata['help']}"
            lines.append(text)
        for f in tables:
            emit(getattr(obj, f.name), f"{prefix}.{f.name}" if prefix else f.name)

    emit(cfg, "")
    return "\n".join(lines) + "\n"


def config_diff(a: ChipConfig, b: ChipConfig) -> dict[str, tuple[Any, Any]]:
    """Dotted keys whose values differ between two configurations."""
    out: dict[str, tuple[Any, Any]] = {}

    def walk(x, y, prefix):
        for k in x:
            if isinstance(x[k], dict):
                walk(x[k], y[k], f"{prefix}{k}.")
            elif x[k] != y[k]:
                out[f"{prefix}{k}"] = (x[k], y[k])

    walk(config_to_dict(a), config_to_dict(b), "")
    return out
