"""Explicit vector loops over the disparities, for the SVA's per-pixel d-loops.

numba vectorises a per-pixel d-loop that reads some rows and writes others, but only behind
runtime checks that no written row overlaps a read one, run at every pixel: for the SGM's
loop a long run of scalar compares a pixel, more than the loop's own work. The SGM's rows
never overlap (:func:`sva.sgm.new_path_buffers` lays them out so), so its loop is written out
in <LANES x i16> vectors instead (llvmlite IR in a numba ``intrinsic``, as sva/cost.py emits
``llvm.ctpop``): :class:`VectorCode` builds such loops, one chunk of LANES disparities a step,
and the caller runs the last D mod LANES disparities in its scalar loop. The vectors wrap like
uint16 and every operation is the scalar loop's, so the results are the same bit for bit
(tests/sva/test_sgm.py holds the kernel against the naive reference). The box filter's and
the right disparity's d-loops written the same way were no faster in the fused stream
(`python benchmarks/bench_sva_kernels.py --repeat 5`, 2026-12-06: 0.120 s against 0.097 s),
so they stay numba's.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils

# uint16 lanes of one vector (512 bits)
LANES = 32


def uint16_rows(*arrays) -> bool:
    """Whether every numba type given is a contiguous 1-D uint16 array (what the vector loops
    read and write)."""
    return all(isinstance(a, types.Array) and a.ndim == 1 and a.layout == "C"
               and a.dtype == types.uint16 for a in arrays)


class VectorCode:
    """Helpers of an intrinsic's code generator: uint16 vectors of :data:`LANES` lanes."""

    def __init__(self, context, builder):
        self.context, self.builder = context, builder
        self.lane = ir.IntType(16)
        self.vec = ir.VectorType(self.lane, LANES)

    def data(self, ty, value):
        """The data pointer of an array argument (its numba type ``ty``)."""
        return self.context.make_array(ty)(self.context, self.builder, value).data

    def splat(self, value):
        """A vector of LANES copies of the uint16 ``value``."""
        b = self.builder
        vec = b.insert_element(ir.Constant(self.vec, ir.Undefined), value,
                               ir.Constant(ir.IntType(32), 0))
        return b.shuffle_vector(vec, ir.Constant(self.vec, ir.Undefined),
                                ir.Constant(ir.VectorType(ir.IntType(32), LANES), [0] * LANES))

    def full(self, value: int):
        return ir.Constant(self.vec, [value] * LANES)

    def umin(self, a, b):
        return self.builder.select(self.builder.icmp_unsigned("<", a, b), a, b)

    def load(self, ptr, d, plus: int = 0):
        """The LANES uint16 at ptr[d + plus ...]."""
        return self.builder.load(self._at(ptr, d, plus), align=2)

    def store(self, value, ptr, d, plus: int = 0):
        self.builder.store(value, self._at(ptr, d, plus), align=2)

    def _at(self, ptr, d, plus):
        b = self.builder
        if plus:
            d = b.add(d, ir.Constant(d.type, plus))
        return b.bitcast(b.gep(ptr, [d]), self.vec.as_pointer())

    def chunks(self, count):
        """``with code.chunks(n) as d:`` the body once per chunk, d = its first disparity."""
        return _Chunks(self, count)

    def reduce_min(self, vec):
        """The minimum of the lanes (uint16)."""
        fn = cgutils.get_or_insert_function(
            self.builder.module, ir.FunctionType(self.lane, [self.vec]),
            f"llvm.vector.reduce.umin.v{LANES}i16")
        return self.builder.call(fn, [vec])


class _Chunks:
    def __init__(self, code: VectorCode, count):
        self.code, self.count = code, count

    def __enter__(self):
        self._loop = cgutils.for_range(self.code.builder, self.count)
        index = self._loop.__enter__().index
        return self.code.builder.mul(index, ir.Constant(index.type, LANES))

    def __exit__(self, *exc):
        return self._loop.__exit__(*exc)
