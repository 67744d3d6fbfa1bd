"""Stereo Vision Accelerator (SVA): Hamming cost, box filter, SGM, WTA, sub-pixel, LR check.

One module per stage (``cost``, ``aggregation``, ``sgm``, ``wta``, ``lr_check``, ``median``), each
with a naive ``*_ref`` that defines the chip and numba row kernels; ``pipeline`` chains them.
"""
