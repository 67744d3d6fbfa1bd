"""Neural Network Accelerator (NNA): the per-pixel binary descriptors of the chip.

A folder per block: ``census_unit`` (the census transform), ``conv`` (the int8 network whose
last layer's signs are the learned descriptor, and its weight files), ``submodule`` (the line
buffers and MAC arrays that run it: its timing rule and RTL) and ``training`` (training the
networks, needs torch: an application tool on top of the stage). :mod:`nna.descriptor` selects
the descriptor by configuration and :mod:`nna.geometry` states what its window and MAC array
imply for a frame. Both descriptors use the replicate border policy and pack bits LSB first.
"""
