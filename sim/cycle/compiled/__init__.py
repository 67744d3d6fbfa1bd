"""The compiled cycle engine: the readable kernel's results from the event streams of a frame
(docs/compiled-engine.md). :func:`sim.cycle.compiled.run.run_compiled` is its entry."""
