"""The NNA submodule as a clocked block of the cycle model.

One submodule turns one camera's pixel stream into its descriptor stream. It has two halves that
work in the same cycle:

- **Line buffer** (input): pops at most one pixel per cycle into a buffer of ``rows`` image rows.
  The row being received, y_in, must fit beside the rows still needed: the next output row
  y_out reads input rows y_out - 4 .. y_out + 4 (clamped), so the buffer holds
  y_in - max(0, y_out - 4) + 1 <= rows rows. With rows = 9 a new row waits until the window has
  moved on; with 10 it arrives while the window computes.
- **MAC array** (output): output row y may start once input row min(y + 4, H - 1) is complete
  (the replicate border: row 0 needs rows 0..4; "4" is the window's half height h, 4 for the
  9x9 layer, 1 for the default 11x3 census). Each descriptor occupies the array for
  ``cycles_per_descriptor`` = ceil(K*K*C / macs) cycles (census: 1) and is pushed in its last
  cycle; if ``out`` is full the finished descriptor is held (blocked) and the next one starts
  the cycle after the push. Without stalls the initiation interval is cycles_per_descriptor.

Latency of the first descriptor, with the input arriving one pixel per cycle from cycle a
(first pop) and nothing else stalling: row min(4, H - 1) is complete after its last pixel is
popped in cycle a + min(5, H) * W - 1, the row may start in the next cycle, and the descriptor
is pushed cycles_per_descriptor - 1 cycles later.

Beats: in ``(x, y, pixel)``, out ``(x, y, descriptor, pixel)`` (the pixel rides along for the
SVA's adaptive P2). Data: the descriptors of a row are computed, when its first descriptor is
pushed, from the pixels this line buffer actually received (the functional kernel applied to the
received rows max(0, y-4) .. min(H-1, y+4)), so any mistake in what reached the buffer shows in
the bit-exactness tests.
"""

from __future__ import annotations

import math

import numpy as np

from nna.descriptor import compute_descriptor, layer
from sim.clock import Block, ClockDomain
from sim.config import NnaConfig
from sim.errors import ConfigError

def half_window(cfg: NnaConfig) -> int:
    """Rows above and below a pixel that its descriptor reads: K // 2 (CNN), h // 2 (census)."""
    if cfg.descriptor == "census":
        return cfg.census.window[1] // 2
    return layer(cfg)[0].shape[1] // 2


def cycles_per_descriptor(cfg: NnaConfig) -> int:
    """MAC-array cycles per descriptor: ceil(K*K*C / macs) for the CNN, 1 for the census unit."""
    if cfg.descriptor == "census":
        return 1
    weights = layer(cfg)[0]
    c, k, _ = weights.shape
    return math.ceil(k * k * c / cfg.macs)


class NnaSubmodule(Block):
    """One NNA submodule (see the module docstring for ports, latency and initiation interval)."""

    def __init__(self, name: str, domain: ClockDomain, shape: tuple[int, int], inp, out,
                 cfg: NnaConfig):
        super().__init__(name, domain)
        self.height, self.width = shape
        self.inp, self.out, self.cfg = inp, out, cfg
        self.rows = cfg.line_buffer_rows
        self.half = half_window(cfg)
        if self.rows < 2 * self.half + 1:
            raise ConfigError(
                f"nna.line_buffer_rows={self.rows} cannot hold the {2 * self.half + 1}-row "
                f"descriptor window: use at least {2 * self.half + 1}"
            )
        self.cycles_per_descriptor = cycles_per_descriptor(cfg)
        self.pixels = np.zeros(shape, np.uint8)  # what the line buffer received
        self.received = 0  # pixels popped so far (raster order)
        self.emitted = 0  # descriptors pushed so far (raster order)
        self.phase = 0  # MAC cycles spent on the current descriptor
        self._desc_row: np.ndarray | None = None
        self._desc_y = -1
        self._beat_in = None
        self._pushed = False
        self._phase_next = 0

    def _rows_complete(self) -> int:
        return self.received // self.width

    def _row_ready(self, y: int) -> bool:
        return self._rows_complete() > min(y + self.half, self.height - 1)

    def _room_for_input(self) -> bool:
        y_in = self.received // self.width
        y_out = self.emitted // self.width
        if y_out >= self.height:
            return True
        return y_in - max(0, y_out - self.half) + 1 <= self.rows

    def _descriptors_of_row(self, y: int) -> np.ndarray:
        if self._desc_y != y:
            lo = max(0, y - self.half)
            hi = min(self.height, y + self.half + 1)
            self._desc_row = compute_descriptor(self.pixels[lo:hi], self.cfg)[y - lo].copy()
            self._desc_y = y
        return self._desc_row

    def evaluate(self, now_cycle: int) -> None:
        n = self.height * self.width
        moved = False
        # line buffer: one pixel per cycle while there is room
        if self.received < n and self.inp.can_pop() and self._room_for_input():
            self._beat_in = self.inp.pop()
            moved = True
        # MAC array
        self._phase_next = self.phase
        self._pushed = False
        mac_wait = None
        if self.emitted < n:
            y, x = divmod(self.emitted, self.width)
            if self.phase == 0 and not self._row_ready(y):
                mac_wait = "starved"
            else:
                worked = self.phase < self.cycles_per_descriptor
                if self.phase + 1 >= self.cycles_per_descriptor:
                    if self.out.can_push():
                        desc = self._descriptors_of_row(y)[x]
                        self.out.push((x, y, int(desc), int(self.pixels[y, x])))
                        self._pushed = True
                        self._phase_next = 0
                        moved = True
                    else:
                        self._phase_next = self.cycles_per_descriptor
                        mac_wait = "blocked" if not worked else None
                        moved = moved or worked
                else:
                    self._phase_next = self.phase + 1
                    moved = True
        if moved:
            self.busy()
        elif mac_wait == "blocked":
            self.blocked(self.out)
        elif self.emitted < n or self.received < n:
            self.starved(self.inp)
        else:
            self.idle()

    def commit(self) -> None:
        if self._beat_in is not None:
            x, y, value = self._beat_in
            self.pixels[y, x] = value
            self.received += 1
            self._beat_in = None
        if self._pushed:
            self.emitted += 1
            self._pushed = False
        self.phase = self._phase_next

    def signals(self):
        return [("rows_in", 16), ("descriptors_out", 32), ("mac_phase", 16)]

    def signal_values(self):
        return {
            "rows_in": self._rows_complete(),
            "descriptors_out": self.emitted,
            "mac_phase": self.phase,
        }
