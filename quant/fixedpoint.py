"""The chip's integer arithmetic: saturation and rounding, defined once.

Every other layer (naive references, numba kernels, clocked blocks) imports these, so the
definition of "saturating add" or "round half up" cannot drift between them. All functions are
numba-compiled and also callable from plain Python with Python ints.
"""

from numba import njit


def max_unsigned(bits: int) -> int:
    """Largest value an unsigned register of ``bits`` bits holds (the saturation ceiling)."""
    return (1 << bits) - 1


@njit(cache=True, inline="always")
def sat_add(a, b, cap):
    """Unsigned saturating add: min(a + b, cap)."""
    s = a + b
    return cap if s > cap else s


@njit(cache=True, inline="always")
def saturate(a, cap):
    """Clamp a non-negative value to the register ceiling ``cap``."""
    return cap if a > cap else a


@njit(cache=True, inline="always")
def div_round_half_up(num, den):
    """round(num / den) with ties towards +inf, for den > 0, using floor division only.

    floor((2*num + den) / (2*den)) -- the form a divider with a rounding constant computes, and
    identical in Python and numba (both floor towards -inf).
    """
    return (2 * num + den) // (2 * den)
