"""Synthetic Middlebury scenes for the training tests."""

from pathlib import Path

import numpy as np
import pytest

from stereosim.core.io import encode_png


def write_scene(folder: Path, seed: int, shift: int, h: int = 30, w: int = 400) -> None:
    """A 2006-layout scene: a smooth random texture, the right view shifted by ``shift``
    pixels, GT x3 as Middlebury stores it (the first ``shift`` columns unknown on the left, the
    last on the right); ThirdSize width, so the loader applies the x3 scale."""
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 256, (h, w + shift)).astype(np.float64)
    base = (base + np.roll(base, 1, 0) + np.roll(base, 1, 1) + np.roll(base, (1, 1), (0, 1))) / 4
    base = base.astype(np.uint8)
    folder.mkdir(parents=True)
    (folder / "view1.png").write_bytes(encode_png(base[:, :w].copy()))
    (folder / "view5.png").write_bytes(encode_png(base[:, shift:].copy()))
    gt = np.full((h, w), 3 * shift, np.uint8)
    gt[:, :shift] = 0
    gt_right = np.full((h, w), 3 * shift, np.uint8)
    gt_right[:, w - shift:] = 0
    (folder / "disp1.png").write_bytes(encode_png(gt))
    (folder / "disp5.png").write_bytes(encode_png(gt_right))


@pytest.fixture(scope="session")
def scene_writer():
    """:func:`write_scene`, for the test modules (which cannot import each other)."""
    return write_scene
