"""How the simulation's compiled kernels are compiled.

`@kernel` is numba's `njit`, cached on disk, and without numba's reference counting of arrays:
the kernels never allocate, they only read and write arrays (and bundles of arrays) that their
Python caller owns and keeps alive. With counting on, every call of one kernel from another
would increment and then decrement an atomic count for each array it is passed, two dozen of
them for the behaviours; that was about a twentieth of a tick's instructions, and atomic
operations are slow ones. Allocating inside a `@kernel` fails to compile, which is the point.
"""

from __future__ import annotations

from functools import partial

from llvmlite import ir
from numba import njit, types
from numba.core.extending import intrinsic

kernel = partial(njit, cache=True, _nrt=False)


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c with one rounding, in compiled code (LLVM's fma: the processor's fused
    multiply-add, or the C library's fma where there is none). Takes float64s."""
    if not all(isinstance(x, types.Float) for x in (a, b, c)):
        return None

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        a, b, c = (context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args, strict=True))
        fn = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3))
        return builder.call(fn, [a, b, c])

    return types.float64(a, b, c), codegen
