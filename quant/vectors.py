"""Explicit vector code in a numba ``intrinsic``: the helpers its code generator uses.

Where numba's own loop is not what the kernel needs, a kernel emits its inner loop as llvmlite
IR over LLVM vectors: the NNA's single layer by byte dot products (``vpdpbusd``,
:mod:`quant.vnni`), the SGM's d-loop (:mod:`sva.sgm.sgm`), which numba vectorised too but behind
runtime checks, at every pixel, that no written row overlaps a read one -- a long run of scalar
compares, more than the loop's own work -- and the 5 x 5 median (:mod:`sva.median.median`), whose 25
values a pixel numba's own loop could not keep in registers. :class:`VectorCode` holds what
they build: an array argument's data pointer, a vector loaded or stored at an element offset,
a scalar splat over the lanes, an unsigned compare, minimum and maximum, loads and stores
under a mask of lanes, a loop over chunks and the lanes' minimum; :func:`aligned_full` the
arrays whose rows such loops read as aligned vectors. The vectors wrap like the scalar
integers they stand for, so a kernel written with them computes what its scalar loop
computes, bit for bit (each kernel's tests hold it to its reference).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils

#: the alignment of a vector of 512 bits: one such load or store touches one cache line
VECTOR_BYTES = 64
#: uint16 lanes of one such vector (the SGM's disparities a step, the median's pixels a step)
U16_LANES = VECTOR_BYTES // 2


def aligned_full(shape, dtype, fill, first: int = 0) -> np.ndarray:
    """A C-contiguous array of ``shape`` filled with ``fill`` whose element ``first`` (flat
    index) lies on a :data:`VECTOR_BYTES` boundary: rows whose length is a multiple of a
    vector's elements then start every vector of a kernel's chunk loop on a cache line."""
    dtype = np.dtype(dtype)
    per = VECTOR_BYTES // dtype.itemsize
    n = int(np.prod(shape))
    flat = np.full(n + per, fill, dtype)
    skip = -(flat.ctypes.data // dtype.itemsize + first) % per
    return flat[skip:skip + n].reshape(shape)


def contiguous_rows(dtype, *arrays) -> bool:
    """Whether every numba type given is a contiguous 1-D array of ``dtype`` (what a vector
    loop may read and write at element offsets)."""
    return all(isinstance(a, types.Array) and a.ndim == 1 and a.layout == "C"
               and a.dtype == dtype for a in arrays)


class VectorCode:
    """Helpers of an intrinsic's code generator for vectors of ``lanes`` integers of
    ``bits`` bits."""

    def __init__(self, context, builder, bits: int, lanes: int):
        self.context, self.builder = context, builder
        self.lanes = lanes
        self.lane = ir.IntType(bits)
        self.vec = ir.VectorType(self.lane, lanes)
        self.align = bits // 8

    def data(self, ty, value):
        """The data pointer of an array argument (its numba type ``ty``)."""
        return self.context.make_array(ty)(self.context, self.builder, value).data

    def splat(self, value):
        """A vector holding the scalar ``value`` in every lane."""
        b = self.builder
        vec = b.insert_element(ir.Constant(self.vec, ir.Undefined), value,
                               ir.Constant(ir.IntType(32), 0))
        return b.shuffle_vector(vec, ir.Constant(self.vec, ir.Undefined),
                                ir.Constant(ir.VectorType(ir.IntType(32), self.lanes),
                                            [0] * self.lanes))

    def full(self, value: int):
        """A constant vector holding ``value`` in every lane."""
        return ir.Constant(self.vec, [value] * self.lanes)

    def umin(self, a, b):
        return self.builder.select(self.ult(a, b), a, b)

    def umax(self, a, b):
        return self.builder.select(self.ult(a, b), b, a)

    def ult(self, a, b):
        """Lane by lane a < b, unsigned (a vector of i1)."""
        return self.builder.icmp_unsigned("<", a, b)

    def index(self, i):
        """The lanes' element indices i, i + 1, ..., i + lanes - 1 (wrapping like the lane
        type), ``i`` a scalar integer at least as wide as a lane."""
        b = self.builder
        if i.type.width > self.lane.width:
            i = b.trunc(i, self.lane)
        return b.add(self.splat(i), ir.Constant(self.vec, list(range(self.lanes))))

    def lanes_below(self, n):
        """The mask of the lanes 0 .. n - 1 (``n`` a scalar of the lane type, <= lanes)."""
        return self.ult(ir.Constant(self.vec, list(range(self.lanes))), self.splat(n))

    def _masked(self, op: str):
        ptr = self.vec.as_pointer()
        mask = ir.VectorType(ir.IntType(1), self.lanes)
        suffix = f"v{self.lanes}i{self.lane.width}.p0"
        if op == "load":
            fnty = ir.FunctionType(self.vec, [ptr, ir.IntType(32), mask, self.vec])
        else:
            fnty = ir.FunctionType(ir.VoidType(), [self.vec, ptr, ir.IntType(32), mask])
        return cgutils.get_or_insert_function(self.builder.module, fnty,
                                              f"llvm.masked.{op}.{suffix}")

    def load_masked(self, ptr, i, mask, plus: int = 0, other: int = 0):
        """The lanes at ptr[i + plus ...] where ``mask`` is set, ``other`` in the rest; the
        masked-off lanes' memory is not touched (AVX-512 suppresses their faults)."""
        return self.builder.call(self._masked("load"), [
            self.at(ptr, i, plus), ir.Constant(ir.IntType(32), self.align), mask,
            self.full(other)])

    def store_masked(self, value, ptr, i, mask, plus: int = 0):
        """Store the lanes of ``value`` where ``mask`` is set; the others' memory is not
        touched."""
        self.builder.call(self._masked("store"), [
            value, self.at(ptr, i, plus), ir.Constant(ir.IntType(32), self.align), mask])

    def at(self, ptr, i, plus: int = 0):
        """A vector pointer to the lanes at ptr[i + plus ...]."""
        b = self.builder
        if plus:
            i = b.add(i, ir.Constant(i.type, plus))
        return b.bitcast(b.gep(ptr, [i]), self.vec.as_pointer())

    def load(self, ptr, i, plus: int = 0):
        """The lanes at ptr[i + plus ...]."""
        return self.builder.load(self.at(ptr, i, plus), align=self.align)

    def store(self, value, ptr, i, plus: int = 0):
        self.builder.store(value, self.at(ptr, i, plus), align=self.align)

    def chunks(self, count):
        """``with code.chunks(n) as i:`` the body once per chunk of ``lanes`` elements, i the
        chunk's first element."""
        return _Chunks(self, count)

    def reduce_min(self, vec):
        """The unsigned minimum of the lanes."""
        fn = cgutils.get_or_insert_function(
            self.builder.module, ir.FunctionType(self.lane, [self.vec]),
            f"llvm.vector.reduce.umin.v{self.lanes}i{self.lane.width}")
        return self.builder.call(fn, [vec])


class _Chunks:
    def __init__(self, code: VectorCode, count):
        self.code, self.count = code, count

    def __enter__(self):
        self._loop = cgutils.for_range(self.code.builder, self.count)
        index = self._loop.__enter__().index
        return self.code.builder.mul(index, ir.Constant(index.type, self.code.lanes))

    def __exit__(self, *exc):
        return self._loop.__exit__(*exc)
