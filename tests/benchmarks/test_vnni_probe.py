"""The VNNI probe (benchmarks/vnni_probe.py) refuses a CPU without the instruction in one line
(the kernel itself is held to the definition in tests/quant/test_intconv.py)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))


def test_a_cpu_without_vnni_is_one_line(monkeypatch, capsys):
    import vnni_probe

    monkeypatch.setattr(vnni_probe.vnni, "HAS_VNNI", False)
    assert vnni_probe.main([]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "AVX512-VNNI" in err
