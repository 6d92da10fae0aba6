"""Compiled draws for many NumPy generators in one call (imported only when numba is installed).

numba implements ``Generator.standard_normal`` as NumPy's ziggurat method on the bit
generator's own ``next_uint64`` / ``next_double`` functions, reached through the
addresses in ``bit_generator.ctypes`` (the state pointer and the function pointers). A
call of a compiled function with a ``Generator`` argument reads those addresses anew
(attribute look-ups and three ``ctypes.cast`` calls): per member and chunk, that costs
as much as the member's draws (CHANGELOG, issue 13). Here the addresses are read once per call from
Python (:func:`addresses`; the function pointers once per bit-generator type) and
:func:`normals_into_many` rebuilds numba's bit-generator value from them inside the
compiled loop, so one call draws the blocks of all the members of a group: the same
function (``numba.np.random.distributions.random_standard_normal``) on the same state, so
the same numbers as ``rng.standard_normal(out=block)`` and the same generator state after
(``tests/sensors/test_imu_kernel.py``); :func:`uniforms_into_many` likewise for
``rng.random(out=block)`` (the bit generator's ``next_double``, as NumPy's fill).
"""

from __future__ import annotations

import ctypes
from typing import Sequence

import numba
import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic
from numba.np.random.distributions import random_standard_normal
from numba.np.random.generator_core import next_double

__all__ = ["addresses", "normals_into_many", "uniforms_into_many"]

_BITGEN = types.NumPyRandomBitGeneratorType("bit_generator")
_FUNCTIONS: dict[type, np.ndarray] = {}


@intrinsic
def _bit_generator(typingctx, state, next_uint64, next_uint32, next_double):  # type: ignore[no-untyped-def]
    """numba's bit-generator value from the state address and the three function addresses."""
    sig = _BITGEN(types.uintp, types.uintp, types.uintp, types.uintp)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        value = cgutils.create_struct_proxy(_BITGEN)(context, builder)
        value.parent = cgutils.get_null_value(value.parent.type)  # no Python object behind it
        value.state_address = args[0]
        value.state = args[0]
        value.fnptr_next_uint64 = args[1]
        value.fnptr_next_uint32 = args[2]
        value.fnptr_next_double = args[3]
        value.bit_generator = context.get_constant(types.uintp, 0)
        return value._getvalue()

    return sig, codegen


def addresses(rngs: Sequence[np.random.Generator]) -> tuple[np.ndarray, np.ndarray]:
    """The state addresses (B,) of the generators' bit generators and the addresses of
    their ``next_uint64``, ``next_uint32``, ``next_double`` (3,), as unsigned integers.
    The generators must stay referenced while the addresses are used (the caller holds them)."""
    kinds = {type(rng.bit_generator) for rng in rngs}
    if len(kinds) != 1:
        raise ValueError("generators of one bit-generator type per call")
    kind = kinds.pop()
    functions = _FUNCTIONS.get(kind)
    if functions is None:  # static C functions: the same for every instance of the type
        ct = rngs[0].bit_generator.ctypes
        functions = np.array([ctypes.cast(f, ctypes.c_void_p).value for f in (ct.next_uint64, ct.next_uint32,
                                                                               ct.next_double)], dtype=np.uintp)
        _FUNCTIONS[kind] = functions
    states = np.array([rng.bit_generator.ctypes.state_address for rng in rngs], dtype=np.uintp)
    return states, functions


@numba.njit(cache=True, nogil=True)
def normals_into_many(states: np.ndarray, functions: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out[b]`` (C-contiguous (B, n, W)) row by row with standard normals from the
    bit generator at ``states[b]``, as ``Generator.standard_normal(out=out[b])``."""
    for b in range(out.shape[0]):
        bitgen = _bit_generator(states[b], functions[0], functions[1], functions[2])  # type: ignore[call-arg, var-annotated]
        for k in range(out.shape[1]):
            for c in range(out.shape[2]):
                out[b, k, c] = random_standard_normal(bitgen)


@numba.njit(cache=True, nogil=True)
def uniforms_into_many(states: np.ndarray, functions: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out[b]`` (C-contiguous (B, n, W)) with uniforms on [0, 1) from the bit
    generator at ``states[b]``, as ``Generator.random(out=out[b])`` (its ``next_double``)."""
    for b in range(out.shape[0]):
        bitgen = _bit_generator(states[b], functions[0], functions[1], functions[2])  # type: ignore[call-arg, var-annotated]
        for k in range(out.shape[1]):
            for c in range(out.shape[2]):
                out[b, k, c] = next_double(bitgen)
