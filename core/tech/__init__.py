"""The technology model: what logic, SRAM and DRAM cost at a process node, every figure cited.

- :mod:`.nodes`: one :class:`~.nodes.Node` per node (130, 45 and 7 nm) -- gate-equivalent area,
  leakage and toggle energy, flip-flop area, leakage and clock energy, gate delay for fmax,
  DRAM energy per bit -- read from the open libraries' liberty files (``data/*.json`` keeps
  the figures with repository, commit and path); ``node(name)`` looks one up.
- :mod:`.sram`: ``sram_macro(node, bits, word_bits, ports)`` -- area, energy per access and
  leakage, power laws fitted to the node's published macro table; a second port priced by the
  130 nm library's 1rw / 1rw1r pairs.
- :mod:`.vf`: clock frequency (alpha-power law), dynamic energy and leakage against the supply.
- :mod:`.fits`: the least-squares fits, each to its data points.

``python -m stereosim.core.tech`` prints every figure, fit and source (docs/energy.md, "The
technology model"). The bottom layer: only the standard library, numpy and core.errors.
"""
