"""How many NNA submodules keep up with the camera (issue 46's architect's question: the
robust network at 1080p60): the estimate's answer is the least even count whose NNA work
bound reaches the camera's rate, checked here against every count from 2 up."""

import dataclasses

import pytest

from stereosim.core.config import load_config
from stereosim.sim.cli import PRESETS
from stereosim.sim.cycle.estimate import estimate
from stereosim.sim.cycle.figures import nna_fps
from stereosim.sim.cycle.plan import build_plan, frame_size


def _nna_fps_at(cfg, shape, s):
    n = cfg.nna
    other = dataclasses.replace(cfg, nna=dataclasses.replace(
        n, stereo_submodules=s, submodules=max(n.submodules, s + n.lent_submodules)))
    return nna_fps(build_plan(other, shape))


@pytest.mark.parametrize("presets", [["1080p60"], ["paper-720p"],
                                     ["robust-720p", "1080p60"]])
def test_the_least_count_that_keeps_up_with_the_camera(presets):
    cfg = load_config([PRESETS / f"{p}.toml" for p in presets])
    shape = frame_size(cfg)
    est = estimate(cfg, shape)
    need = est["throughput"]["submodules_for_camera"]
    camera = est["throughput"]["camera_fps"]
    assert need["fps"] == camera
    first = next(s for s in range(2, 257, 2) if _nna_fps_at(cfg, shape, s) >= camera)
    assert need["stereo_submodules"] == first and need["per_camera"] == first // 2
    assert need["nna_fps"] == _nna_fps_at(cfg, shape, first) >= camera
    assert need["submodules"] == max(cfg.nna.submodules, first)
    # the chip built that way: its NNA no longer the bottleneck below the camera's rate
    n = cfg.nna
    built = dataclasses.replace(cfg, nna=dataclasses.replace(
        n, stereo_submodules=first, submodules=need["submodules"]))
    assert estimate(built, shape)["throughput"]["fps_delivered"] == pytest.approx(camera, 1e-3)


def test_the_robust_network_at_1080p60_needs_38_submodules():
    """The figure the issue's architect found by hand: 19 a camera."""
    cfg = load_config([PRESETS / "robust-720p.toml", PRESETS / "1080p60.toml"])
    need = estimate(cfg, (1080, 1920))["throughput"]["submodules_for_camera"]
    assert need["stereo_submodules"] == 38


def test_without_a_camera_there_is_no_target():
    assert estimate(load_config(), (72, 256))["throughput"]["submodules_for_camera"] is None
