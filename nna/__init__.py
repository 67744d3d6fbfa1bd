"""Neural Network Accelerator (NNA): the per-pixel binary descriptors of the chip.

Two descriptors feed the stereo accelerator: the census transform (:mod:`nna.census`) and the
single-layer int8 CNN thresholded on zero (:mod:`nna.conv`), with its weights in
:mod:`nna.weights`. Both use the replicate border policy and pack bits LSB first.
"""

from nna.census import census, census_bits, census_offsets, census_ref
from nna.conv import check_layer, cnn_accumulators, cnn_descriptor, cnn_descriptor_ref
from nna.weights import (
    default_weights,
    load_layer,
    load_weights,
    placeholder_weights,
    save_weights,
)

__all__ = [
    "census",
    "census_bits",
    "census_offsets",
    "census_ref",
    "check_layer",
    "cnn_accumulators",
    "cnn_descriptor",
    "cnn_descriptor_ref",
    "default_weights",
    "load_layer",
    "load_weights",
    "placeholder_weights",
    "save_weights",
]
