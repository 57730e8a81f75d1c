"""Messages between the flight subsystems.

Conventions shared by every message (``shared/DESIGN.md``):

* Quaternions are scalar-first ``(w, x, y, z)`` and rotate body-frame vectors into the inertial (ECI,
  J2000) frame: ``v_eci = R(q) @ v_body``.
* The body frame has the UVISI boresight along +X; an imager pixel ``(row, col)`` (pixel centres at
  ``+0.5``) maps to the imager-frame direction ``(1, x, y)`` normalised, with
  ``x = (col - 128.0) * scale_col`` and ``y = (row - 122.0) * scale_row`` (gnomonic, tangent-plane
  radians per pixel): the paper's measurement unit vector ``(~1, e1, e2)``.
* Positions in metres, velocities in m/s, angles in radians, times in seconds.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class AttitudeData:
    """What the MSX attitude processor hands the track processor each frame.

    Attributes
    ----------
    t : float
        Time tag, s since the event epoch.
    q_body_to_eci : ndarray (4,) float64
        Attitude quaternion, scalar first, body -> ECI (as known on board, i.e. with knowledge error).
    rate_body : ndarray (3,) float64
        Body angular rate in body axes, rad/s.
    r_eci : ndarray (3,) float64
        Spacecraft position, m (ECI).
    v_eci : ndarray (3,) float64
        Spacecraft velocity, m/s (ECI).
    valid : bool
        False when the attitude processor has no data for this frame (a gap); the TP coasts.
    """

    t: float
    q_body_to_eci: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    rate_body: np.ndarray = field(default_factory=lambda: np.zeros(3))
    r_eci: np.ndarray = field(default_factory=lambda: np.zeros(3))
    v_eci: np.ndarray = field(default_factory=lambda: np.zeros(3))
    valid: bool = True
