"""The named presets of configs/ (``--config NAME``): each loads, builds its chip, and the
analytic work bound is the one its comment derives by hand."""

import pytest

from stereosim.core.config import DESCRIPTOR_DEFAULTS, load_config
from stereosim.sim.cli import PRESETS, main
from stereosim.sim.cycle.estimate import estimate

NAMES = ("paper-720p", "1080p60", "census-baseline", "robust-720p", "hybrid-720p")


def test_the_shipped_presets_are_the_documented_ones():
    assert sorted(p.stem for p in PRESETS.glob("*.toml")) == sorted(NAMES)


def _bound(cfg, h, w):
    """The estimate's bottleneck and its work per frame (ms)."""
    thr = estimate(cfg, (h, w))["throughput"]
    return thr["bottleneck"], thr["work_ms_per_frame"][thr["bottleneck"]]


def test_paper_720p_is_bound_by_the_nna_at_55_fps():
    """9 NNA cycles per descriptor, 1280 x 720 descriptors per camera at 460 MHz: 18.031 ms,
    55.459 fps; the 720p60 camera's 1650 x 750 pixel clocks at 74.25 MHz: 16.667 ms."""
    cfg = load_config(PRESETS / "paper-720p.toml")
    block, ms = _bound(cfg, 720, 1280)
    assert block == "nna_left"
    assert ms == pytest.approx(9 * 1280 * 720 / 460e6 * 1e3, abs=1e-6)
    assert 1e3 / ms == pytest.approx(55.459, abs=5e-4)
    work = estimate(cfg, (720, 1280))["throughput"]["work_ms_per_frame"]
    assert work["camera_left"] == pytest.approx(1650 * 750 / 74.25e6 * 1e3, abs=1e-6)
    assert cfg.source.frame_buffers == 2 and cfg.source.on_overflow == "drop_frame"


def test_1080p60_keeps_up_with_its_camera():
    """Three submodules per camera: 9 x 1920 x 1080 / 3 cycles at 460 MHz = 13.523 ms, under the
    camera's 2200 x 1125 / 148.5 MHz = 16.667 ms frame period; the SVA's frame at 465 MHz,
    8.956 ms: 1080 rows of 1919 x 2 cycles, 1079 row starts of r + 1 = 4 (box 7) and the frame
    start 4 + S + 6 x 1920 (the 5x5 median's skew S = 2 x 1921, six passes)."""
    cfg = load_config(PRESETS / "1080p60.toml")
    work = estimate(cfg, (1080, 1920))["throughput"]["work_ms_per_frame"]
    block, ms = _bound(cfg, 1080, 1920)
    assert block.startswith("camera_")
    assert ms == pytest.approx(2200 * 1125 / 148.5e6 * 1e3, abs=1e-6)  # 60 fps (ms rounded)
    nna = [v for k, v in work.items() if k.startswith("nna_")]
    assert len(nna) == 6
    assert max(nna) == pytest.approx(9 * 1920 * 1080 / 3 / 460e6 * 1e3, abs=1e-6)
    ticks = 1080 * 1919 * 2 + 1079 * 4 + 4 + 2 * 1921 + 6 * 1920
    assert work["sva"] == pytest.approx(ticks / 465e6 * 1e3, abs=1e-6)


def test_census_baseline_keeps_the_census_penalties():
    cfg = load_config(PRESETS / "census-baseline.toml")
    assert cfg.nna.descriptor == "census"
    assert (cfg.sva.p1, cfg.sva.p2) == (DESCRIPTOR_DEFAULTS["census"]["p1"],
                                        DESCRIPTOR_DEFAULTS["census"]["p2"])


def test_robust_720p_sustains_30_fps_on_the_ten_submodules(monkeypatch, tmp_path):
    """Its network's weight file is named relative to the preset (core.config.loader.read_layer)
    and found from any working directory; the NNA's work bound at 720p is at least 30 fps on
    10 submodules (5 per camera)."""
    monkeypatch.chdir(tmp_path)  # not the repository: benchmarks/models/... is not here
    cfg = load_config(PRESETS / "robust-720p.toml")
    assert cfg.nna.stereo_submodules == cfg.nna.submodules == 10
    block, ms = _bound(cfg, 720, 1280)
    assert block.startswith("nna_") and 1e3 / ms >= 30.0


def test_hybrid_720p_is_the_robust_chip_with_census_bits_beside_the_network(monkeypatch,
                                                                             tmp_path):
    """The robust preset's network, submodules and clocks, the 11x3 census beside it, the
    weights picked per frame; the census adds no MAC cycles, so its work bound is the robust
    chip's, at least 30 fps at 720p."""
    monkeypatch.chdir(tmp_path)
    hybrid = load_config(PRESETS / "hybrid-720p.toml")
    robust = load_config(PRESETS / "robust-720p.toml")
    assert hybrid.nna.descriptor == "hybrid" and hybrid.sva.weight_mode == "auto"
    assert hybrid.nna.cnn.weights == robust.nna.cnn.weights
    assert (hybrid.nna.stereo_submodules, hybrid.clocks) == (10, robust.clocks)
    assert {k: getattr(hybrid.sva, k) for k in DESCRIPTOR_DEFAULTS["hybrid"]} == \
        DESCRIPTOR_DEFAULTS["hybrid"]
    block, ms = _bound(hybrid, 720, 1280)
    assert (block, ms) == _bound(robust, 720, 1280) and 1e3 / ms >= 30.0


@pytest.mark.parametrize("name", NAMES)
def test_a_preset_is_usable_by_name(name, capsys):
    assert main(["config", "show", "--plain", "--config", name]) == 0
    shown = capsys.readouterr().out
    assert main(["config", "show", "--plain", "--config", str(PRESETS / f"{name}.toml")]) == 0
    assert capsys.readouterr().out == shown


def test_an_unknown_preset_is_one_line_naming_the_presets(capsys):
    assert main(["estimate", "--config", "paper-4k"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "no config file or preset named 'paper-4k'" in err
    assert all(n in err for n in NAMES)
