"""Integer arithmetic of the chip (rounding, saturation, multiply-shift) and the int8 quantizer."""

from quant.distances import DISTANCES, get_distance
from quant.intconv import check_network, int_forward, int_forward_ref, mul_shift, requantize
from quant.quantizer import (
    FloatModel,
    QuantizedModel,
    QuantizerConfig,
    float_forward,
    load_quantized,
    quantize,
    save_quantized,
    to_nna_weights,
)

__all__ = [
    "DISTANCES",
    "FloatModel",
    "QuantizedModel",
    "QuantizerConfig",
    "check_network",
    "float_forward",
    "get_distance",
    "int_forward",
    "int_forward_ref",
    "load_quantized",
    "mul_shift",
    "quantize",
    "requantize",
    "save_quantized",
    "to_nna_weights",
]
