"""``stereosim estimate`` answers the chip the cycle model runs, on every shipped preset
(configs/*.toml, at its camera's frame size): frame latency and first output of one frame
within 1 % of a one-frame cycle run (to the cycle, in fact, and the same energy a frame), the
rate the chip delivers within 1 % of the sustained rate of a short stream
(``throughput.fps_delivered``: the work bound, or the camera's rate when the camera is the
bottleneck -- with frame buffers the chip drops the camera frames beyond its bound), and no
overflow warning where the cycle model runs the stream without one.

Every preset but the census baseline has a camera writing into DRAM frame buffers; the
estimate once timed that path as if the camera fed the NNA directly (1080p60: 13.60 ms and
99 us against the cycle model's 16.11 ms and 159 us) and warned of an overflow that cannot
happen."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim.api import run, run_stream
from stereosim.sim.cli import PRESETS
from stereosim.sim.cycle.estimate import estimate

NAMES = sorted(p.stem for p in PRESETS.glob("*.toml"))
FRAMES = 4  # a short stream: enough for a preset that drops frames to take three


def _shape(name: str, cfg) -> tuple[int, int]:
    """The preset's camera frame (H, W): its ``source.camera_width`` / ``camera_height`` when
    it names them, else 1920x1080 for 1080p60 and 1280x720 for the others."""
    w = getattr(cfg.source, "camera_width", 0) or (1920 if name == "1080p60" else 1280)
    h = getattr(cfg.source, "camera_height", 0) or (1080 if name == "1080p60" else 720)
    return h, w


def _pair(shape):
    """A textured pair: noise, the right view shifted by 7 pixels."""
    left = np.random.default_rng(46).integers(0, 256, shape, dtype=np.uint8)
    return left, np.roll(left, -7, axis=1)


def test_every_shipped_preset_is_checked():
    assert {"paper-720p", "1080p60", "census-baseline", "robust-720p"} <= set(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_the_estimate_answers_the_cycle_models_chip(name):
    cfg = load_config(PRESETS / f"{name}.toml")
    shape = _shape(name, cfg)
    est = estimate(cfg, shape)
    pair = _pair(shape)
    one = run(*pair, mode="cycle", config=cfg).report
    lat = est["latency"]
    assert lat["frame_ms"] == pytest.approx(one["latency"]["frame_ms"], rel=0.01)
    assert lat["first_output_us"] == pytest.approx(one["latency"]["first_output_us"], rel=0.01)
    # and, as docs/whatif.md says, to the cycle
    assert lat["first_output_sva_cycle"] == one["cycles"]["first_output"]["sva"]
    assert lat["last_output_sva_cycle"] == one["cycles"]["last_output"]["sva"]
    # the default table's clocks cost nothing: the estimate's energy a frame is the run's
    assert est["energy"]["per_frame_uj"] == one["energy"]["per_frame_uj"]
    stream = run_stream([pair] * FRAMES, config=cfg).report["stream"]  # raises on an overflow
    assert stream["frames_completed"] >= 3
    assert est["throughput"]["fps_delivered"] == pytest.approx(stream["sustained_fps"], rel=0.01)
    assert not [w for w in est["warnings"] if "overflow" in w or "frame buffer" in w]
