"""quant.vectors: the arrays whose rows the vector kernels read aligned."""

import numpy as np
import pytest

from stereosim.quant.vectors import VECTOR_BYTES, aligned_full


@pytest.mark.parametrize(("shape", "dtype", "first"), [
    ((3, 130), np.uint16, 1), ((1280, 128), np.uint16, 0), ((7,), np.int32, 5),
    ((2, 3, 4), np.uint8, 0)])
def test_the_named_element_lies_on_a_vector_boundary(shape, dtype, first):
    a = aligned_full(shape, dtype, 7, first=first)
    assert a.shape == shape and a.dtype == dtype and a.flags.c_contiguous
    assert (a == 7).all()
    assert (a.ctypes.data + first * a.itemsize) % VECTOR_BYTES == 0
    a[...] = 1  # its own memory: writable, no view of a shared buffer
    assert a.sum() == a.size
