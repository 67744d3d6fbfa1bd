"""What the NNA's descriptor window and MAC array imply for a frame: the window's reach, the MAC
cycles per descriptor, and how a frame is shared by several submodules (tiles with halos).

These are facts of the stage, used by the chip plan (``sim.cycle.plan``), the clocked blocks and
the analytic estimate alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from stereosim.nna.descriptor import network
from stereosim.sim.config import NnaConfig
from stereosim.sim.errors import ConfigError


def half_window(cfg: NnaConfig) -> int:
    """Rows above and below a pixel that its descriptor reads: the sum of the layers' K // 2
    (CNN), h // 2 (census)."""
    if cfg.descriptor == "census":
        return cfg.census.window[1] // 2
    return network(cfg).reach


def half_window_width(cfg: NnaConfig) -> int:
    """Columns left and right of a pixel that its descriptor reads: the sum of the layers'
    K // 2, or w // 2."""
    if cfg.descriptor == "census":
        return cfg.census.window[0] // 2
    return network(cfg).reach


def window_rows(cfg: NnaConfig) -> int:
    """Input rows one output row of descriptors reads: 2 h + 1."""
    return 2 * half_window(cfg) + 1


def cycles_per_descriptor(cfg: NnaConfig) -> int:
    """MAC-array cycles per descriptor: ceil(MACs per descriptor / macs) for the CNN (one
    layer: ceil(K*K*C / macs)), 1 for the census unit."""
    if cfg.descriptor == "census":
        return 1
    return math.ceil(macs_per_descriptor(cfg) / cfg.macs)


def macs_per_descriptor(cfg: NnaConfig) -> int:
    """Multiply-accumulates of one descriptor: the sum over the CNN's layers of K*K*C_in*C_out
    (one layer: K*K*C); census descriptors use no MACs."""
    if cfg.descriptor == "census":
        return 0
    return sum(network(cfg).layer_macs)


def check_line_buffer(cfg: NnaConfig) -> None:
    """A line buffer must hold the descriptor window's rows (ConfigError otherwise)."""
    need = window_rows(cfg)
    if cfg.line_buffer_rows < need:
        raise ConfigError(
            f"nna.line_buffer_rows={cfg.line_buffer_rows} cannot hold the {need}-row "
            f"descriptor window: use at least {need}"
        )


@dataclass(frozen=True)
class Tile:
    """The part of a camera's frame one submodule serves: the output region
    [x0, x1) x [y0, y1) and the input region it needs (the output region widened by the
    descriptor window's halo, clipped to the image)."""

    x0: int
    x1: int
    y0: int
    y1: int
    in_x0: int
    in_x1: int
    in_y0: int
    in_y1: int

    def takes_input(self, x: int, y: int) -> bool:
        return self.in_x0 <= x < self.in_x1 and self.in_y0 <= y < self.in_y1

    def owns(self, x: int, y: int) -> bool:
        return self.x0 <= x < self.x1 and self.y0 <= y < self.y1

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, columns) of the output region."""
        return self.y1 - self.y0, self.x1 - self.x0

    @property
    def in_shape(self) -> tuple[int, int]:
        """(rows, columns) of the input region."""
        return self.in_y1 - self.in_y0, self.in_x1 - self.in_x0

    @property
    def top_halo(self) -> int:
        """Input rows above the output region."""
        return self.y0 - self.in_y0


def whole_frame(shape: tuple[int, int]) -> Tile:
    """The tile of a submodule that serves the whole frame."""
    h, w = shape
    return Tile(0, w, 0, h, 0, w, 0, h)


def split_frame(shape: tuple[int, int], parts: int, split: str, cfg: NnaConfig) -> list[Tile]:
    """``parts`` tiles of a frame: column tiles (split = "columns") or row bands ("rows"),
    as equal as integers allow (part t covers [floor(t N / parts), floor((t+1) N / parts))),
    each with the halo its window needs. One part is the whole frame."""
    h, w = shape
    if parts == 1:
        return [whole_frame(shape)]
    hy, hx = half_window(cfg), half_window_width(cfg)
    n = w if split == "columns" else h
    if parts > n:
        raise ConfigError(
            f"cannot split {n} {'columns' if split == 'columns' else 'rows'} into {parts} parts: "
            "use fewer nna.stereo_submodules"
        )
    tiles = []
    for t in range(parts):
        a, b = t * n // parts, (t + 1) * n // parts
        if split == "columns":
            tiles.append(Tile(a, b, 0, h, max(0, a - hx), min(w, b + hx), 0, h))
        else:
            tiles.append(Tile(0, w, a, b, 0, w, max(0, a - hy), min(h, b + hy)))
    return tiles
