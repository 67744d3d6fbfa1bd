"""Waveform traces (VCD, timeline) -- arrives with the trace issue."""
