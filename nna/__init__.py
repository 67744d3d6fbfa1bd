"""Neural Network Accelerator (NNA): the per-pixel binary descriptors of the chip.

Two descriptors feed the stereo accelerator: the census transform (:mod:`nna.census`) and the
single-layer int8 CNN thresholded on zero (:mod:`nna.conv`), with its weights in
:mod:`nna.weights`; :mod:`nna.descriptor` selects one by configuration and :mod:`nna.geometry`
states what its window and MAC array imply for a frame. Both use the replicate border policy and
pack bits LSB first. :mod:`nna.train` (training the networks, needs torch) is an application
tool on top of the stage.
"""
