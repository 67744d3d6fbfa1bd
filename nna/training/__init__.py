"""Training the learned descriptor (torch, the application layer of the NNA): the settings and
networks (trainconfig), the scenes and batches (traindata, augment), the losses (trainloss), the
run loop (train, trainrun), quantisation-aware fine-tuning (trainqat) and the float model's file
(floatmodel). The chip's own integer network is :mod:`nna.conv`; nothing below imports this."""
