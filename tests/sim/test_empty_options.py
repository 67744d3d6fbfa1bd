"""A file or size option given as '' (an unset shell variable, say) is refused in one line,
never taken as unset (which fell back to a default file) or as the working directory."""

import pytest

from stereosim.sim.cli import main

CASES = [
    ["config", "plan", "--png", ""],
    ["config", "plan", "--size", ""],
    ["estimate", "--size", ""],
    ["eval", "DATA", "--out", ""],
    ["eval", "DATA", "--save", ""],
    ["eval", ""],
    ["sweep", "SWEEP", "--out", ""],
    ["sweep", ""],
    ["plot", "RESULTS", "--x", "a", "--y", "b", "--png", ""],
    ["plot", "", "--x", "a", "--y", "b", "--png", "p.png"],
    ["config", "backend", ""],
]


@pytest.mark.parametrize("argv", CASES, ids=[" ".join(a) or "''" for a in CASES])
def test_an_empty_path_or_size_is_one_line_and_writes_nothing(argv, tmp_path, monkeypatch,
                                                              capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "DATA").mkdir()
    (tmp_path / "SWEEP").write_text('scenes = ["default"]\n[grid]\n"sva.p1" = [1, 2]\n')
    (tmp_path / "RESULTS").write_text("a,b\n1,2\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "empty" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_sweep_refuses_a_target_rate_that_is_not_above_zero(tmp_path, capsys):
    assert main(["sweep", str(tmp_path / "s.toml"), "--target-fps", "0"]) == 2
    assert "--target-fps must be above 0" in capsys.readouterr().err


def test_the_sweep_summary_names_the_least_sram_reaching_the_target():
    from stereosim.sim.whatif_cli import sweep_summary

    rows = [{"point": str(i), "status": "ok", "sram_bits": 1000 * (i + 1),
             "throughput.fps_bound": 20.0 * (i + 1), "nna.stereo_submodules": 2 * (i + 1)}
            for i in range(5)]
    lines = sweep_summary(rows, ["nna.stereo_submodules"], target_fps=55.0)
    (line,) = [x for x in lines if x.startswith("target ")]
    assert line == ("target 55.0 fps (given): the least SRAM that reaches it is "
                    "stereo_submodules=6, 60.0 fps, SRAM 3,000 bits")
    lines = sweep_summary(rows, ["nna.stereo_submodules"], target_fps=500.0)
    (line,) = [x for x in lines if x.startswith("target ")]
    assert line.endswith("no point reaches it (best 100.0 fps)")
    assert not [x for x in sweep_summary(rows, ["nna.stereo_submodules"])
                if x.startswith("target ")]  # no target known: no line
