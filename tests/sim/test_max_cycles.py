"""``--max-cycles N`` (sim.max_cycles): a run stops once any clock domain ran N cycles, on both
engines at the same instant with the same state of every FIFO; a limit the run does not reach
changes nothing; ``--version`` names the installed version."""

import importlib.metadata
import json

import numpy as np
import pytest

from stereosim.sim.cli import main
from stereosim.sim.config import load_config
from stereosim.sim.cycle.chip import run_cycle
from stereosim.sim.cycle.clock import BudgetExceeded
from stereosim.sim.cycle.engine.run import run_compiled
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.io import encode_png

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census"}


def _pair(h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift), dtype=np.uint8)
    return base[:, :w].copy(), base[:, shift:].copy()


@pytest.mark.parametrize("clocks, share", [((400, 400), 0.5), ((460, 465), 0.3),
                                            ((300, 500), 0.77)])
def test_the_run_stops_at_the_limit_of_its_fastest_domain(clocks, share):
    """With N = sim.max_cycles every domain may run N cycles: the fastest clock gets there first,
    so the run stops with that domain at exactly N cycles and the others at the cycles their
    clock fits into the same time; both engines agree on the message and the state."""
    left, right = _pair(6, 40)
    over = {**CENSUS, "clocks.nna_mhz": clocks[0], "clocks.sva_mhz": clocks[1]}
    free = run_compiled(build_plan(load_config(overrides=over), left.shape), left, right)
    limit = int(share * max(free.report["cycles"]["total"].values()))
    cfg = load_config(overrides={**over, "sim.max_cycles": limit})
    plan = build_plan(cfg, left.shape)
    assert plan.budget == {"nna": limit, "sva": limit}
    with pytest.raises(BudgetExceeded) as fast:
        run_compiled(plan, left, right)
    with pytest.raises(BudgetExceeded) as slow:
        run_cycle(left, right, cfg)
    assert str(fast.value) == str(slow.value)
    assert fast.value.fifos == slow.value.fifos and fast.value.cycles == slow.value.cycles
    fastest = min(plan.domains, key=lambda d: (plan.domains[d].period_fs, d))
    assert fast.value.cycles[fastest] == limit
    for d, dom in plan.domains.items():  # every domain's edges before the stop instant
        per = dom.period_fs
        assert fast.value.cycles[d] == -(-limit * plan.domains[fastest].period_fs // per)
    assert f"stopped by sim.max_cycles = {limit} (--max-cycles N)" in str(fast.value)


def test_a_limit_the_run_does_not_reach_changes_nothing():
    left, right = _pair(6, 40)
    free = load_config(overrides=CENSUS)
    words, report, _ = run_cycle(left, right, free)
    need = max(report["cycles"]["total"].values())
    capped = load_config(overrides={**CENSUS, "sim.max_cycles": need})
    frame = run_compiled(build_plan(capped, left.shape), left, right)
    assert np.array_equal(frame.words, words)
    assert frame.report["cycles"] == report["cycles"]
    with pytest.raises(BudgetExceeded):  # one cycle fewer does not complete the frame
        run_compiled(build_plan(load_config(overrides={**CENSUS, "sim.max_cycles": need - 1}),
                                left.shape), left, right)


def test_the_cli_stops_with_one_line_and_writes_nothing(tmp_path, capsys):
    left, right = _pair(12, 40)
    lp, rp = tmp_path / "l.png", tmp_path / "r.png"
    lp.write_bytes(encode_png(left))
    rp.write_bytes(encode_png(right))
    out = tmp_path / "out"
    args = ["run", "--left", str(lp), "--right", str(rp), "--disparities", "16",
            "--out", str(out)]
    assert main(args + ["--max-cycles", "500"]) == 2
    _, err = capsys.readouterr()
    assert err.count("\n") == 1
    assert "stopped by sim.max_cycles = 500" in err and "src_left_to_nna" in err
    assert not out.exists()
    assert main(args + ["--max-cycles", "0"]) == 2  # not a positive count
    assert "--max-cycles" in capsys.readouterr().err
    assert main(args + ["--max-cycles", "10000000", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["config"]["sim"]["max_cycles"] == 10000000


def test_version_is_the_installed_one(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"stereosim {importlib.metadata.version('stereosim')} (Python ")
