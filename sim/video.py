"""A stereo pair of videos read frame by frame (``stereosim run --left-video/--right-video``).

:class:`VideoPair` opens both files with OpenCV and gives frame f of each, grey uint8, in order
(the engines read a stream's frames in order; going back is refused). The frame count is the
smaller of the two containers' counts, or ``limit``; a video that ends before its header said
it would is one line, naming the frame. What FFmpeg prints while a video is opened or read is
kept off stderr; its last line becomes part of ours.
"""

from __future__ import annotations

import os
import re

import cv2
import numpy as np

from stereosim.core.errors import InputError
from stereosim.core.io import native_stderr_caught, to_grey


def _reason(said: list[str]) -> str:
    """FFmpeg's last line, for our message: `` ([mov,mp4] moov atom not found)`` (the address
    of its decoder, which changes from run to run, left out)."""
    return f" ({re.sub(r' @ 0x[0-9a-fA-F]+', '', said[-1])})" if said else ""


def _open(path: str | os.PathLike, side: str) -> cv2.VideoCapture:
    if not os.path.isfile(path):
        raise InputError(f"the {side} video {os.fspath(path)!r} does not exist or is not a file")
    with native_stderr_caught() as said:  # FFmpeg's log goes into our line, not beside it
        cap = cv2.VideoCapture(os.fspath(path))
        opened = cap.isOpened()
    if not opened:
        reason = _reason(said)
        raise InputError(f"the {side} video {os.fspath(path)!r} cannot be read{reason}: give a "
                         "video file OpenCV can decode (e.g. .mp4, .avi)")
    return cap


class VideoPair:
    """Frames of two videos as stereo pairs: ``len()``, ``[f]`` -> (left, right) grey uint8,
    in increasing f."""

    def __init__(self, left: str | os.PathLike, right: str | os.PathLike,
                 limit: int | None = None):
        self.paths = (os.fspath(left), os.fspath(right))
        self.caps = (_open(left, "left"), _open(right, "right"))
        counts = [int(c.get(cv2.CAP_PROP_FRAME_COUNT)) for c in self.caps]
        self.count = min(counts)
        if limit is not None:
            self.count = min(self.count, limit)
        if self.count < 1:
            raise InputError(f"the videos hold no frames ({counts[0]} and {counts[1]})")
        self._next = 0

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, f: int) -> tuple[np.ndarray, np.ndarray]:
        if f != self._next:
            raise InputError(f"video frames are read in order: asked for frame {f} after "
                             f"{self._next - 1}")
        out = []
        for cap, path in zip(self.caps, self.paths, strict=True):
            with native_stderr_caught() as said:
                ok, img = cap.read()
            if not ok:
                reason = _reason(said)
                raise InputError(f"the video {path!r} ended at frame {f}, before the "
                                 f"{self.count} frames its header announced{reason}")
            out.append(to_grey(img[:, :, ::-1] if img.ndim == 3 else img))
        self._next += 1
        return out[0], out[1]

    def close(self) -> None:
        for cap in self.caps:
            cap.release()
