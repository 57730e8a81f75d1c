"""Each 1750A primitive's numba overload has its own name (``m1750_float.overload_impl1/2``).

numba names a compiled function's symbol by its module, qualified name, a counter of the process
that compiled it and its argument types. The overloads of the primitives are closures made by one
factory with one argument list (int64 words): with one shared name, two processes could give the
overloads of two different primitives one symbol, and a process loading both cached kernels would
run one body for both (numba issue 10486). Oracles: numba's own mangler
(``numba.core.funcdesc.default_mangler``) with one counter value; Python's names.
"""
import pytest
from numba.core import types
from numba.core.funcdesc import default_mangler

import flightsw.arith.m1750_float as F
import flightsw.arith.m1750_int as I
import flightsw.arith.m1750_math as M

#: kernels of primitives with one argument list for each arity (two int64 words, one)
TWO = [F._fa32_k, F._fm32_k, F._fd32_k, F._fa48_k, F._fd48_k, I._add16_k, I._div32_k]
ONE = [F._fabs32_k, F._fix48_k, F._flt32_k, I._neg16_k, M._sqrt32_k, M._sqrt48_k]


@pytest.mark.parametrize("factory, kernels, argtypes", [
    (F.overload_impl2, TWO, [types.int64, types.int64]),
    (F.overload_impl1, ONE, [types.int64]),
])
def test_same_counter_different_primitives_different_symbols(factory, kernels, argtypes):
    impls = [factory(k)(*argtypes) for k in kernels]
    names = [f.__qualname__ for f in impls]
    assert len(set(names)) == len(kernels), names
    symbols = {default_mangler(f"{f.__module__}.{f.__qualname__}", argtypes, uid=76)
               for f in impls}
    assert len(symbols) == len(kernels)


def test_the_same_primitive_keeps_its_name():
    """Its cache entries and its symbol stay the same from one process to the next."""
    a = F.overload_impl2(F._fa32_k)(types.int64, types.int64)
    b = F.overload_impl2(F._fa32_k)(types.int64, types.int64)
    assert a is not b and a.__qualname__ == b.__qualname__ == "m1750_float__fa32_k_overload"
    assert a.__name__ == a.__qualname__
