"""The SVA's micro-architecture: its pipeline of stages, each with a latency, an initiation
interval (II) and buffers sized in bits, derived from the configuration.

Every stage evaluates ``L = sva.lanes`` disparities per cycle, so one pixel's D disparities take
``G = ceil(D / L)`` *lane groups* (cycles). Reductions (a popcount, the minimum over disparities,
the sum over paths, a sorting network) are trees of two-input operators, of which
``V = sva.compare_levels`` levels settle in one SVA cycle; a tree of depth ``t`` levels takes
``tree(t) = ceil(t / V)`` cycles (0 for ``t = 0``). ``lg(n) = ceil(log2 n)``.

The stages, in stream order (their docstrings give the formulas the tests check):

======================  =================================  ==================================
stage                   II (cycles per pixel)              latency (cycles)
======================  =================================  ==================================
row buffers' read       1                                  1
hamming cost            max(G, ports)                      G + tree(lg(bits)); hybrid:
                                                           G + tree(lg(max b_k) + 2)
box filter              max(G, ports)                      G + tree(2) + tree(lg(k) + 1)
SGM (per path)          max(left path's recurrence, ports) G + tree(5)
path sum                G                                  tree(lg(paths) + 1)
WTA / uniqueness / sub  G                                  G + tree(lg(L) + [G > 1]) + [uniq]
                                                           + sub
LR check (optional)     G                                  (D - 1) II + 1
median (optional)       max(1, ports)                      tree(depth of the sorting network)
output register         1                                  1
======================  =================================  ==================================

The box filter slides its column sums (an add and a subtract: tree(2)), then sums k of them
and caps the sum (tree(lg(k) + 1)). One lane's SGM step is five levels
(:data:`~sva.sgm.timing.SGM_STEP_LEVELS`); the path sum adds the paths and caps at sum_bits
(lg(paths) + 1);
WTA's minimum is a tree over a group's L lanes and, G > 1, one level folding it into the
earlier groups'. These are the levels of the RTL twin's stages (``sva/<stage>/*.sv``, docs/rtl.md),
which first showed that the plan's earlier G + 2, tree(lg(paths)) and tree(lg(D)) were right
only for V >= 4 or 5.

The SVA's II is the largest stage II. The left-to-right SGM path carries a dependency from one
pixel to the next: pixel p's first lane group needs ``min_d L(p - 1, d)``, the minimum over all
D of the previous pixel's path costs. Its last group leaves the step tree(5) cycles after it
entered (G - 1 after the first), and the minimum is complete ``tree(lg(L) + [G > 1])`` cycles
later (the lanes' minimum, then one level to fold in the running minimum of the earlier
groups). So this path cannot overlap two pixels, and its II is ``G - 1 + tree(5) + tree(lg(L)
+ [G > 1])``. The other paths read the previous *row* and overlap freely.

The defaults (D = 128, L = 128, V = 8) give G = 1 and II = 0 + tree(5) + tree(7) = 2: the
paper's "one disparity every two clock ticks", 1280 x 720 x 2 / 465 MHz = 3.964 ms per frame,
252.3 fps.

SRAM ports (``sva.sram_ports``): every SRAM bank declares its reads and writes per pixel
(:class:`BufferPlan`) -- a median-row bank per row 1 and 1, the column sums and each top SGM
path's previous-row bank G and G (one lane group per access); the descriptor rows are a bank per
row and view, each either the arriving row's (written) or a row a slot reads (the rows entering
and leaving the column sums are two banks): one access a bank, whatever the ports.
With ``1r1w`` banks (a read and a write port) a stage needs max(reads, writes) cycles per pixel
for them, with ``1rw`` (one shared port) reads + writes; a stage's II is the larger of its
compute II and its banks' port cycles, so a single-port SRAM shows its cost: at the defaults
none (the left path's recurrence already leaves the second cycle), with 64 lanes at D = 128 the
SGM's II goes from 3 to 2 G = 4.

The SVA's latency L (a word issued -> it reaches the output register) is the sum of the stage
latencies. Words are the emitting *slots* of the SVA's sequencer (:func:`~sim.cycle.rules.
sva_slot`): a frame's k - 1 passes seed the box filter's column sums, and each box row is W + r
slots, the first r filling the box's row window; every slot passes the row read, the matching
cost and the box filter, one slot II apart (:func:`slot_ii`), the words one II apart. With the
median a word leaves with the word m W + m after it (:func:`~sim.cycle.rules.sva_exit_item`).
The LR check computes the right view's disparities from the same aggregated volume: the right
pixel ``x_r`` takes the best of ``S(x_r + d, d)`` over d, a diagonal through the next D left
pixels. So a left pixel's check waits until the D - 1 pixels after it have been aggregated:
(D - 1) IIs. Its buffers hold the running minimum of D right pixels and the D left words that
wait for them.
"""

from __future__ import annotations

from stereosim.core.config import ChipConfig
from stereosim.core.timing import StagePlan, with_slots
from stereosim.sva.box.timing import box_registers, box_stage
from stereosim.sva.hamming.timing import hamming_registers, hamming_stage
from stereosim.sva.lr.timing import lr_registers, lr_stage
from stereosim.sva.median.timing import median_registers, median_stage
from stereosim.sva.sgm.timing import path_sum_registers, path_sum_stage, sgm_registers, sgm_stage
from stereosim.sva.wta.timing import wta_registers, wta_stage


def sva_stages(cfg: ChipConfig, width: int, parts: tuple[int, ...], word_bits: int,
               cost_max: int) -> tuple[StagePlan, ...]:
    """The SVA's stages for frames ``width`` pixels wide, descriptors of ``parts`` (each
    part's bits), a largest matching cost of ``cost_max`` (:func:`~core.config.widths.
    largest_cost`) and ``word_bits``-bit output words, in stream order (see the module
    docstring), each with its pipeline registers (:func:`~core.timing.with_slots`). Each
    stage's II, latency and storage are its folder's rule (``sva/<stage>/timing.py``); this
    composes them: the row read and the output register, the LR check's latency from the
    pipeline's II."""
    s = cfg.sva
    stages = [
        with_slots(StagePlan("row_read", 1, 1, "II = 1; latency = 1 (the row buffers' read "
                             "register: a slot's descriptors and the right window's new "
                             "column)"),
                   2 * sum(parts), f"a slot's two left descriptors of {sum(parts)} bits (the "
                   "rows entering and leaving the box)"),
        with_slots(hamming_stage(cfg, width, parts), *hamming_registers(cfg, parts, cost_max)),
        with_slots(box_stage(cfg, width, cost_max), *box_registers(cfg, cost_max)),
        with_slots(sgm_stage(cfg, width), *sgm_registers(cfg)),
        with_slots(path_sum_stage(cfg), *path_sum_registers(cfg)),
        with_slots(wta_stage(cfg), *wta_registers(cfg, word_bits)),
    ]
    # the median after the LR check, whose latency is D - 1 of the whole pipeline's IIs
    median = ([with_slots(median_stage(cfg, width, word_bits), *median_registers(word_bits))]
              if s.median > 1 else [])
    ii = max(st.ii for st in stages + median)  # the pipeline's
    if s.lr_check:
        bits, holds, slots = lr_registers(cfg, word_bits)
        stages.append(with_slots(lr_stage(cfg, ii, word_bits), bits, holds, slots=slots))
    stages += median
    stages.append(with_slots(StagePlan("output", 1, 1, "II = 1; latency = 1 (the output "
                                       "register)"), word_bits, f"the {word_bits}-bit word"))
    return tuple(stages)


def stage_offsets(stages: tuple[StagePlan, ...]) -> tuple[int, ...]:
    """Each stage's offset in the pipeline: the latencies of the stages before it. Word j,
    issued at tick t, is in stage s while offset_s < tick - t <= offset_s + latency_s."""
    out = []
    total = 0
    for st in stages:
        out.append(total)
        total += st.latency
    return tuple(out)


def pipeline_ii(stages: tuple[StagePlan, ...]) -> int:
    """The SVA's initiation interval: its slowest stage's."""
    return max(st.ii for st in stages)


def slot_ii(stages: tuple[StagePlan, ...]) -> int:
    """The SVA sequencer's slot II a: every slot (a pass's, a row's first r, a word's) passes
    the row read, the matching cost and the box filter, so slots go the largest of their IIs
    apart (words: the pipeline's II, :func:`pipeline_ii`)."""
    return max(st.ii for st in stages if st.name in ("row_read", "hamming", "box_filter"))


def flush_ii(stages: tuple[StagePlan, ...]) -> int:
    """Ticks between the median's flush slots (after a frame's last word its S slots drain
    the window; :func:`~sim.cycle.rules.sva_exit_item`): the median's II -- 1, or 2 with
    single-port row banks (each flush slot reads them, then the next may) -- and 1 without
    the median."""
    return next((st.ii for st in stages if st.name == "median"), 1)


def pipeline_latency(stages: tuple[StagePlan, ...]) -> int:
    """The SVA's latency (an output row ready -> its first word): the stages' latencies."""
    return sum(st.latency for st in stages)
