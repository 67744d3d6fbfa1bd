"""The SVA as one block: the functional stream of its stages (pipeline: the fused row kernels
the cycle model's SVA block calls) and the RTL top (sva_top.sv: the row buffers, the
sequencer and the stages in lock step). Its stages' timing rules are in their folders; the
cycle model composes them (:func:`sim.cycle.stages.sva_stages`)."""
