"""What the NNA's descriptor window and MAC array imply for a frame: the window's reach, the MAC
cycles per descriptor, how a frame is shared by several submodules (tiles with halos), and the
layer pipeline of a submodule -- one stage per layer of the network (the census unit: one stage),
each with its MAC share, its cycles per output pixel, its line buffer's rows and its regions.

The layer rules (L layers, layer l of kernel K_l, half kernel h_l = K_l // 2, C_in,l input and
C_out,l output channels):

- MACs per output pixel m_l = K_l^2 C_in,l C_out,l; the MAC share macs_l: ``nna.layer_macs``
  when given, else ``nna.macs`` split in proportion to m_l by largest remainder, each at least
  1 (:func:`mac_shares`); cycles per output pixel II_l = ceil(m_l / macs_l)
  (:func:`~nna.submodule.timing.layer_cycles`: the MAC array's timing rule);
- line buffer rows: layer 0 holds ``nna.line_buffer_rows`` rows (at least K_0), layer l >= 1
  K_l plus the same slack (:func:`layer_rows`); a layer of stride s_l holds K_l + slack s_l
  (:func:`buffer_rows`: the slack counts output rows, and each takes s_l input rows); its line
  buffer holds rows x its input width x C_in,l x 8 bits (:func:`line_buffer_bits`);
- stride: a layer of stride s reads its input around every s-th pixel of every s-th row, with
  the input padded by h_l ("same" padding): an input of N pixels gives ceil(N / s) outputs
  (:func:`strided_size`); the stereo descriptor's layers all have stride 1;
- a layer pipeline's frame: its layers run side by side, so a frame takes the busiest layer's
  output pixels x cycles per pixel, max_l items_l II_l
  (:func:`~nna.submodule.timing.pipeline_cycles`);
- regions: layer l's output region is the tile's output region widened by R_l = h_{l+1} + ...
  + h_{L-1} (clipped to the frame), its input region the tile's widened by R_l + h_l -- layer
  l - 1's output region; layer 0's input region is the tile's (:func:`layer_tiles`).

One layer (and the census) gives one stage with today's figures: macs_0 = ``nna.macs``,
cpp_0 = ceil(K^2 C / macs), rows_0 = ``nna.line_buffer_rows``, the tile's own regions.

These are facts of the stage, used by the chip plan (``sim.cycle.plan``), the clocked blocks and
the analytic estimate alike. Each reads the NNA's :class:`~nna.descriptor.NnaSpec` (the checked
section and the network loaded once where the run started); a tool holding only a raw ``nna``
section gets it resolved first (:func:`~nna.descriptor.as_nna_spec`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from stereosim.core.config import NnaConfig
from stereosim.core.errors import ConfigError
from stereosim.nna.descriptor import NnaSpec, as_nna_spec


def half_window(spec: NnaSpec | NnaConfig) -> int:
    """Rows above and below a pixel that its descriptor reads: the sum of the layers' K // 2
    (CNN), h // 2 (census). The hybrid's census is no taller than its network's reach
    (:func:`nna.descriptor.resolve_nna`)."""
    return sum(as_nna_spec(spec).halves)


def half_window_width(spec: NnaSpec | NnaConfig) -> int:
    """Columns left and right of a pixel that its descriptor reads: the sum of the layers'
    K // 2, or w // 2 (the hybrid: the larger of the two)."""
    spec = as_nna_spec(spec)
    census = spec.cfg.census.window[0] // 2
    if spec.descriptor == "census":
        return census
    if spec.descriptor == "hybrid":
        return max(spec.cnn.reach, census)
    return spec.cnn.reach


def census_rows(spec: NnaSpec | NnaConfig) -> int:
    """Input rows the hybrid descriptor's census unit must hold beside a network of several
    layers (0: it reads layer 0's line buffer -- one layer, whose window holds the census's --
    or the descriptor has no census part).

    The census of output row y is taken when the last layer emits y, from input rows
    y - r_c .. y + r_c (r_c the census's half height). By the room rules
    (:func:`~sim.cycle.rules.nna_rows_started_before_input`) layer l takes input row r only
    while its window -- from max(the frame's first row, y_l - h_l), y_l its next output row --
    and r fit in its rows_l rows, so r <= y_l + rows_l - 1 (at a frame's first rows the window
    is clamped to the frame, so the h_l rows above y_l are not held and do not count); its
    input rows are layer l - 1's output rows, so the newest input row is at most
    y + sum_l rows_l - 1 rows below the last layer's next output row y, and the census rows
    span from y - r_c: sum_l rows_l + r_c rows (:func:`layer_rows`). Both engines track the
    window against this capacity (:mod:`sim.cycle.buffers`), which the first frames of a
    stream can reach."""
    spec = as_nna_spec(spec)
    if spec.descriptor != "hybrid" or len(spec.halves) == 1:
        return 0
    return sum(layer_rows(spec)) + spec.cfg.census.window[1] // 2


def window_rows(spec: NnaSpec | NnaConfig) -> int:
    """Input rows one output row of descriptors reads: 2 h + 1."""
    return 2 * half_window(spec) + 1


def macs_per_descriptor(spec: NnaSpec | NnaConfig) -> int:
    """Multiply-accumulates of one descriptor: the sum over the CNN's layers of K*K*C_in*C_out
    (one layer: K*K*C); census descriptors use no MACs."""
    return sum(as_nna_spec(spec).layer_macs)


def layer_halves(spec: NnaSpec | NnaConfig) -> tuple[int, ...]:
    """Each layer's half kernel h_l = K_l // 2 (rows above and below an output pixel that it
    reads of its input); the census unit is one stage of half height h // 2."""
    return as_nna_spec(spec).halves


def layer_macs_per_pixel(spec: NnaSpec | NnaConfig) -> tuple[int, ...]:
    """Multiply-accumulates of one output pixel of each layer: m_l = K_l^2 C_in,l C_out,l
    (census: one stage of no MACs, 0)."""
    return as_nna_spec(spec).layer_macs


def share_macs(total: int, work: tuple[int, ...]) -> tuple[int, ...]:
    """``total`` MAC units split over layers in proportion to their ``work`` by largest
    remainder: floor(M w_l / sum w) each, the units left over one each to the largest remainders
    (the earlier layer first on ties), then a layer left with none takes one from the layer
    with the most (the earlier on ties), so each has at least 1. Fewer MACs than layers is a
    ConfigError. The stereo network's work is m_l (its layers make about one output pixel per
    pixel each); a network whose strides shrink the frame weighs m_l by its output pixels."""
    n = len(work)
    if total < n:
        raise ConfigError(f"nna.macs={total} cannot give each of the network's {n} layers a "
                          f"MAC unit: use at least {n}")
    weight = sum(work) or 1
    shares = [total * x // weight for x in work]
    order = sorted(range(n), key=lambda i: (-(total * work[i] % weight), i))
    for i in order[:total - sum(shares)]:
        shares[i] += 1
    for i in range(n):
        if shares[i] == 0:
            richest = max(range(n), key=lambda j: (shares[j], -j))
            shares[richest] -= 1
            shares[i] = 1
    return tuple(shares)


def mac_shares(spec: NnaSpec | NnaConfig) -> tuple[int, ...]:
    """The MAC units of each layer's stage: ``nna.layer_macs`` when given (one per layer,
    summing to at most ``nna.macs``), else ``nna.macs`` = M split in proportion to the layers'
    MACs per pixel m_l (:func:`share_macs`). A ``nna.layer_macs`` of the wrong length or sum is
    a ConfigError. One layer (and the census): (M,)."""
    spec = as_nna_spec(spec)
    cfg, m = spec.cfg, spec.layer_macs
    if cfg.layer_macs:
        if len(cfg.layer_macs) != len(m) or sum(cfg.layer_macs) > cfg.macs:
            raise ConfigError(
                f"nna.layer_macs={list(cfg.layer_macs)} must give one MAC share per layer "
                f"({len(m)}) summing to at most nna.macs={cfg.macs}: fix it or leave it empty "
                "(the proportional split)")
        return tuple(cfg.layer_macs)
    return share_macs(cfg.macs, m)


def strided_size(n: int, stride: int) -> int:
    """Outputs of a layer of ``stride`` over ``n`` inputs ("same" padding): ceil(n / s)."""
    return -(-n // stride)


def buffer_rows(kernels: tuple[int, ...], strides: tuple[int, ...], slack: int
                ) -> tuple[int, ...]:
    """Input rows each layer's line buffer holds: its window K_l plus ``slack`` output rows'
    worth of arriving input, slack x s_l rows (a row, or a stride's rows, may arrive while the
    window computes)."""
    return tuple(k + slack * s for k, s in zip(kernels, strides, strict=True))


def line_buffer_bits(rows: int, width: int, channels_in: int) -> int:
    """SRAM bits of a line buffer of ``rows`` rows of ``width`` pixels of ``channels_in`` int8
    activations: rows x width x C_in x 8."""
    return rows * width * channels_in * 8


def layer_rows(spec: NnaSpec | NnaConfig) -> tuple[int, ...]:
    """Input rows each layer's line buffer holds: layer 0 ``nna.line_buffer_rows``, layer
    l >= 1 K_l + (``nna.line_buffer_rows`` - K_0) -- its window and the same slack
    (:func:`buffer_rows` at stride 1)."""
    spec = as_nna_spec(spec)
    kernels = tuple(2 * r + 1 for r in spec.halves)
    return buffer_rows(kernels, (1,) * len(kernels), spec.cfg.line_buffer_rows - kernels[0])


def check_line_buffer(spec: NnaSpec | NnaConfig) -> None:
    """A line buffer must hold its layer's window: layer 0's K_0 rows, the descriptor window
    for a network of one layer; and no later layer's (:func:`layer_rows`) may need more rows
    than ``nna.line_buffer_rows`` may be (ConfigError otherwise)."""
    spec = as_nna_spec(spec)
    cfg = spec.cfg
    need = 2 * spec.halves[0] + 1
    if cfg.line_buffer_rows < need:
        what = ("descriptor window" if len(spec.halves) == 1
                else "window of the network's first layer")
        raise ConfigError(
            f"nna.line_buffer_rows={cfg.line_buffer_rows} cannot hold the {need}-row "
            f"{what}: use at least {need}"
        )
    most = next(f.metadata["hi"] for f in dataclasses.fields(NnaConfig)
                if f.name == "line_buffer_rows")
    for i, rows in enumerate(layer_rows(spec)[1:], start=1):
        if rows > most:  # a later layer's window plus layer 0's slack
            raise ConfigError(
                f"layer {i}'s line buffer would need {rows} rows (its window and the "
                f"nna.line_buffer_rows - K_0 = {cfg.line_buffer_rows - need} rows of slack), "
                f"more than the {most} a line buffer holds (nna.line_buffer_rows' largest "
                "value): use a smaller nna.line_buffer_rows or a network with smaller kernels")


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


def widened(tile: Tile, reach_out: int, reach_in: int, shape: tuple[int, int]) -> Tile:
    """The tile's output region widened by ``reach_out`` rows and columns on each side as an
    output region, and by ``reach_in`` as its input region, both clipped to the frame."""
    h, w = shape

    def grow(a, b, r, n):
        return max(0, a - r), min(n, b + r)

    x0, x1 = grow(tile.x0, tile.x1, reach_out, w)
    y0, y1 = grow(tile.y0, tile.y1, reach_out, h)
    ix0, ix1 = grow(tile.x0, tile.x1, reach_in, w)
    iy0, iy1 = grow(tile.y0, tile.y1, reach_in, h)
    return Tile(x0, x1, y0, y1, ix0, ix1, iy0, iy1)


def layer_tiles(tile: Tile, spec: NnaSpec | NnaConfig, shape: tuple[int, int]
                ) -> tuple[Tile, ...]:
    """Each layer's regions within a submodule serving ``tile``: layer l's output region is the
    tile's widened by R_l = the half kernels of the layers after l, its input region the tile's
    widened by R_l + h_l (layer l - 1's output region), clipped to the frame; layer 0's input
    region is the tile's own (one layer: the tile itself)."""
    halves = layer_halves(spec)
    out = []
    for i in range(len(halves)):
        after = sum(halves[i + 1:])
        if i == 0:
            t = widened(tile, after, 0, shape)
            out.append(Tile(t.x0, t.x1, t.y0, t.y1, tile.in_x0, tile.in_x1, tile.in_y0,
                            tile.in_y1))
        else:
            out.append(widened(tile, after, after + halves[i], shape))
    return tuple(out)


def whole_frame(shape: tuple[int, int]) -> Tile:
    """The tile of a submodule that serves the whole frame."""
    h, w = shape
    return Tile(0, w, 0, h, 0, w, 0, h)


def split_frame(shape: tuple[int, int], parts: int, split: str, spec: NnaSpec | NnaConfig
                ) -> list[Tile]:
    """``parts`` tiles of a frame: column tiles (split = "columns") or row bands ("rows"),
    as equal as integers allow (part t covers [floor(t N / parts), floor((t+1) N / parts))),
    each with the halo its window needs. One part is the whole frame."""
    h, w = shape
    if parts == 1:
        return [whole_frame(shape)]
    hy, hx = half_window(spec), half_window_width(spec)
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
