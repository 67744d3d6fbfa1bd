"""One import name: the project installs the single top-level package ``stereosim``, whose
sub-packages are the checkout's folders ``sim/``, ``nna/``, ``sva/``, ``quant/`` and
``traces/`` (pyproject.toml maps them), and nothing else lands in site-packages."""

import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("core", "sim", "nna", "sva", "quant", "traces")


def _setuptools() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_package_installed_is_inside_stereosim():
    """The listed packages are stereosim and its sub-packages, each folder mapped to its own
    name; every folder of the five that is a package is listed, so an install leaves none out."""
    conf = _setuptools()
    listed = set(conf["packages"])
    assert all(name == "stereosim" or name.startswith("stereosim.") for name in listed)
    assert conf["package-dir"] == {"stereosim": ".",
                                   **{f"stereosim.{f}": f for f in FOLDERS}}
    found = {"stereosim"} | {
        "stereosim." + ".".join(init.parent.relative_to(ROOT).parts)
        for folder in FOLDERS for init in (ROOT / folder).rglob("__init__.py")}
    assert listed == found


def test_import_stereosim_from_anywhere_and_no_generic_names(tmp_path):
    """In a fresh interpreter started outside the checkout: ``stereosim.run`` and
    ``run_stream`` resolve (and ``dir`` lists them, as it does for ``stereosim.sim``), and none
    of the folders' bare names is importable."""
    code = (
        "import importlib.util as u, stereosim, stereosim.sim as s\n"
        "assert callable(stereosim.run) and callable(stereosim.run_stream)\n"
        "assert {'run', 'run_stream'} <= set(dir(stereosim)) & set(dir(s))\n"
        f"print([n for n in {FOLDERS!r} if u.find_spec(n) is not None])\n"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "[]\n"
