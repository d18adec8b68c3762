"""Numpy's random draws, in compiled code, from the same generator's state.

A trial's policy draws from a `numpy.random.Generator`. Compiled code that serves
deliveries draws from that very generator, through the bit generator's C entry points
(`EntryPoints`), and computes what numpy computes from what they return, so that a draw
made here and one made by numpy in Python come out of one stream, in order, with the
same values:

- `uniform` is `Generator.random()`: the bit generator's double;
- `below` is `Generator.integers(n)` (and `choice` of n items): Lemire's bounded
  integers on 32-bit draws, as numpy's `random_bounded_uint64_fill` does them for a
  range that fits 32 bits, rejection included; nothing is drawn for n = 1.

Both are checked against numpy, draw for draw, by the tests.
"""

from __future__ import annotations

import ctypes
from typing import NamedTuple

import numpy as np

from tavc_cli.kernel import kernel

# the bit generator's entry points, called with the address of its state (as an integer)
NEXT_UINT32 = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_size_t)
NEXT_DOUBLE = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_size_t)

_LOW32 = np.uint64(0xFFFFFFFF)
_SHIFT32 = np.uint64(32)


class EntryPoints(NamedTuple):
    """Where compiled code draws a generator's numbers: its state's address and the two
    functions of its bit generator that read it. The functions are the same for every
    generator of one kind of bit generator; the state lives as long as the generator."""

    state: int
    next_uint32: ctypes._CFuncPtr
    next_double: ctypes._CFuncPtr


def entry_points(rng: np.random.Generator) -> EntryPoints:
    """The entry points of `rng`'s bit generator (numpy's ctypes interface to it)."""
    iface = rng.bit_generator.ctypes
    return EntryPoints(int(iface.state_address),
                       NEXT_UINT32(ctypes.cast(iface.next_uint32, ctypes.c_void_p).value),
                       NEXT_DOUBLE(ctypes.cast(iface.next_double, ctypes.c_void_p).value))


def same_functions(points: list[EntryPoints]) -> bool:
    """Whether every generator draws through the same two functions (one kind of bit
    generator), so that compiled code can be handed one pair for all of them."""
    def address(f):
        return ctypes.cast(f, ctypes.c_void_p).value

    return len({(address(p.next_uint32), address(p.next_double)) for p in points}) <= 1


@kernel
def uniform(next_double, state):
    """`Generator.random()`: a double in [0, 1)."""
    return next_double(state)


@kernel
def below(next_uint32, state, n):
    """`Generator.integers(n)` for 1 <= n < 2**32: an int in [0, n)."""
    rng = np.uint64(n - 1)
    if rng == 0:
        return 0
    if rng == _LOW32:
        return np.int64(next_uint32(state))
    excl = rng + np.uint64(1)
    m = np.uint64(next_uint32(state)) * excl
    leftover = m & _LOW32
    if leftover < excl:
        threshold = (_LOW32 - rng) % excl
        while leftover < threshold:
            m = np.uint64(next_uint32(state)) * excl
            leftover = m & _LOW32
    return np.int64(m >> _SHIFT32)
