"""The row windows on the compiled engine: the most rows each NNA tile's line buffer and the
SVA's row buffers held, and when (:func:`sim.cycle.buffers.window_peaks`, the same arithmetic,
which the readable kernel applies to its blocks' row instants), walked behind the streams over
the row instants the blocks' loops note in ``Net.occ`` (``TILE.occ_in`` / ``occ_out``,
``IDS.occ_sva_in`` / ``occ_sva_out``).
"""

from __future__ import annotations

from stereosim.core.kernel_cache import njit_borrowing
from stereosim.sim.cycle.compiled.layout import ERR_RING


@njit_borrowing(cache=True)
def walk_windows(net, final):
    """Settle the row windows' peaks (:func:`sim.cycle.buffers.window_peaks`, the same
    arithmetic) for the input rows whose instant is known and before which every output row
    done is known: when input row r starts to enter, with y output rows done before that cycle
    -- the next is row y % out_rows of frame y // out_rows -- the window holds r - oldest + 1
    rows, oldest = min(frame in_rows + max(0, row + offset), r). The row instants live in the
    rings of ``Net.occ``; a walk that fell a ring behind sets the ring error."""
    prm = net.prm[0]
    state = net.state[0]
    occ = net.occ
    mask = occ.shape[1] - 1
    for i in range(net.win.shape[0]):
        wn = net.win[i]
        n_in = (net.streams[wn.in_stream].count + wn.in_width - 1) // wn.in_width
        n_out = net.streams[wn.out_stream].count // wn.out_width
        out_total = prm.frames * wn.out_rows
        slot, offset, in_rows, out_rows = wn.slot, wn.offset, wn.in_rows, wn.out_rows
        r, y, peak, at = wn.row, wn.done, wn.peak, wn.at
        if n_in - r > mask or n_out - y > mask:
            state.error = ERR_RING
        while r < n_in:
            t = occ[slot, r & mask]
            while y < n_out and occ[wn.out_slot, y & mask] < t:
                y += 1
            if y == n_out and n_out < out_total and not final:
                break  # an output row not yet known may be done before t
            fr = y // out_rows
            oldest = min(fr * in_rows + max(0, y - fr * out_rows + offset), r)
            if r - oldest + 1 > peak:
                peak, at = r - oldest + 1, t
            r += 1
        wn.row, wn.done, wn.peak, wn.at = r, y, peak, at

