"""Quaternion and rotation helpers (scalar-first ``(w, x, y, z)``, Hamilton product).

A quaternion ``q`` rotates frame-A vectors into frame B: ``v_B = R(q) @ v_A`` (here mostly body -> ECI).
Composition: ``q_img_to_eci = q_mul(q_body_to_eci, q_img_to_body)``.
"""
from __future__ import annotations

import math

import numpy as np


def _is_f64(v):
    return type(v) is np.ndarray and v.dtype == np.float64 and v.ndim == 1


def _f64_items(v):
    """Python floats of a float64 ndarray (the same IEEE double arithmetic as numpy's float64
    scalars, without their overhead); anything else unchanged."""
    return v.tolist() if _is_f64(v) else v


def q_mul(a, b):
    """Hamilton product ``a * b`` (apply b first, then a)."""
    if _is_f64(a) and _is_f64(b):       # Python floats: the same IEEE double arithmetic, faster
        a, b = a.tolist(), b.tolist()
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def q_conj(q):
    v = _f64_items(q)
    return np.array([v[0], -v[1], -v[2], -v[3]])


def q_normalize(q):
    """Unit quaternion (float64 (4,)) with scalar part >= 0; ValueError for a zero or non-finite one."""
    q = np.asarray(q, dtype=float)
    if q.shape != (4,):
        n = math.sqrt(float(q @ q))
        if not n > 0.0:
            raise ValueError("zero or non-finite quaternion")
        q = q / n
        return q if q[0] >= 0.0 else -q
    w, x, y, z = q.tolist()              # Python floats: the same IEEE double arithmetic, faster
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not n > 0.0 or n == math.inf:
        raise ValueError("zero or non-finite quaternion")
    if w / n >= 0.0:
        return np.array([w / n, x / n, y / n, z / n])
    return np.array([-(w / n), -(x / n), -(y / n), -(z / n)])


def q_to_dcm(q):
    """3x3 rotation matrix R with ``v_out = R @ v_in``."""
    w, x, y, z = _f64_items(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def dcm_to_q(m):
    """Inverse of :func:`q_to_dcm` (Shepperd's method), scalar part >= 0."""
    m = np.asarray(m, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    cands = [tr, m[0, 0], m[1, 1], m[2, 2]]
    i = int(np.argmax(cands))
    if i == 0:
        w = 0.5 * math.sqrt(1.0 + tr)
        q = [w, (m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), (m[1, 0] - m[0, 1]) / (4 * w)]
    elif i == 1:
        x = 0.5 * math.sqrt(1.0 + 2 * m[0, 0] - tr)
        q = [(m[2, 1] - m[1, 2]) / (4 * x), x, (m[0, 1] + m[1, 0]) / (4 * x), (m[0, 2] + m[2, 0]) / (4 * x)]
    elif i == 2:
        y = 0.5 * math.sqrt(1.0 + 2 * m[1, 1] - tr)
        q = [(m[0, 2] - m[2, 0]) / (4 * y), (m[0, 1] + m[1, 0]) / (4 * y), y, (m[1, 2] + m[2, 1]) / (4 * y)]
    else:
        z = 0.5 * math.sqrt(1.0 + 2 * m[2, 2] - tr)
        q = [(m[1, 0] - m[0, 1]) / (4 * z), (m[0, 2] + m[2, 0]) / (4 * z), (m[1, 2] + m[2, 1]) / (4 * z), z]
    return q_normalize(np.array(q))


def q_from_rotvec(phi):
    """Quaternion of a rotation by vector ``phi`` (axis * angle, rad)."""
    phi = np.asarray(phi, dtype=float)
    a = math.sqrt(float(phi @ phi))
    if a < 1e-12:
        return q_normalize(np.array([1.0, 0.5 * phi[0], 0.5 * phi[1], 0.5 * phi[2]]))
    s = math.sin(0.5 * a) / a
    return np.array([math.cos(0.5 * a), s * phi[0], s * phi[1], s * phi[2]])


def q_to_rotvec(q):
    """Rotation vector (axis * angle, rad, float64 (3,)) of a quaternion (normalised first)."""
    w, x, y, z = q_normalize(q).tolist()
    s = math.sqrt(x * x + y * y + z * z)
    g = 2.0 if s < 1e-12 else 2.0 * math.atan2(s, w) / s
    return np.array([x * g, y * g, z * g])


def q_rate(q_new, q_old, dt: float):
    """Angular velocity (rad/s, float64 (3,), in the frame the quaternions rotate into, e.g. ECI)
    that takes ``q_old`` to ``q_new`` in ``dt`` s: ``q_to_rotvec(q_new * conj(q_old)) / dt``, on
    Python floats (it is on the per-frame path)."""
    aw, ax, ay, az = np.asarray(q_new, float).tolist()
    bw, bx, by, bz = np.asarray(q_old, float).tolist()
    bx, by, bz = -bx, -by, -bz
    w = aw * bw - ax * bx - ay * by - az * bz
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not n > 0.0 or n == math.inf:
        raise ValueError("zero or non-finite quaternion")
    if w / n >= 0.0:
        w, x, y, z = w / n, x / n, y / n, z / n
    else:
        w, x, y, z = -(w / n), -(x / n), -(y / n), -(z / n)
    s = math.sqrt(x * x + y * y + z * z)
    g = 2.0 if s < 1e-12 else 2.0 * math.atan2(s, w) / s
    return np.array([x * g / dt, y * g / dt, z * g / dt])


def q_pointing(boresight_eci, up_eci=(0.0, 0.0, 1.0), roll=0.0):
    """Body->ECI quaternion putting body +X on ``boresight_eci``.

    Body +Z is the component of ``up_eci`` perpendicular to the boresight (falling back to ECI +X
    when they are parallel), then the body is rolled by ``roll`` rad about +X.
    """
    b = np.asarray(boresight_eci, dtype=float)
    b = b / np.linalg.norm(b)
    u = np.asarray(up_eci, dtype=float)
    z = u - (u @ b) * b
    if np.linalg.norm(z) < 1e-9:
        u = np.array([1.0, 0.0, 0.0]) if abs(b[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        z = u - (u @ b) * b
    z = z / np.linalg.norm(z)
    y = np.array([z[1] * b[2] - z[2] * b[1], z[2] * b[0] - z[0] * b[2], z[0] * b[1] - z[1] * b[0]])
    m = np.empty((3, 3))
    m[:, 0], m[:, 1], m[:, 2] = b, y, z
    q = dcm_to_q(m)
    if roll:
        q = q_mul(q, q_from_rotvec([roll, 0.0, 0.0]))
    return q_normalize(q)


def radec_to_vec(ra, dec):
    cd = math.cos(dec)
    return np.array([cd * math.cos(ra), cd * math.sin(ra), math.sin(dec)])
