"""The FIFO block: a clocked FIFO of stated depth, latency and synchroniser, in one domain or two.
It owns the plan's FIFO rule (``FifoPlan.data_edges`` / ``space_edges``): push k waits until
pop k - depth is seen, an item is visible data_edges consumer edges on (:mod:`.rule`)."""
