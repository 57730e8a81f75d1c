"""The parameter records of the scene's targets (plain dataclasses, no numerics): a dedicated
launch's :class:`LaunchParams` and an auroral scene's :class:`AuroraParams` with its :class:`Arc` s.
Kept apart from the models (``groundsim.targets``, ``groundsim.aurora``) so reading a scenario file
does not load SGP4 or the numba kernels. Units are in the field names (deg, km, s, kR, m, m/s^2).
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LaunchParams:
    lat_deg: float = 34.6
    lon_deg: float = -120.6
    t_launch: float = -60.0          # s from the event epoch
    azimuth_deg: float = 180.0       # launch azimuth, from north toward east
    vertical_s: float = 8.0          # vertical rise before the pitch kick
    kick_deg: float = 3.0            # pitch-over from the vertical at the kick
    burn_s: float = 170.0            # burn time
    accel0: float = 16.0             # m/s^2 thrust acceleration at lift-off
    mass_ratio: float = 5.0          # m0 / m_burnout: accel grows as 1 / (1 - (1 - 1/mr) t / burn)
    body_mag_at_1000km: float = 8.0
    plume_mag_at_1000km: float = 0.5
    uv_plume_gain_mag: float = -1.0
    uv_offset: float = 2.0
    plume_length_m: float = 400.0
    plume_width_frac: float = 0.2
    nominal_dt: float = 0.0
    nominal_bias_m: tuple = (0.0, 0.0, 0.0)


@dataclass
class Arc:
    y0_km: float = 0.0
    amp_km: float = 8.0
    wavelength_km: float = 300.0
    phase: float = 0.0
    omega: float = 0.02            # rad/s: the waves travel
    drift_north_km_s: float = 0.0
    width_km: float = 8.0
    half_length_km: float = 600.0
    b0_kR: float = 5.0
    var: float = 0.2
    period_s: float = 20.0


@dataclass
class AuroraParams:
    lat0_deg: float = 66.0
    lon0_deg: float = -100.0
    shell_alt_km: float = 110.0
    arcs: list = field(default_factory=lambda: [Arc(), Arc(y0_km=60.0, amp_km=5.0, b0_kR=2.0, width_km=12.0,
                                                        phase=1.0, omega=-0.015)])
    surge_grow_km_s: float = 1.0
    surge_max_km: float = 60.0
    surge_width_km: float = 70.0
    surge_west_km_s: float = 1.0
    surge_x0_km: float = 40.0
    surge_kR: float = 8.0
    spot_radius_km: float = 12.0
    spot_kR: float = 40.0
    limb_kR: float = 20.0
    airglow_kR: float = 0.3
    dayglow_kR: float = 200.0
    sun_eci: tuple = (1.0, 0.0, 0.0)   # set by the scene from the epoch
