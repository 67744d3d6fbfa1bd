"""The chip's timing rules that both cycle engines and the estimate apply, written once.

Each rule is a small pure function of integers. ``register_jitable`` keeps it a plain Python
function for the readable kernel and the analytic estimate, and lets the compiled engine inline
it into its numba kernels -- so the rule below is the one every engine runs. Cycles count edges
of a clock domain from 0; every clock of the chip has its first edge at t = 0.

What is *not* here is deliberate: the readable kernel applies these rules cycle by cycle to its
committed state (it is the specification); the compiled engine applies them to whole streams of
beats (docs/compiled-engine.md). The FIFO's rule is its block's (:mod:`sim.cycle.fifo.rule`).
Derived constants (windows, depths, widths, budgets) live in the
chip plan (:mod:`sim.cycle.plan`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba.extending import register_jitable

from stereosim.core.errors import ConfigError

FS_PER_S = 10**15


def period_fs(freq_hz: float) -> int:
    """A clock's period in whole femtoseconds: round(1e15 / f)."""
    return round(FS_PER_S / freq_hz)


@register_jitable
def memory_first_cycle(k, freq_hz, bytes_per_s):
    """The first cycle in which a memory source's token bucket lets pixel k (from 0) leave: the
    smallest c with (k + 1) f <= (c + 1) B (0 when the bandwidth is at least one byte per
    cycle)."""
    if bytes_per_s >= freq_hz:
        return 0
    return ((k + 1) * freq_hz + bytes_per_s - 1) // bytes_per_s - 1


@register_jitable
def camera_frame_start(f, frame_clocks, pairs):
    """The pixel-clock cycle in which camera frame f starts. One camera pair: frames back to
    back, f * ``frame_clocks``. ``pairs`` = P camera pairs sharing the chip frame by frame
    (``sva.pairs``): the stream's frame f is pair f % P's (f // P)-th, and pair p runs pair 0's
    raster p * (frame_clocks // P) clocks later -- the pairs' frame starts spread evenly over a
    frame period, in the order of f."""
    return (f // pairs) * frame_clocks + (f % pairs) * (frame_clocks // pairs)


@register_jitable
def camera_cycle(f, x, y, line_clocks, frame_clocks, pairs):
    """The pixel-clock cycle in which a camera delivers pixel (x, y) of camera frame f: each
    frame a raster of ``frame_clocks`` = (H + vblank)(W + hblank) clocks of ``line_clocks``
    = W + hblank clocks per line, from its start (:func:`camera_frame_start`)."""
    return camera_frame_start(f, frame_clocks, pairs) + y * line_clocks + x


@register_jitable
def camera_in_lines(c, frames, lines, line_clocks, frame_clocks, pairs):
    """Is a camera of the stream in the lines of one of its ``frames`` camera frames (blanking
    between its pixels included) in its cycle c?"""
    step = frame_clocks // pairs
    for p in range(pairs):
        cp = c - p * step
        if cp < 0:
            continue
        fl = cp // frame_clocks
        if fl * pairs + p < frames and (cp - fl * frame_clocks) // line_clocks < lines:
            return True
    return False


@register_jitable
def camera_pixels_streamed(c, frames, h, w, line_clocks, frame_clocks, pairs):
    """Pixels the cameras of one side have streamed up to their cycle c included (each pair's
    raster, frame after frame, over the stream's ``frames`` camera frames)."""
    step = frame_clocks // pairs
    total = 0
    for p in range(pairs):
        cp = c - p * step
        if cp < 0:
            continue
        count = (frames - p + pairs - 1) // pairs  # camera frames of pair p
        fl = cp // frame_clocks
        if fl >= count:
            total += count * h * w
            continue
        line = (cp - fl * frame_clocks) // line_clocks
        col = cp - fl * frame_clocks - line * line_clocks
        total += fl * h * w + (h * w if line >= h else line * w + min(col + 1, w))
    return total


@register_jitable
def camera_busy_cycles(cycles, frames, lines, line_clocks, frame_clocks, pairs):
    """Cycles among the first ``cycles`` in which a camera of the stream is in the lines of a
    frame: the union over its ``frames`` camera frames of [start, start + lines x line_clocks)
    (with several pairs their frames overlap)."""
    busy = 0
    covered = 0  # the cycles before it are counted
    for f in range(frames):
        s = camera_frame_start(f, frame_clocks, pairs)
        e = s + lines * line_clocks
        lo, hi = max(s, covered), min(e, cycles)
        if hi > lo:
            busy += hi - lo
        covered = max(covered, e)
    return busy


@register_jitable
def frame_buffer_admits(g, buffers, busy_until_fs, start_fs):
    """Does a camera (pair) with ``buffers`` frame buffers in DRAM take the frame it starts at
    ``start_fs`` as its g-th (from 0)? Yes while fewer than ``buffers`` frames were taken, else
    when the reader finished the frame that held the buffer, the pair's (g - buffers)-th taken,
    at ``busy_until_fs`` -- strictly before the frame starts. (Pairs sharing the chip each have
    their own buffers and count their own frames.)"""
    return g < buffers or busy_until_fs < start_fs


# ---- the DRAM channel (dram.model = "tdm") ------------------------------------------------------
# One channel, time-division multiplexed: time is cut into slots of one burst each (burst bytes
# at the peak bandwidth), slots into rounds of R; each client owns fixed slots of every round
# (the plan's DramPlan: the stereo pair's reads first, left then right, then the cameras'
# frame-buffer writes, the disparity write-back, a spill, a lent network). Slot g spans
# [g s, (g + 1) s) femtoseconds from 0. A client's bursts take its slots in order.


@register_jitable
def dram_slot(request_fs, last_slot, slot_fs, round_slots, first, count):
    """The slot serving a client's burst requested at ``request_fs``: the first of the client's
    slots (offsets ``first`` .. ``first + count - 1`` of every round of ``round_slots``) that
    starts at or after the request and after its previous burst's slot ``last_slot`` (-1 before
    the first)."""
    g = max((request_fs + slot_fs - 1) // slot_fs, last_slot + 1)
    rnd = g // round_slots
    o = g - rnd * round_slots
    if o < first:
        return rnd * round_slots + first
    if o < first + count:
        return g
    return (rnd + 1) * round_slots + first


@register_jitable
def dram_read_ready_fs(slot, slot_fs, latency_fs):
    """When a stereo read that takes slots ``slot`` (left) and ``slot + 1`` (right) is in the
    chip: the right view's slot's end plus the access latency."""
    return (slot + 2) * slot_fs + latency_fs


@register_jitable
def dram_write_done_fs(slot, slot_fs):
    """When a write-back burst served in ``slot`` has left the sink's write buffer: the slot's
    end."""
    return (slot + 1) * slot_fs


@register_jitable
def burst_of(k, n, per_burst):
    """(burst over the stream, index of its last item over the stream) of item k (from 0, over
    a stream of frames of n items): bursts of ``per_burst`` items, restarted at each frame (a
    frame's last burst may be short)."""
    f = k // n
    i = k - f * n
    per_frame = (n + per_burst - 1) // per_burst
    b = i // per_burst
    return f * per_frame + b, f * n + min((b + 1) * per_burst, n) - 1


@register_jitable
def burst_last(burst, n, per_burst):
    """The index over the stream of the last item of ``burst`` (as :func:`burst_of`)."""
    per_frame = (n + per_burst - 1) // per_burst
    f = burst // per_frame
    b = burst - f * per_frame
    return f * n + min((b + 1) * per_burst, n) - 1


@register_jitable
def first_edge_at(t_fs, period_fs):
    """The first edge of a clock of ``period_fs`` at or after the instant ``t_fs``."""
    return (t_fs + period_fs - 1) // period_fs


@register_jitable
def nna_last_input_row(y, half, image_rows):
    """The last image row the descriptors of image row y read: min(y + h, H - 1) (replicate
    border below)."""
    return min(y + half, image_rows - 1)


@register_jitable
def nna_rows_started_before_input(r, rows, half, top_halo, out_rows, in_rows):
    """Output rows of a tile (counted over the stream of frames) its MAC array must have started
    before the tile's input row r (counted over the stream: frame r // in_rows, row r % in_rows
    of it) may enter a line buffer of ``rows`` rows: the row arriving must fit beside the rows
    the next output row still reads -- from max(0, y_out + top_halo - h) of its own frame --
    unless every output row of the frames before has started. In frame 0 a row below ``rows``
    waits for nothing; in a later frame it may wait for the last output rows of the frame
    before, which still read that frame's last rows. 0: no wait."""
    f = r // in_rows
    local = r - f * in_rows
    if local >= rows:
        return f * out_rows + max(0, min(local + 1 - rows + half - top_halo, out_rows))
    if f == 0:
        return 0
    return (f - 1) * out_rows + max(0, min(in_rows + local + 1 - rows + half - top_halo,
                                           out_rows))


@register_jitable
def sva_last_input_row(y, radius, image_rows):
    """The last input row the SVA's box row y needs: min(y + r, H - 1) (r the box radius; the
    SGM paths and the LR check's diagonal stay within rows already in, and the median reads
    words the pipeline made, not input rows: its skew, :func:`sva_exit_item`)."""
    return min(y + radius, image_rows - 1)


@register_jitable
def sva_rows_done_before_input(y_in, radius, image_rows):
    """Box rows the SVA must have *issued* (every slot of the row, its last word included, read
    from the row buffers) before it takes input row ``y_in``. Its row buffers are a ring of
    k + 2 = 2r + 3 rows: with box row y next (local row y_l of its frame) the oldest row still
    read is row max(0, y_l - r - 1) of that frame (the row leaving the column sums; a frame
    reads none of the previous frame's), and a row may arrive while it is at most 2r + 2
    rows below it. So row y_in (local q of frame g) waits for box rows up to y_in - r - 1,
    except rows r + 2 .. 2r + 2 of a frame, which only wait for the previous frame's last
    box row (g H). Rows are counted over the stream of frames (frame g's row q is g H +
    q)."""
    g = y_in // image_rows
    q = y_in - g * image_rows
    if radius + 1 < q <= 2 * radius + 2:
        return g * image_rows
    return max(0, y_in - radius - 1)


@register_jitable
def frame_row(row, rows, frames):
    """(frame, row within it) of a row counted over a stream of ``frames`` frames of ``rows``
    rows; past the end: the last frame and ``rows`` (one past its last row) -- how the traces
    show a block's row counters."""
    if row >= frames * rows:
        return frames - 1, rows
    return row // rows, row % rows


@register_jitable
def rows_ready_in_frame(rows_in, image_rows, lookahead, frames):
    """The SVA's box rows ready in the frame whose input rows arrive, ``rows_in`` input rows
    being complete over the stream: max(0, q - r) of q complete rows of that frame,
    every row once the stream is in (:func:`sva_last_input_row`)."""
    if rows_in >= frames * image_rows:
        return image_rows
    return max(0, rows_in % image_rows - lookahead)


# ---- the SVA's pipeline ------------------------------------------------------------------------
# The SVA is a lock-step pipeline (sim.cycle.stages) fed by a slot sequencer (sva_slot): a slot
# enters it (is *issued*) and moves one position per *advancing* cycle; when the word in the
# output register cannot be pushed (the output FIFO is full) the whole pipeline stalls -- no
# position moves, nothing is issued. Its *tick* counts the advancing cycles so far (a stalled
# cycle does not count). The slots that emit are the *words*: word j issued at tick t_j is in
# stage s while t_j + offset_s < tick <= t_j + offset_s + latency_s; it reaches the output
# register at its exit tick x_j = t_{item} + extra + L (sva_exit_item: the median's skew; without
# the median x_j = t_j + L). The readable kernel runs the sequencer slot by slot; the compiled
# engine finds the same ticks in closed form (sva_row_issue_tick, sva_first_word_tick) and the
# cycles with the two rules after them.


@register_jitable
def sva_issue_tick(ready_tick, last_tick, ii):
    """The tick at which the SVA issues a word inside a row: an initiation interval of *ticks*
    after the previous word (a stalled pipeline's II counter stalls with it); ``ready_tick``
    (the pipeline's tick when the row became ready) is below it inside a row."""
    return max(ready_tick, last_tick + ii)


@register_jitable
def sva_row_issue_tick(ready_tick, last_tick, ii, radius, slot_ii):
    """The tick of an output row's first word. A box row is W + r *slots* (:func:`sva_slot`):
    its first r slots read columns 0 .. r - 1 into the box's row window and emit nothing, so
    the first word is slot r. A slot goes a slot II (the matching cost's and box filter's, in
    ticks) after the previous slot, once its input row is complete (``ready_tick``: the tick
    when row y + r became complete); a word goes a pipeline II after the previous word
    (``last_tick``): max(ready + r a, last + max(II, (r + 1) a)), a the slot II."""
    return max(ready_tick + radius * slot_ii, last_tick + max(ii, (radius + 1) * slot_ii))


@register_jitable
def sva_pass_row(p, radius, image_rows):
    """The input row (of its frame) that pass p (0 .. k - 2) adds into the column sums before
    the frame's box row 0: min(max(p - r, 0), H - 1). The sums start as rows -r .. r - 1
    clamped to the frame (row 0 r + 1 times, rows 1 .. r - 1 once); box row 0 adds row
    min(r, H - 1), the k-th."""
    return min(max(p - radius, 0), image_rows - 1)


@register_jitable
def sva_pass_start(row_tick, last_end):
    """The tick of a pass's first slot: once its row is complete (``row_tick``, the pipeline's
    tick then) and the previous pass (or, for the first, the frame start
    :func:`sva_frame_start`) is over (``last_end``). Its W slots go one slot II apart, so it
    ends W a ticks later."""
    return max(row_tick, last_end)


@register_jitable
def sva_frame_start(last_tick, slot_ii, skew, flush_ii):
    """The first tick at which a frame's first slot may go: a slot II after the previous
    frame's last word (``last_tick``; none: a huge negative number), and after the median's S
    flush slots, one a median II f, that follow it (S f ticks: :func:`sva_exit_item`)."""
    return last_tick + slot_ii + skew * flush_ii


@register_jitable
def sva_first_word_tick(ready_tick, last_tick, ii, radius, slot_ii, passes_end):
    """The tick of a frame's first word: :func:`sva_row_issue_tick` of box row 0, and its r
    first slots after the frame's passes (``passes_end``: the tick after the last pass slot's
    slot II; no passes (k = 1): the frame start)."""
    return max(sva_row_issue_tick(ready_tick, last_tick, ii, radius, slot_ii),
               passes_end + radius * slot_ii)


@register_jitable
def sva_exit_item(i, skew, n, flush_ii):
    """Which issue word i of a frame (0 .. N - 1, raster order) leaves with: (item, extra) --
    word i is in the output register L ticks after the tick of the frame's word ``item``
    plus ``extra``. The median (radius m) emits word i when word i + S enters it, S = m W + m
    (its K - 1 row banks hold the rows between): item i + S; the frame's last S words leave
    with S flush slots that follow its last word, one a median II f (``flush_ii``: 1, 2 with
    single-port banks): item N - 1, extra (i + S - N + 1) f. Without the median S = 0: item
    i, extra 0."""
    if i + skew < n:
        return i + skew, 0
    return n - 1, (i + skew - n + 1) * flush_ii


@register_jitable
def sva_frame_ticks(height, width, ii, radius, slot_ii, skew, passes, flush_ii):
    """The ticks an SVA-bound frame takes in a stream (every input row in before its slots
    need it): H rows of W words, (W - 1) II inside a row, a row's first word
    max(II, (r + 1) a) after the previous row's last (:func:`sva_row_issue_tick`) and a
    frame's first word max(II, (r + 1) a + S f + (k - 1) W a) after the previous frame's
    last (the median's flush, S slots one a median II f; the passes:
    :func:`sva_first_word_tick`, :func:`sva_frame_start`)."""
    row_gap = max(ii, (radius + 1) * slot_ii)
    frame_gap = max(ii, (radius + 1) * slot_ii + skew * flush_ii + passes * width * slot_ii)
    return height * (width - 1) * ii + (height - 1) * row_gap + frame_gap


@register_jitable
def sva_slot(i, width, height, radius, passes, first_row):
    """Slot i of a frame's slot sequence (the SVA's sequencer, one slot a slot II at most):
    (input row of the frame it needs complete, the frame-local word it emits or -1). First
    ``passes`` = k - 1 passes of W slots (pass p adds row :func:`sva_pass_row`), then per box
    row y W + r slots: column c < W adds row min(y + r, H - 1), c >= r emits word (y, c - r);
    the last r re-enter column W - 1 and need no new row (-1). The frame's first slot also
    waits for row ``first_row`` (:func:`sva_first_slot_row`)."""
    first = passes * width
    if i < first:
        row = sva_pass_row(i // width, radius, height)
        return (max(row, first_row) if i == 0 else row), -1
    j = i - first
    y = j // (width + radius)
    c = j - y * (width + radius)
    row = min(y + radius, height - 1) if c < width else -1
    if i == 0:
        row = max(row, first_row)
    return row, y * width + c - radius if c >= radius else -1


@register_jitable
def sva_first_slot_row(band_rows, image_rows):
    """The input row a frame's first slot (its first matching costs) waits for besides its
    own: with the hybrid's automatic weights the noise band's last row, min(b, H) - 1 (the
    frame's weights come from the band's statistic, :mod:`sva.hamming.noise`); else row 0
    (``band_rows`` 0)."""
    return max(0, min(band_rows, image_rows) - 1)


@register_jitable
def sva_tick_at(cycle, last_push, last_exit, next_exit):
    """The pipeline's tick at the start of ``cycle`` (advancing cycles before it): the last
    word pushed before ``cycle`` left at cycle ``last_push`` with exit tick ``last_exit``
    (none yet: 0, 0), and the next word's exit tick is ``next_exit`` (never: a huge number);
    after a push the tick advances with every cycle until the next word reaches the output
    register, where it stays while that word waits for a free slot."""
    return min(last_exit + cycle - last_push, next_exit)


@register_jitable
def sva_cycle_of_tick(tick, last_push, last_exit):
    """The cycle in which the pipeline reaches ``tick`` when no word reaches the output
    register between the last push (cycle ``last_push``, exit tick ``last_exit``; none yet:
    0, 0) and that tick: the push cycle plus the ticks in between. A word's arrival at the
    output register is the cycle of its exit tick; the cycle it is issued, of its issue
    tick."""
    return last_push + tick - last_exit


def sink_pattern(sink_stall) -> np.ndarray:
    """The sink's pattern as both engines read it: int64 ``[P, i_0, i_1, ...]``, a period of P
    cycles repeated from cycle 0 and, ascending, the cycles of a period in which the sink may
    pop. ``sink_stall``: None (every cycle), a periodic pattern ``(period, allowed_phase)``
    (only cycles with c % period == phase; period 0: every cycle), or a script -- a 1-D
    sequence of 0/1 (or bool) of length P >= 1 with at least one 1: the sink may pop in cycle
    c iff ``script[c % P]`` (as long as the run: any back-pressure at all; random 0/1: random
    back-pressure). Raises ValueError for anything else."""
    if sink_stall is None:
        return np.array([1, 0], np.int64)
    if isinstance(sink_stall, tuple) and len(sink_stall) == 2:
        period, phase = (int(v) for v in sink_stall)
        if period == 0:
            return np.array([1, 0], np.int64)
        if period < 0 or not 0 <= phase < period:
            raise ValueError(f"sink stall (period, phase) needs period >= 0 and 0 <= phase < "
                             f"period; got {sink_stall!r}")
        return np.array([period, phase], np.int64)
    script = np.asarray(sink_stall)
    if script.ndim != 1 or script.size == 0 or not np.isin(script, (0, 1)).all():
        raise ValueError("a sink script must be a non-empty 1-D sequence of 0/1 (1: the sink "
                         "may pop in that cycle)")
    if not script.any():
        raise ValueError("a sink script must allow at least one cycle (a 1 somewhere)")
    return np.concatenate(([script.size], np.flatnonzero(script))).astype(np.int64)


@register_jitable
def sink_may_pop(cycle, pattern):
    """Whether the sink may pop in ``cycle`` (its :func:`sink_pattern`)."""
    i = cycle % pattern[0]
    k = np.searchsorted(pattern[1:], i)
    return k < len(pattern) - 1 and pattern[1 + k] == i


@register_jitable
def sink_allowed_before(cycle, pattern):
    """Cycles in [0, ``cycle``) in which the sink may pop: whole periods, then those of the
    last period before ``cycle % P``."""
    p = pattern[0]
    return (cycle // p) * (len(pattern) - 1) + np.searchsorted(pattern[1:], cycle % p)


@register_jitable
def sink_allowed_between(lo, hi, pattern):
    """Cycles in [lo, hi) in which the sink may pop."""
    if hi <= lo:
        return 0
    return sink_allowed_before(hi, pattern) - sink_allowed_before(lo, pattern)


@register_jitable
def sink_next_allowed(cycle, pattern):
    """The first cycle >= ``cycle`` in which the sink may pop: the period's first allowed
    cycle at or after ``cycle % P``, else the next period's first."""
    p = pattern[0]
    i = cycle % p
    k = np.searchsorted(pattern[1:], i)
    if k < len(pattern) - 1:
        return cycle - i + pattern[1 + k]
    return cycle - i + p + pattern[1]


def check_int(what: str, value, lo: int, fix: str) -> int:
    """``value`` if it is a whole number of at least ``lo``; else ConfigError naming ``what``
    and ``fix``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{what} must be an integer; got {value!r} ({fix})")
    if value < lo:
        raise ConfigError(f"{what} must be >= {lo}; got {value} ({fix})")
    return value


@dataclass(frozen=True, slots=True)
class ClockDomain:
    """A clock: edge ``k`` (its cycle index) is at ``phase_fs + k * period_fs`` femtoseconds,
    with ``period_fs = round(1e15 / freq_hz)``."""

    name: str
    freq_hz: float
    phase_fs: int = 0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"clock domain name must be a non-empty string; got {self.name!r}")
        f = self.freq_hz
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) or f <= 0:
            raise ConfigError(
                f"clock domain '{self.name}': freq_hz must be a positive number; got {f!r}"
            )
        if period_fs(f) < 1:
            raise ConfigError(
                f"clock domain '{self.name}': freq_hz {f!r} gives a period below 1 fs; "
                "use at most 1e15 Hz"
            )
        check_int(
            f"clock domain '{self.name}': phase_fs", self.phase_fs, 0, "the first edge's time in fs"
        )

    @property
    def period_fs(self) -> int:
        return period_fs(self.freq_hz)

    def edge_fs(self, k: int) -> int:
        """The instant of edge ``k``."""
        return self.phase_fs + k * self.period_fs

    def first_edge_after(self, t_fs: int) -> int:
        """Index of the first edge strictly after the instant ``t_fs``."""
        if t_fs < self.phase_fs:
            return 0
        return (t_fs - self.phase_fs) // self.period_fs + 1


def edges_through(t_fs: int, period_fs: int) -> int:
    """Edges of a clock of ``period_fs`` (its first at t = 0) at or before the instant
    ``t_fs``: t // P + 1 -- the cycles a run counts in each domain when it ends at ``t_fs``
    (the report's ``cycles.total``, the clock energy of a one-frame run)."""
    return t_fs // period_fs + 1
