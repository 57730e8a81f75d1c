"""MIL-STD-1750A arithmetic for the 1750A flight code (IP back end, track processor).

One import point re-exporting:

* :mod:`flightsw.arith.m1750_float` -- 32/48-bit float formats, ``encode32/48``, ``decode32/48``,
  the FA/FS/FM/FD/FLT/FIX/FABS/FNEG/FC instructions (``fa32 ... fc48``), the PI flag constants and
  the per-primitive cycle costs (``OP_MIX``, ``op_mix``, ``op_cycles``, ``CYCLES``);
* :mod:`flightsw.arith.m1750_int` -- 16/32-bit integer add/sub/neg/abs/multiply/divide with the
  standard's overflow rules (``add16 ... div32``, ``INT_OP_MIX``);
* :mod:`flightsw.arith.m1750_math` -- sqrt, exp, ln, sin, cos, atan2 written in 1750A float ops
  (``sqrt32, sqrt48, exp32, ln32, sin32, cos32, sin48, cos48, atan2_32, atan2_48``), their
  stated errors (``MAX_ERROR``) and op mixes (``MATH_OP_MIX``, ``MATH_CYCLES``, ``math_cycles``).

Every public scalar function validates its arguments when called from Python (``ValueError``
naming the value) and can be called under the same name from ``@njit`` code (no validation there),
e.g.::

    from numba import njit
    from flightsw.arith.m1750 import fa32, fm32, CYC_FA32, CYC_FM32

    @njit(cache=True)
    def dot3(a, b):                   # packed 32-bit floats
        acc, pi = 0, 0
        for i in range(3):
            p, f = fm32(a[i], b[i]); pi |= f
            acc, f = fa32(acc, p); pi |= f
        return acc, pi, 3 * (CYC_FM32 + CYC_FA32)

Charging a :class:`flightsw.budget.Ledger`: count the operations in the kernel (or use a routine's
``MATH_CYCLES`` / ``CYCLES`` entry, plain ints usable inside ``@njit``) and
``ledger.charge("tp1750", stage, cycles)``.
"""
from flightsw.arith.m1750_float import *  # noqa: F401,F403
from flightsw.arith.m1750_float import (  # noqa: F401
    CYC_FA32, CYC_FA48, CYC_FD32, CYC_FD48, CYC_FM32, CYC_FM48, CYC_FS32, CYC_FS48,
    DECISION_FA_GUARD_BITS, MASK32, MASK48,
)
from flightsw.arith.m1750_int import *  # noqa: F401,F403
from flightsw.arith.m1750_math import *  # noqa: F401,F403
from flightsw.arith.m1750_math import (  # noqa: F401
    CYC_ATAN2_32, CYC_ATAN2_48, CYC_COS32, CYC_COS48, CYC_EXP32, CYC_LN32, CYC_SIN32, CYC_SIN48,
    CYC_SQRT32, CYC_SQRT48,
)

