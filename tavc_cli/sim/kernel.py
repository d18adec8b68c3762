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

from numba import njit

kernel = partial(njit, cache=True, _nrt=False)
