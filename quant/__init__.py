"""Integer arithmetic of the chip (rounding, saturation) and, later, the int8 quantizer."""
