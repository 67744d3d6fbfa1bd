"""The FIFO block: a clocked FIFO of stated depth, latency and synchroniser, in one domain or two.
It owns the plan's FIFO rule (``FifoPlan.data_edges`` / ``space_edges``): push k waits until
pop k - depth is seen, an item is visible data_edges consumer edges on (:mod:`.rule`). Beside
it: its readable twin (:mod:`.readable`: the clocked :class:`~.readable.Fifo`), what the
compiled engine's FIFO traces (:mod:`.compiled`) and the statistics every engine reports
(:mod:`.counts`)."""
