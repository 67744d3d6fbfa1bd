"""The chip's integer rounding, defined once.

The naive references and the numba kernels both import :func:`div_round_half_up`, so the
sub-pixel rounding cannot drift between them; it is numba-compiled and also callable from plain
Python with Python ints. (Saturation is a plain ``min(value, 2^bits - 1)`` wherever it occurs,
stated in each stage's docstring; the int8 multiply-shift lives in :mod:`quant.intconv`.)
"""

from stereosim.core.kernel_cache import njit


@njit(cache=True, inline="always")
def div_round_half_up(num, den):
    """round(num / den) with ties towards +inf, for den > 0, using floor division only.

    floor((2*num + den) / (2*den)) -- the form a divider with a rounding constant computes, and
    identical in Python and numba (both floor towards -inf).
    """
    return (2 * num + den) // (2 * den)
