"""The frames a cycle run simulates: a stream of stereo pairs of one shape, read on demand.

Both engines take a :class:`FrameSupply`: its count, the shape of every frame and ``pair(f)``,
frame f's (left, right) uint8 images. The timing of the chip does not depend on the pixels, so
the compiled engine reads frame f only when it computes that frame's words, in order; a video
or a folder of pairs is then never held whole in memory (the supply keeps the last two frames
it read, so the two cameras of one frame share a read).

What does grow with the number of frames is bounded by :data:`MAX_FRAMES` (checked by
:func:`check_frame_count` before anything is allocated): the timing pass keeps every camera
frame's instants and the report every frame's latency (and, with ground truth, its metrics).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable

import numpy as np

from stereosim.core.errors import ConfigError, InputError
from stereosim.nna.descriptor import compute_descriptor
from stereosim.sva.pipeline.pipeline import sva_stream

# The most camera frames one run simulates (input frames x camera pairs). What a stream keeps
# per frame (python benchmarks/stream_memory.py): the timing pass about 250 bytes at its peak
# (the engine's five int64 instants of each frame, the report's per-frame latency list), and
# with ground truth each frame's metrics, about 4.2 KB in memory and 2.4 KB in report.json for
# two masks -- about 1 GB at the cap (docs/streams.md, "How long a stream may be").
MAX_FRAMES = 100_000


class FrameSupply:
    """``count`` frames of ``shape`` = (H, W); ``read(f)`` returns frame f's (left, right)."""

    def __init__(self, count: int, shape: tuple[int, int],
                 read: Callable[[int], tuple[np.ndarray, np.ndarray]]):
        self.count = int(count)
        self.shape = (int(shape[0]), int(shape[1]))
        self._read = read
        self._cache: OrderedDict[int, tuple[np.ndarray, np.ndarray]] = OrderedDict()

    def pair(self, f: int) -> tuple[np.ndarray, np.ndarray]:
        """Frame f's (left, right), each (H, W) uint8; a frame of another shape is refused."""
        if f in self._cache:
            self._cache.move_to_end(f)
            return self._cache[f]
        left, right = self._read(f)
        for side, img in (("left", left), ("right", right)):
            if img.shape != self.shape:
                got = "x".join(str(v) for v in (img.shape[1::-1] + img.shape[2:]))
                raise InputError(
                    f"frame {f}'s {side} image is {got}, the stream's frames are "
                    f"{self.shape[1]}x{self.shape[0]} grey: every frame of a stream must have "
                    "the same size (and one channel)")
        self._cache[f] = (left, right)
        while len(self._cache) > 2:
            self._cache.popitem(last=False)
        return left, right

    @classmethod
    def of(cls, left, right=None) -> FrameSupply:
        """A supply from one pair of (H, W) arrays, from two (N, H, W) stacks, or an existing
        supply."""
        if isinstance(left, FrameSupply):
            return left
        left, right = np.asarray(left), np.asarray(right)
        if left.ndim == 2:
            return cls(1, left.shape, lambda f: (left, right))
        return cls(left.shape[0], left.shape[1:], lambda f: (left[f], right[f]))


def check_frame_count(frames: int, pairs: int = 1) -> None:
    """Refuse a stream of more than :data:`MAX_FRAMES` camera frames (``frames`` input frames
    seen by ``pairs`` camera pairs) before any memory is spent on it."""
    total = int(frames) * int(pairs)
    if total > MAX_FRAMES:
        shown = f"{frames:,} frames" if pairs == 1 else \
            f"{frames:,} frames x {pairs} camera pairs = {total:,} camera frames"
        raise InputError(
            f"the stream has {shown}, above the cap of {MAX_FRAMES:,} a run (the timing pass "
            "keeps every frame's instants and the report every frame's latency and metrics): "
            f"simulate it in parts of at most {MAX_FRAMES // pairs:,} frames (--frames)")


def camera_frames(supply: FrameSupply, plan) -> FrameSupply:
    """The supply of a plan's camera frames from the stream's: with ``sva.pairs`` = P camera
    pairs sharing the chip every pair sees the stream, camera frame f being the stream's frame
    f // P. Raises ConfigError when the plan is for another count or shape of frames."""
    pairs = plan.pairs
    if (plan.frames, plan.shape) != (supply.count * pairs, supply.shape):
        raise ConfigError(
            f"the plan is for {plan.frames // pairs} frame(s) of {plan.shape[1]}x"
            f"{plan.shape[0]}, the stream has {supply.count} of {supply.shape[1]}x"
            f"{supply.shape[0]}: build the plan for the frames you run")
    if pairs == 1:
        return supply
    return FrameSupply(supply.count * pairs, supply.shape, lambda f: supply.pair(f // pairs))


def functional_words(spec, bits, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """One frame's output words by the functional model (the chip's words: every engine's
    timing is independent of them, and the readable kernel computes the same from the beats
    it moves); ``spec`` the run's resolved chip (:class:`~sim.cycle.spec.ChipSpec`, the
    plan's ``spec``)."""
    desc_l, desc_r = compute_descriptor(left, spec.nna), compute_descriptor(right, spec.nna)
    return sva_stream(desc_l, desc_r, left, spec.sva, bits)
