"""Waveform traces of the cycle model: VCD for GTKWave and Surfer, GTKWave save files, a
Perfetto timeline and waveform pictures, all from one engine-agnostic columnar log.

- :mod:`traces.log` -- :class:`~traces.log.TraceLog` (what the engines produce), validation,
  :class:`~traces.log.TraceRecorder` (the readable engine's trace hook), ``select`` / ``window``;
- :mod:`traces.vcd` -- the fast VCD writer, the pyvcd reference writer, size estimate and bound;
- :mod:`traces.gtkw` -- a GTKWave save file: zoomed to the window, unique aliases, one group per
  block, status names through a translate filter;
- :mod:`traces.window` -- the one window syntax of ``run --trace-window`` and ``wave --window``;
- :mod:`traces.timeline` -- Chrome/Perfetto trace-event JSON (busy/stall spans, FIFO counters);
- :mod:`traces.vcdread` and :mod:`traces.dumpread` -- read a VCD, or an FST (pywellen), back;
- :mod:`traces.wave` -- draw a dump with matplotlib: statuses by name, counts in decimal;
- :mod:`traces.cli` -- the ``stereosim wave`` subcommand.

``docs/traces.md`` describes the format, the signal names and the viewers.
"""
