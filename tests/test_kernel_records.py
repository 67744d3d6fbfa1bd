"""Kernels take named data (docs/architecture.md, "Kernels take named data"; issue 49's
"named kernel state"): no plain tuple of more than four items crosses a kernel boundary -- a
kernel's state and parameters travel as records (NamedTuples, structrefs, record dtypes) read by
field name -- and the argument rule of tests/test_architecture.py (at most 8 parameters) holds
for numba intrinsics too, which that rule does not look at.

Two halves: the kernels' compiled signatures (arguments and return type) after representative
runs (only the kernels this process typed: a callee numba loads from its cache, or a function it
inlines, is not typed here), and a scan of the source that does not depend on the cache: no call
of a kernel passes a tuple literal of more than four items, no kernel unpacks one of its
parameters into more than four names, no kernel returns a tuple literal of more than four
items."""

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
    found = []
    for dispatcher in after_runs:
        name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}"
        for compiled in dispatcher.overloads.values():
            sig = compiled.signature
            for i, arg in enumerate(sig.args):
                found += [f"{name} {where}" for where in _long_tuples(arg, f"arg{i}")]
            found += [f"{name} {where}" for where in _long_tuples(sig.return_type, "returns")]
    assert not found, "\n".join(sorted(set(found)))


def _sources() -> list[Path]:
    """Every module of the project's packages."""
    return [path for pkg in PACKAGES for path in sorted((ROOT / pkg).rglob("*.py"))]


def _decorated(node, names) -> bool:
    """Whether the function ``node`` has a decorator named one of ``names`` (``@d``,
    ``@d(...)``, ``@module.d``)."""
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in names:
            return True
    return False


def _intrinsic(node) -> bool:
    return _decorated(node, {"intrinsic"})


# what makes a function a kernel (or code a kernel inlines): the project's and numba's
KERNEL_DECORATORS = {"njit", "njit_borrowing", "jit", "register_jitable", "intrinsic",
                     "generated_jit"}


class _Module:
    """One module of the project: its kernels (functions at module level with a decorator of
    KERNEL_DECORATORS) and what its names stand for (``from m import f as g``: g is (m, f);
    ``import m as n`` / ``from p import m``: n.f is (m, f))."""

    def __init__(self, path: Path):
        rel = path.relative_to(ROOT).with_suffix("")
        parts = ["stereosim", *rel.parts]
        self.package = ".".join(parts[:-1] if parts[-1] != "__init__" else parts[:-1])
        self.name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        self.path = path
        self.tree = ast.parse(path.read_text())
        self.kernels = {node.name for node in self.tree.body
                        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                        and _decorated(node, KERNEL_DECORATORS)}
        self.names: dict[str, tuple[str, str]] = {}  # local name -> (module, name in it)
        self.modules: dict[str, str] = {}  # local name -> module
        for node in ast.walk(self.tree):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = self.package.split(".")[:len(self.package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                for alias in node.names:
                    local = alias.asname or alias.name
                    self.names[local] = (base, alias.name)
                    self.modules[local] = f"{base}.{alias.name}"
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.asname:
                        self.modules[alias.asname] = alias.name


def _modules() -> dict[str, _Module]:
    return {m.name: m for m in map(_Module, _sources())}


def _kernel_of(modules: dict[str, _Module], module: _Module, func) -> str | None:
    """The kernel (``module.name``) that the callee expression ``func`` of a call in ``module``
    names, following re-exports; None if it names no kernel of the project."""
    if isinstance(func, ast.Name):
        if func.id in module.kernels:
            return f"{module.name}.{func.id}"
        where = module.names.get(func.id)
    elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) \
            and func.value.id in module.modules:
        where = (module.modules[func.value.id], func.attr)
    else:
        return None
    for _ in range(8):  # a chain of re-exports
        if where is None or where[0] not in modules:
            return None
        target = modules[where[0]]
        if where[1] in target.kernels:
            return f"{target.name}.{where[1]}"
        where = target.names.get(where[1])
    return None


def _long_literals(node, tuples: dict[str, int]) -> list[int]:
    """The sizes of the tuple literals of more than MOST_ITEMS items that the argument ``node``
    is or holds (inside tuple literals), a name bound to one (``tuples``: the names its
    function binds to a tuple literal, with the literal's size) included."""
    if isinstance(node, ast.Name) and tuples.get(node.id, 0) > MOST_ITEMS:
        return [tuples[node.id]]
    if not isinstance(node, ast.Tuple):
        return []
    out = [len(node.elts)] if len(node.elts) > MOST_ITEMS else []
    for item in node.elts:
        out += _long_literals(item, tuples)
    return out


def _scopes(tree):
    """Every function of a module, and the module itself (its top-level statements)."""
    yield tree
    yield from (n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef,
                                                            ast.AsyncFunctionDef)))


def _own_nodes(scope):
    """The nodes of a function (or module) outside the functions it defines."""
    todo = list(ast.iter_child_nodes(scope))
    while todo:
        node = todo.pop()
        yield node
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            todo.extend(ast.iter_child_nodes(node))


def _tuple_names(nodes) -> dict[str, int]:
    """The names that ``nodes`` (a function's own) bind to a tuple literal, with its size."""
    return {t.id: len(n.value.elts) for n in nodes if isinstance(n, ast.Assign)
            and isinstance(n.value, ast.Tuple) for t in n.targets if isinstance(t, ast.Name)}


def long_tuples_passed(modules: dict[str, _Module]) -> list[str]:
    """(a) Calls, in the project's source, of a kernel with a tuple literal of more than
    MOST_ITEMS items as an argument (or a name its function binds to one)."""
    found = []
    for module in modules.values():
        for scope in _scopes(module.tree):
            nodes = list(_own_nodes(scope))
            tuples = _tuple_names(nodes)
            for call in (n for n in nodes if isinstance(n, ast.Call)):
                kernel = _kernel_of(modules, module, call.func)
                if kernel is None:
                    continue
                for i, arg in enumerate([*call.args, *(k.value for k in call.keywords)]):
                    for size in _long_literals(arg, tuples):
                        found.append(f"{module.path.relative_to(ROOT)}:{call.lineno} "
                                     f"{kernel} argument {i}: {size} items")
    return found


def long_parameters_unpacked(modules: dict[str, _Module]) -> list[str]:
    """(b) Kernels whose body unpacks one of their own parameters into more than MOST_ITEMS
    names (``a, b, c, d, e = param``): a long tuple that came in."""
    found = []
    for module in modules.values():
        for node in module.tree.body:
            if not (isinstance(node, ast.FunctionDef) and node.name in module.kernels):
                continue
            params = {a.arg for a in [*node.args.posonlyargs, *node.args.args,
                                      *node.args.kwonlyargs]}
            for n in _own_nodes(node):
                if isinstance(n, ast.Assign) and isinstance(n.value, ast.Name) \
                        and n.value.id in params:
                    for t in n.targets:
                        if isinstance(t, (ast.Tuple, ast.List)) and len(t.elts) > MOST_ITEMS:
                            found.append(f"{module.path.relative_to(ROOT)}:{n.lineno} "
                                         f"{module.name}.{node.name} unpacks {n.value.id} "
                                         f"into {len(t.elts)}")
    return found


def long_tuples_returned(modules: dict[str, _Module]) -> list[str]:
    """(c) Kernels that return a tuple literal of more than MOST_ITEMS items (or hold one in
    the tuple they return, or return a name their body binds to one): a long tuple that goes
    out."""
    found = []
    for module in modules.values():
        for node in module.tree.body:
            if not (isinstance(node, ast.FunctionDef) and node.name in module.kernels):
                continue
            nodes = list(_own_nodes(node))
            tuples = _tuple_names(nodes)
            for n in nodes:
                if isinstance(n, ast.Return) and n.value is not None:
                    for size in _long_literals(n.value, tuples):
                        found.append(f"{module.path.relative_to(ROOT)}:{n.lineno} "
                                     f"{module.name}.{node.name} returns {size} items")
    return found


def test_the_static_scan_sees_what_it_looks_for():
    """The scan's probes on a module written for it (a scan that finds nothing cannot fail)."""
    source = (
        "from numba import njit\n"
        "from numba.extending import register_jitable\n"
        "@njit\n"
        "def k(a, s):\n"
        "    x, y, z, u, v = s\n"
        "    return x\n"
        "@register_jitable\n"
        "def r(a, s):\n"
        "    x, y, z, u = s\n"
        "    return x, y, z, u\n"
        "@njit(cache=True)\n"
        "def out(a):\n"
        "    t = (1, 2, 3, 4, 5)\n"
        "    if a:\n"
        "        return t\n"
        "    return (1, 2, 3, 4, 5, 6), a\n"
        "def plain(s):\n"
        "    x, y, z, u, v = s\n"
        "    return x, y, z, u, v\n"
        "def caller():\n"
        "    t = (1, 2, 3, 4, 5)\n"
        "    k(0, (1, 2, 3, 4, 5))\n"
        "    k(0, t)\n"
        "    k(0, (1, (1, 2, 3, 4, 5, 6)))\n"
        "    r(0, (1, 2, 3, 4))\n"
        "    plain((1, 2, 3, 4, 5))\n"
    )
    module = _Module.__new__(_Module)
    module.package, module.name, module.path = "stereosim", "stereosim.probe", ROOT / "probe.py"
    module.tree = ast.parse(source)
    module.kernels = {"k", "r", "out"}
    module.names, module.modules = {}, {}
    modules = {module.name: module}
    assert sorted(f.split(" ", 1)[1] for f in long_tuples_passed(modules)) == [
        "stereosim.probe.k argument 1: 5 items", "stereosim.probe.k argument 1: 5 items",
        "stereosim.probe.k argument 1: 6 items"]
    assert [f.split(" ", 1)[1] for f in long_parameters_unpacked(modules)] == [
        "stereosim.probe.k unpacks s into 5"]
    assert sorted(f.split(" ", 1)[1] for f in long_tuples_returned(modules)) == [
        "stereosim.probe.out returns 5 items", "stereosim.probe.out returns 6 items"]
    # and the project's own: the scan resolves its imports to the kernels
    project = _modules()
    ring = project["stereosim.sim.cycle.compiled.ring"]
    assert "pops_in" in ring.kernels
    sva = project["stereosim.sim.cycle.compiled.sva"]
    assert _kernel_of(project, sva, ast.parse("pops_in").body[0].value) == \
        "stereosim.sim.cycle.compiled.ring.pops_in"


def test_no_kernel_call_passes_a_tuple_literal_of_more_than_four_items():
    """The cache-independent half of the rule: the runtime scan sees only the kernels this
    process compiled (a callee loaded from numba's cache, or a function a kernel inlines, is
    never typed here)."""
    found = long_tuples_passed(_modules())
    assert not found, "\n".join(found)


def test_no_kernel_unpacks_a_parameter_into_more_than_four_names():
    found = long_parameters_unpacked(_modules())
    assert not found, "\n".join(found)


def test_no_kernel_returns_a_tuple_literal_of_more_than_four_items():
    found = long_tuples_returned(_modules())
    assert not found, "\n".join(found)


def test_no_intrinsic_takes_more_than_8_parameters():
    """tests/test_architecture.py's rule for numba intrinsics: their parameters after the
    typing context (``typingctx``, numba's, not the caller's)."""
    found = []
    intrinsics = 0
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.FunctionDef) and _intrinsic(node)):
                continue
            intrinsics += 1
            n = len(node.args.args) - 1 + len(node.args.kwonlyargs)
            if node.args.vararg is not None or n > MOST_PARAMETERS:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {n}")
    assert intrinsics >= 3  # popcount, the SGM step, the median's lanes at least
    assert not found, "\n".join(found)
