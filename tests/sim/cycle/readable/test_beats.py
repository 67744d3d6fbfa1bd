"""The readable chip's beats are the typed ones of sim/cycle/readable/beats.py (the table of
docs/architecture.md is generated from them): every FIFO carries the kind its producer's kind
is listed for, and in raster order, frame after frame, as the beats' place fields say."""

import numpy as np
import pytest

from stereosim.core.config import load_config
from stereosim.sim.cycle.fifo.readable import Fifo
from stereosim.sim.cycle.plan import build_plan
from stereosim.sim.cycle.readable.beats import BEATS

CENSUS = {"sva.disparities": 16, "nna.descriptor": "census"}


def _pairs(frames, h, w, seed=0, shift=3):
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (frames, h, w + shift), dtype=np.uint8)
    return base[:, :, :w].copy(), base[:, :, shift:].copy()


@pytest.mark.parametrize("over", [
    {},
    {"nna.stereo_submodules": 4, "source.kind": "camera", "clocks.camera_mhz": 100,
     "source.camera_hblank": 4, "source.camera_vblank": 1},
    {"nna.stereo_submodules": 4, "nna.split": "rows", "nna.descriptor": "cnn"},
])
def test_every_fifo_carries_its_producers_beat_in_raster_order(over, monkeypatch, run_cycle):
    pushed: dict[str, list] = {}
    push = Fifo.push

    def recording_push(fifo, item):
        pushed.setdefault(fifo.name, []).append(item)
        push(fifo, item)

    monkeypatch.setattr(Fifo, "push", recording_push)
    left, right = _pairs(2, 8, 40)
    plan = build_plan(load_config(overrides={**CENSUS, **over}), (8, 40), frames=2)
    words, _, _ = run_cycle(left, right, plan)
    assert set(pushed) == {f.name for f in plan.fifos}
    for fifo in plan.fifos:
        kind = plan.block(fifo.producer).kind
        (beat,) = [b for b in BEATS if kind in b.pushed_by]
        beats = pushed[fifo.name]
        assert all(type(b) is beat for b in beats), (fifo.name, beat.__name__)
        assert len(beats) == 2 * fifo.beats
        places = [(b.frame, b.y, b.x) for b in beats]
        assert places == sorted(set(places)), fifo.name  # raster order, frame after frame
    # the sink's beats hold the words where their place says
    last = [b for b in pushed["sva_to_sink"] if b.frame == 1]
    assert all(words[b.y, b.x] == b.word for b in last)
