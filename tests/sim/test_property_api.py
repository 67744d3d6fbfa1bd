"""Property: ``sim.run`` with a hand-built ``ChipConfig`` behaves exactly as ``load_config`` says.

Each example takes the default configuration and replaces a few fields with
``dataclasses.replace`` -- values drawn around each field's declared rules (in range, at the
bounds, one past them, the wrong type, NaN, an unknown choice) -- and runs a tiny frame in a
random mode. The oracle is ``load_config`` given the same values as overrides: when it refuses,
``sim.run`` must raise a ConfigError with the same line; when it accepts, ``sim.run`` either
returns a whole result or raises a UserError (an impossible chip, e.g. D not below the width) --
never another exception, never a crash. STEREOSIM_PROPERTY_EXAMPLES sets the number of examples
(CI: the default below; a longer local run takes a larger number).
"""

from __future__ import annotations

import dataclasses
import math
import os
import typing

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from stereosim.core.config import ChipConfig, config_to_dict, load_config
from stereosim.core.errors import ConfigError, UserError
from stereosim.sim.api import run

EXAMPLES = int(os.environ.get("STEREOSIM_PROPERTY_EXAMPLES", "60"))
# fields whose extreme legal values make a tiny frame slow without testing anything new
SLOW_LEGAL = {"source.camera_hblank", "source.camera_vblank", "fifo.source_to_nna_depth",
              "fifo.nna_to_sva_depth", "fifo.nna_to_merge_depth", "fifo.sva_to_sink_depth",
              "sim.watchdog_cycles", "nna.submodules", "nna.stereo_submodules",
              "fifo.latency_cycles"}


def _leaves(cls=ChipConfig, prefix=""):
    """(dotted key, type, metadata) of every scalar config field, nested sections included."""
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if dataclasses.is_dataclass(hints[f.name]):
            out += _leaves(hints[f.name], f"{prefix}{f.name}.")
        else:
            out.append((f"{prefix}{f.name}", hints[f.name], f.metadata))
    return out


LEAVES = _leaves()


def _values(dotted, tp, meta):
    """A strategy of values around the field's rules."""
    bad = st.sampled_from(["x", None, [1], float("nan"), True])
    if meta.get("choices") is not None:
        choices = list(meta["choices"])
        wrong = [17, 0, 300, -16] if tp is int else ["nope", ""]
        return st.one_of(st.sampled_from(choices), st.sampled_from(wrong), bad)
    if tp is bool:
        return st.one_of(st.booleans(), st.sampled_from([np.bool_(True), 1, "yes", None]))
    if typing.get_origin(tp) is tuple:
        return st.one_of(st.tuples(st.integers(-1, 17), st.integers(-1, 17)), bad)
    if tp is str:
        return st.one_of(st.sampled_from(["default", "missing.npz"]), bad)
    lo, hi = meta.get("lo"), meta.get("hi")
    if tp is int:
        top = hi if dotted not in SLOW_LEGAL else min(hi, lo + 64)
        edges = [lo - 1, lo, top, hi + 1, -(1 << 40), 1 << 63]
        legal = st.integers(lo, top)
        return st.one_of(legal, st.sampled_from(edges), st.sampled_from([np.int64(lo), 2.5]),
                         bad)
    top = hi if tp is float else None
    return st.one_of(st.floats(lo, min(top, 2000.0)), st.sampled_from(
        [lo, hi, lo / 2, hi * 2, math.inf, -math.inf, float("nan"), np.float32(lo * 2), 0]), bad)


@st.composite
def configs(draw):
    picked = draw(st.lists(st.sampled_from(LEAVES), min_size=1, max_size=4,
                           unique_by=lambda leaf: leaf[0]))
    return {dotted: draw(_values(dotted, tp, meta)) for dotted, tp, meta in picked}


def _replaced(obj, parts, value):
    if len(parts) == 1:
        return dataclasses.replace(obj, **{parts[0]: value})
    return dataclasses.replace(obj, **{parts[0]: _replaced(getattr(obj, parts[0]), parts[1:],
                                                           value)})


def _hand_built(values: dict) -> ChipConfig:
    cfg = load_config(overrides={"sva.disparities": 16})
    for dotted, value in values.items():
        cfg = _replaced(cfg, dotted.split("."), value)
    return cfg


def _pair():
    rng = np.random.default_rng(9)
    base = rng.integers(0, 256, (12, 44), dtype=np.uint8)
    return np.ascontiguousarray(base[:, 4:]), np.ascontiguousarray(base[:, :-4])


LEFT, RIGHT = _pair()


@settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES <= 100,
          suppress_health_check=[HealthCheck.too_slow])
@given(values=configs(), mode=st.sampled_from(["functional", "cycle"]))
def test_sim_run_takes_a_hand_built_config_exactly_as_load_config_would(values, mode):
    cfg = _hand_built(values)
    every_key = _flat(cfg)  # all keys given: no descriptor default fills one in
    try:
        expected = load_config(overrides=every_key)
        refused = None
    except ConfigError as err:
        refused = str(err)
    try:
        result = run(LEFT, RIGHT, mode=mode, config=cfg)
    except ConfigError as err:
        event("refused by load_config's rules" if refused is not None else
              "accepted by load_config, refused by the plan")
        if refused is not None:
            assert str(err) == refused
        return
    except UserError:
        event("accepted, then a UserError")
        assert refused is None
        return
    event(f"ran ({mode})")
    assert refused is None, f"sim.run accepted what load_config refuses: {refused}"
    assert result.disparity_fixed.shape == LEFT.shape
    assert result.report["config"] == config_to_dict(expected)


def _flat(obj, prefix=""):
    out = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            out.update(_flat(value, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = value
    return out
