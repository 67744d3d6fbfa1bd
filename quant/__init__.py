"""Integer arithmetic of the chip and the int8 quantizer.

Layers (see the import contracts in pyproject.toml): :mod:`quant.fixedpoint` (rounding),
:mod:`quant.intconv` (integer conv, requantisation), :mod:`quant.distances` and
:mod:`quant.artifact` (the int8 artifact format) are the chip's integer arithmetic, below the
stages; :mod:`quant.quantizer` (the scale search of ``stereosim quantize``) is an application
tool on top of them.
"""
