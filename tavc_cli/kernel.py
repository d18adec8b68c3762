"""How the simulation's compiled kernels are compiled.

`@kernel` is numba's `njit`, cached on disk, and without numba's reference counting of arrays:
the kernels never allocate, they only read and write arrays (and bundles of arrays) that their
Python caller owns and keeps alive. With counting on, every call of one kernel from another
would increment and then decrement an atomic count for each array it is passed, two dozen of
them for the behaviours; that was about a twentieth of a tick's instructions, and atomic
operations are slow ones. Allocating inside a `@kernel` fails to compile, which is the point.
"""

from __future__ import annotations

import os
import sys
from functools import partial
from pathlib import Path

from tavc_cli import compiled_code_cache, compiled_code_home


def use_compiled_code_cache() -> None:
    """Point numba's cache of compiled kernels at this version's folder (`compiled_code_cache`),
    before any kernel is compiled or loaded.

    numba checks a cached function against its own file only. A kernel that inlined a
    function, or froze a constant, from another file would otherwise be loaded from the
    cache unchanged after that file changed, and run the old code. With one folder per
    version of the source, any change compiles everything afresh. A NUMBA_CACHE_DIR set
    by the user is left alone.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    root = Path(__file__).resolve().parent
    where = str(compiled_code_cache(root, compiled_code_home(root)))
    os.environ["NUMBA_CACHE_DIR"] = where
    if "numba.core.config" in sys.modules:  # numba came first and has read its settings already
        sys.modules["numba.core.config"].CACHE_DIR = where


use_compiled_code_cache()  # the kernels below are the first numba compiles: their cache is decided here

from llvmlite import ir  # noqa: E402 - numba reads its cache folder when it loads
from numba import njit, types  # noqa: E402
from numba.core.extending import intrinsic  # noqa: E402

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
