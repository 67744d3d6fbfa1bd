"""The VNNI probe's dot-product convolution (benchmarks/vnni_probe.py) is the NNA's layer: its
descriptors equal the naive definition (nna/conv.py) bit for bit, on random images and
random single layers of odd kernels up to 11, whatever the offset and bias."""

import sys
from pathlib import Path

import numpy as np
import pytest
from llvmlite import binding

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from stereosim.nna.conv import cnn_descriptor_ref  # noqa: E402

HAS_VNNI = binding.get_host_cpu_features().get("avx512vnni", False)


@pytest.mark.skipif(not HAS_VNNI, reason="the probe needs a CPU with AVX512-VNNI")
@pytest.mark.parametrize("k, c_out, seed", [(9, 32, 0), (9, 32, 1), (3, 8, 2), (5, 16, 3),
                                            (11, 32, 4), (7, 1, 5)])
def test_the_probe_equals_the_definition(k, c_out, seed):
    import vnni_probe

    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(k, 40)), int(rng.integers(k, 70))
    img = rng.integers(0, 256, (h, w), dtype=np.uint8)
    weights = rng.integers(-128, 128, (c_out, 1, k, k)).astype(np.int8)
    bias = rng.integers(-20000, 20000, c_out).astype(np.int32)
    offset = int(rng.integers(0, 256))
    got = vnni_probe.vnni_descriptor(img, weights, bias, offset)
    np.testing.assert_array_equal(got, cnn_descriptor_ref(img, weights[:, 0], bias, offset))


def test_a_cpu_without_vnni_is_one_line(monkeypatch, capsys):
    import vnni_probe

    monkeypatch.setattr(vnni_probe.binding, "get_host_cpu_features", lambda: {})
    assert vnni_probe.main([]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "AVX512-VNNI" in err
