"""Kernels take named data (docs/architecture.md, "Kernels take named data"; issue 49's
"named kernel state"): no plain tuple of more than four items crosses a kernel boundary -- a
kernel's state and parameters travel as records (NamedTuples, structrefs, record dtypes) read by
field name -- and the argument rule of tests/test_architecture.py (at most 8 parameters) holds
for numba intrinsics too, which that rule does not look at."""

import ast
import sys
from pathlib import Path

import numpy as np
import pytest
from numba.core import types
from numba.core.registry import CPUDispatcher

import stereosim
from stereosim.core.config import load_config
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "sim", "nna", "sva", "quant", "traces")  # as tests/test_architecture.py
MOST_ITEMS = 4
MOST_PARAMETERS = 8

# Kernels of other engineers' files still taking a long plain tuple, each with its reason; the
# test fails when one of them no longer does (then its line goes), so the list cannot go stale.
KNOWN = {
    # the compiled engine's trace sampler: its log, 7 arrays (ctl, last, times, ids, values,
    # scratch, done) as one positional tuple; sim/cycle/compiled/sampler.py is another
    # engineer's file, being reworked at the same time
    "stereosim.sim.cycle.compiled.sampler.record_window",
}

# Intrinsics of other engineers' files still over the argument rule, with the reason; kept
# honest the same way.
KNOWN_INTRINSICS = {
    # the VNNI tap sums: four accumulator rows, quads, weights and the pixel's indices as
    # eleven positional parameters; quant/vnni.py is another engineer's file
    "quant/vnni.py _taps9",
    "quant/vnni.py _taps11",
}

# (descriptor, overrides): every descriptor, with the LR check, the median (narrow and wide
# words) and all four paths on in all but the first
RUNS = [
    ("census", {}),
    ("census", {"sva.paths": 4, "sva.lr_check": True, "sva.median": 5}),
    ("cnn", {"sva.paths": 4, "sva.lr_check": True, "sva.median": 3}),
    ("hybrid", {"sva.paths": 4, "sva.lr_check": True, "sva.median": 5}),
]


def _long_tuples(ty, path: str) -> list[str]:
    """Where the numba type ``ty`` holds a plain (unnamed) tuple of more than MOST_ITEMS items,
    looking inside tuples and named tuples."""
    named = isinstance(ty, (types.NamedTuple, types.NamedUniTuple))
    if not isinstance(ty, types.BaseTuple):
        return []
    out = [] if named or len(ty) <= MOST_ITEMS else [f"{path}: {len(ty)} items, {ty}"[:160]]
    for i, item in enumerate(ty.types):
        out += _long_tuples(item, f"{path}.{ty.fields[i]}" if named else f"{path}[{i}]")
    return out


def _stereosim_dispatchers() -> list[CPUDispatcher]:
    """Every kernel the loaded stereosim modules define (each once, by identity)."""
    found = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("stereosim.") or module is None:
            continue
        for obj in list(vars(module).values()):
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__.startswith("stereosim."):
                found[id(obj)] = obj
    return list(found.values())


@pytest.fixture(scope="module")
def after_runs():
    """Representative runs of both modes: each of RUNS through the functional model and the
    compiled cycle engine with a trace window (the trace sampler's kernels included)."""
    rng = np.random.default_rng(0)
    base = rng.integers(0, 256, (24, 100), dtype=np.uint8)
    left, right = base[:, :96].copy(), base[:, 4:].copy()
    for descriptor, overrides in RUNS:
        cfg = load_config(overrides={"nna.descriptor": descriptor, "sva.disparities": 32,
                                     **overrides})
        stereosim.run(left, right, mode="functional", config=cfg)
        simulate(build_plan(cfg, left.shape), left, right, window=(0, 10**9))
    return _stereosim_dispatchers()


def test_no_plain_tuple_of_more_than_four_items_crosses_a_kernel_boundary(after_runs):
    names = {f"{d.py_func.__module__}.{d.py_func.__qualname__}" for d in after_runs}
    # the runs reached the kernels this test is about (a probe that sees nothing cannot fail)
    assert {"stereosim.sva.pipeline.pipeline.stream_rows", "stereosim.sva.sgm.sgm.sgm_row_start",
            "stereosim.sva.hamming.cost.cost_row_add"} <= names
    found, known_seen = [], set()
    for dispatcher in after_runs:
        name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}"
        for sig in dispatcher.signatures:
            for i, arg in enumerate(sig):
                for where in _long_tuples(arg, f"arg{i}"):
                    if name in KNOWN:
                        known_seen.add(name)
                    else:
                        found.append(f"{name} {where}")
    assert not found, "\n".join(sorted(set(found)))
    assert known_seen == KNOWN, f"no longer taking a long tuple: {KNOWN - known_seen}"


def _sources() -> list[Path]:
    """Every module of the project's packages."""
    return [path for pkg in PACKAGES for path in sorted((ROOT / pkg).rglob("*.py"))]


def _intrinsic(node) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name == "intrinsic":
            return True
    return False


def test_no_intrinsic_takes_more_than_8_parameters():
    """tests/test_architecture.py's rule for numba intrinsics: their parameters after the
    typing context (``typingctx``, numba's, not the caller's)."""
    found, known_seen = [], set()
    intrinsics = 0
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.FunctionDef) and _intrinsic(node)):
                continue
            intrinsics += 1
            n = len(node.args.args) - 1 + len(node.args.kwonlyargs)
            key = f"{path.relative_to(ROOT)} {node.name}"
            if node.args.vararg is not None or n > MOST_PARAMETERS:
                if key in KNOWN_INTRINSICS:
                    known_seen.add(key)
                else:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {n}")
    assert intrinsics >= 3  # popcount, the SGM step, the median's lanes at least
    assert not found, "\n".join(found)
    assert known_seen == KNOWN_INTRINSICS, \
        f"now within the rule: {KNOWN_INTRINSICS - known_seen}"
