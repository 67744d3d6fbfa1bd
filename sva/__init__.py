"""Stereo Vision Accelerator (SVA): Hamming cost, box filter, SGM, WTA, sub-pixel, LR check,
median.

A folder per stage -- ``hamming``, ``box``, ``sgm`` (with the path sum), ``wta`` (uniqueness,
sub-pixel), ``lr``, ``median`` -- each holding its naive ``*_ref`` that defines the chip, its
numba row kernels, its timing rule (``timing.py``: the chip plan's stage) and its RTL
(``sva_*.sv``); ``pipeline`` chains the kernels and holds the RTL top; ``geometry`` the facts
every stage shares (lane groups, rows it reads, word widths).
"""
