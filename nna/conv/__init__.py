"""The NNA's learned descriptor: the signs of an int8 network's last layer (conv: the reference
and the fast paths over :mod:`quant.intconv`) and its weight files (weights). The MAC array that
computes it on the chip, and its timing, is :mod:`nna.submodule`."""
