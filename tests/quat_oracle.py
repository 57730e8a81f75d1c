"""Float64 quaternion oracles the track-processor tests compare the 1750A code with (scalar-first
quaternions ``(w, x, y, z)``, Hamilton product)."""
import numpy as np


def qmul(a, b):
    """Hamilton product ``a * b`` of two quaternions, float64 [4]."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0])


def dcm(q):
    """The rotation matrix float64 [3, 3] of a unit quaternion (body -> reference columns)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
