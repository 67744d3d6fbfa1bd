"""The shape of the code (docs/architecture.md, "Layers"): imports go one way, checked by
import-linter's contracts in pyproject.toml; every module belongs to a layer; no import hides in
a function to dodge a cycle; no private name crosses a package."""

import ast
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("core", "sim", "nna", "sva", "quant", "traces")  # the folders: stereosim's sub-packages
TOP = "stereosim"


def _relative(module: str) -> str:
    """A project module's name inside ``stereosim`` (``stereosim.sim.api`` -> ``sim.api``); other
    modules keep theirs."""
    return module.removeprefix(TOP + ".")


def _modules() -> dict[str, Path]:
    """Every module of the project's packages, dotted name inside ``stereosim`` -> file."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _docstring_only(path: Path) -> bool:
    """A package's ``__init__.py`` that holds nothing but its docstring."""
    body = ast.parse(path.read_text()).body
    return (path.name == "__init__.py" and len(body) == 1 and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str))


def _contracts() -> list[dict]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"][
        "contracts"]


def _layer_members() -> list[set[str]]:
    (layers,) = [c["layers"] for c in _contracts() if c["id"] == "layers"]
    return [{m.strip() for m in layer.replace("|", ":").split(":")} for layer in layers]


def _covered(module: str, members: set[str]) -> bool:
    return any(module == m or module.startswith(m + ".") for m in members)


def test_the_import_contracts_hold():
    """lint-imports (import-linter) over the five packages: the layers, no circles between
    siblings of any package, the two accelerators apart."""
    # run by this interpreter, whose environment has stereosim: the first lint-imports on PATH
    # may belong to another Python (it said "Could not find package 'stereosim'")
    lint = "import sys; from importlinter.cli import lint_imports_command; lint_imports_command()"
    out = subprocess.run([sys.executable, "-c", lint, str(ROOT / "pyproject.toml")], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    assert "BROKEN" not in out.stdout and "broken" in out.stdout  # "N kept, 0 broken"


def test_ruff_finds_nothing():
    """``ruff check`` with the project's configuration (pyproject.toml, ``[tool.ruff]``) over the
    whole repository: pycodestyle, pyflakes, import order and bugbear."""
    exe = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    out = subprocess.run([exe, "check", "--no-cache", "--output-format", "concise", "."], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]


MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 120


def test_no_module_or_function_grows_past_one_concern():
    """No module over 800 lines (a last line without its newline counts) and no function over
    120 lines (from its ``def`` to its last line) in any of the packages."""
    found = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            text = path.read_text()
            name = path.relative_to(ROOT)
            if (lines := len(text.splitlines())) > MAX_MODULE_LINES:
                found.append(f"{name}: {lines} lines")
            for node in ast.walk(ast.parse(text)):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    size = node.end_lineno - node.lineno + 1
                    if size > MAX_FUNCTION_LINES:
                        found.append(f"{name}:{node.lineno} {node.name}() has {size} lines")
    assert not found, "\n".join(found)


def test_the_contracts_set_the_directions_that_keep_circles_out():
    """The contracts name the directions that keep circles out: the cycle model and the
    application above the stages (a stage never imports the clocked kernel), the trace writers
    above the cycle model and the trace log (the format both engines fill) in the core, the
    quantizer tool above the NNA's weights, the stages below the clocked blocks that run them,
    and no circle among any package's modules."""
    layers = _layer_members()

    def level(module):
        (i,) = [i for i, members in enumerate(layers) if _covered(module, members)]
        return i

    assert (level("sim.api") < level("sim.cycle.readable.chip") < level("nna.census_unit.census")
            < level("core.config"))
    assert level("sim.tracing") < level("traces.vcd") < level("sim.cycle") < level("traces.log")
    assert level("quant.quantizer") < level("nna.conv.weights") < level("quant.artifact")
    assert level("sim.cycle.readable.chip") < level("sva.pipeline")
    (acyclic,) = [c for c in _contracts() if c["type"] == "acyclic_siblings"]
    assert {_relative(a) for a in acyclic["ancestors"]} == set(PACKAGES)


def test_every_module_is_in_exactly_one_layer():
    """A new module cannot slip past the contract: each one belongs to one layer (package
    roots hold only docstrings and the core's names; a block folder's root, only its
    docstring)."""
    layers = _layer_members()
    for name, path in _modules().items():
        hits = [i for i, members in enumerate(layers) if _covered(name, members)]
        if name in PACKAGES or _docstring_only(path):
            continue
        assert len(hits) == 1, f"{name} ({path.relative_to(ROOT)}) is in layers {hits}"


def _imports_in_functions(tree):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for sub in ast.walk(node):
                if isinstance(sub, ast.ImportFrom) and sub.module:
                    yield node.name, _relative(sub.module), sub.lineno
                elif isinstance(sub, ast.Import):
                    for alias in sub.names:
                        yield node.name, _relative(alias.name), sub.lineno


# Python runs a package's __init__ before any module in it, and the core the stages import
# (core.config, core.errors, core.io) lives in the sim package: importing the API eagerly there
# would load the whole application on every `import nna.census`. So the public names sim.run
# and sim.Result resolve on first use (PEP 562). The console entry imports the command line
# only once it has installed the signal handler (a SIGTERM while numba loads gets its line).
DEFERRED = {("sim", "__getattr__", "sim"), ("sim.console", "_command", "sim.cli")}


def test_no_project_import_hides_in_a_function():
    """Imports of the project's own modules sit at the top of the module (optional heavy
    third-party packages -- torch, matplotlib, dask -- may be imported where they are used)."""
    found = []
    for name, path in _modules().items():
        for func, module, line in _imports_in_functions(ast.parse(path.read_text())):
            if module.split(".")[0] in PACKAGES and (name, func, module) not in DEFERRED:
                found.append(f"{path.relative_to(ROOT)}:{line} {func}() imports {module}")
    assert not found, "\n".join(found)


def test_no_private_name_crosses_a_package():
    """``from x import _name`` only inside the package that defines ``_name``."""
    found = []
    for name, path in _modules().items():
        here = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                there = _relative(node.module).rpartition(".")[0]
                for alias in node.names:
                    if alias.name.startswith("_") and not alias.name.startswith("__") \
                            and there != here:
                        found.append(f"{path.relative_to(ROOT)}:{node.lineno} imports "
                                     f"{node.module}.{alias.name}")
    assert not found, "\n".join(found)


@pytest.mark.parametrize("pkg", (*PACKAGES, "."))
def test_package_roots_import_only_the_core(pkg):
    """The sub-packages' roots and stereosim's own (the checkout's root) import only the core
    (the API's names resolve on first use)."""
    tree = ast.parse((ROOT / pkg / "__init__.py").read_text())
    top = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
    for node in top:
        modules = [node.module] if isinstance(node, ast.ImportFrom) else [a.name for a in
                                                                            node.names]
        for module in modules:
            assert module in ("__future__", "stereosim.sim", "stereosim.core.config",
                              "stereosim.core.errors"), module


def _jitted(node) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit", "register_jitable"):
            return True
    return False


def test_no_kernel_takes_more_than_8_parameters():
    """Numba kernels take named structures (the chip plan serialised into record arrays and
    NamedTuples: sim.cycle.compiled.layout), not long positional lists."""
    found = []
    for path in _modules().values():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and _jitted(node):
                n = len(node.args.args) + len(node.args.kwonlyargs)
                if n > 8:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {n}")
    assert not found, "\n".join(found)


def _compiled_apart(node) -> bool:
    """A kernel numba compiles on its own (``@njit`` without ``inline="always"``): called with a
    literal argument, it is compiled once more for each literal value."""
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name == "register_jitable":
            return False
        if isinstance(dec, ast.Call) and any(
                k.arg == "inline" and getattr(k.value, "value", None) == "always"
                for k in dec.keywords):
            return False
    return _jitted(node)


def test_no_kernel_hands_another_a_literal_flag():
    """A kernel calling another kernel with ``True``, ``False`` or a number typed in the call
    makes numba compile the callee again for that literal value (a walker called with
    ``final=True`` and ``final=False`` compiled twice: about a third of the engine's cold
    compile). Such arguments are runtime values: ``np.bool_(True)``, ``np.int64(0)``."""
    trees = [(p, ast.parse(p.read_text())) for p in _modules().values()]
    apart = {n.name for _, t in trees for n in ast.walk(t)
             if isinstance(n, ast.FunctionDef) and _compiled_apart(n)}
    found = []
    for path, tree in trees:
        for fn in ast.walk(tree):
            if not (isinstance(fn, ast.FunctionDef) and _jitted(fn)):
                continue
            for call in ast.walk(fn):
                if not isinstance(call, ast.Call):
                    continue
                f = call.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
                if name not in apart:
                    continue
                for arg in [*call.args, *(k.value for k in call.keywords)]:
                    v = arg.operand if isinstance(arg, ast.UnaryOp) else arg
                    if isinstance(v, ast.Constant) and isinstance(v.value, (bool, int)):
                        found.append(f"{path.relative_to(ROOT)}:{call.lineno} "
                                     f"{name}(... {ast.unparse(arg)} ...)")
    assert not found, "\n".join(found)
