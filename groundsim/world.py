"""The closed-loop world (Basilisk style): ``reset()``, ``attitude_data()``, ``render()``, ``command(q)``,
``advance(dt)``; properties ``t``, ``imager`` (settable), ``done``, ``frame_dropped``.

Open loop (``Scenario.frames``) the attitude controller follows the scenario's pointing profile; once
``command(q)`` is called (the track processor's pointing command) it follows the commands instead.
Frame time tags are mid-integration; the attitude at the integration start/end is the present attitude
propagated with the present body rate (smear), the target's start/end positions its state propagated
linearly (error < 0.1 m over 0.125 s).

Truth (a dict, per rendered frame)::

    t, frame_index, imager                      s from the epoch, int, imager id
    stars      structured array (hip, row, col, counts, electrons, mag): every star whose centre is in
               the frame at mid-integration (0-based, pixel centres +0.5); stars behind the Earth omitted
    target     dict(type, row, col (NaN out of field), in_field, los_eci (unit, from MSX), range_m,
               r_eci, v_eci, electrons, plume_electrons) -- None-free even without a target (NaNs)
    spacecraft dict(r_eci, v_eci, q_body_to_eci, rate_body)  (truth)
    q_imager_to_eci                              truth imager attitude (with the true alignment)
    attitude   flightsw.messages.AttitudeData as handed to the TP (knowledge error, gaps)
    bloomed_columns                              columns that could reach the full well
"""
from __future__ import annotations

import math

import numpy as np

from flightsw.messages import AttitudeData

from .aurora import AuroraParams, AuroraScene
from .frames import R_EARTH_M, geodetic_to_ecef, jd_utc, julian_year_tt, rot_z
from .quat import (q_conj, q_from_rotvec, q_mul, q_normalize, q_pointing, q_rate, q_to_dcm,
                   q_to_rotvec, radec_to_vec)
from .render import PointSource, Renderer, frame_rng_state, standard_normals_kernel
from .sky import StarCatalog
from .spacecraft import AttitudeController, ControllerParams, KnowledgeError, Orbit, pass_over_elements
from .targets import LaunchTarget, SatelliteTarget

DEG = math.pi / 180.0
FRAME_DT = 0.5
ATTITUDE_STREAM = 1        # frame_rng_state stream of the attitude knowledge noise


def _orbit_from(spec, epoch, satnum, sc_orbit=None):
    kind, v = spec
    if kind == "tle":
        return Orbit(v[0], v[1], epoch)
    if kind == "kepler":
        return Orbit.from_elements(epoch, v["a_km"] * 1e3, v["ecc"], v["inc_deg"] * DEG, v["raan_deg"] * DEG,
                                   v["argp_deg"] * DEG, v["mean_anomaly_deg"] * DEG, satnum)
    if kind == "pass_over":
        el = pass_over_elements(epoch, v["lat_deg"] * DEG, v["lon_deg"] * DEG, v["alt_km"] * 1e3,
                                v["inc_deg"] * DEG, v["ascending"], v["t"])
        return Orbit.from_elements(epoch, *el, satnum)
    if kind == "relative":
        s = sc_orbit.sat
        a = (s.a * s.radiusearthkm) * 1e3 + v["d_alt_km"] * 1e3
        return Orbit.from_elements(epoch, a, max(s.ecco, 1e-4), s.inclo + v["d_inc_deg"] * DEG,
                                   s.nodeo + v["d_raan_deg"] * DEG, s.argpo,
                                   s.mo + v["d_phase_deg"] * DEG + _epoch_shift(s, epoch), satnum)
    raise ValueError(kind)


def _epoch_shift(sat, epoch):
    # mean anomaly advance from the spacecraft's TLE epoch to the scenario epoch
    from .frames import jd_utc
    jd, fr = jd_utc(epoch)
    dt_min = ((jd - sat.jdsatepoch) + (fr - sat.jdsatepochF)) * 1440.0
    return sat.no_kozai * dt_min


def _copy_attitude(a: AttitudeData) -> AttitudeData:
    return AttitudeData(t=a.t, q_body_to_eci=a.q_body_to_eci.copy(), rate_body=a.rate_body.copy(),
                        r_eci=a.r_eci.copy(), v_eci=a.v_eci.copy(), valid=a.valid)


def _lines_of_sight(r_sc, v_sc, r_t, v_t, h):
    """The target seen from the spacecraft at the start, middle and end of the integration: unit
    lines of sight ``d - dd``, ``d``, ``d + dd`` and ``|d|`` (m), for ``d = r_t - r_sc`` (m) and
    ``dd = h * (v_t - v_sc)`` (its change over half the integration, ``h`` s); positions and
    velocities float64 (3,) ECI. The middle one is a float64 (3,) array (the truth's ``los_eci``),
    the start and end ones (x, y, z) tuples (only projected). Python floats: the arithmetic of the
    same NumPy expressions."""
    x, y, z = (p - q for p, q in zip(r_t.tolist(), r_sc.tolist()))
    a, b, c = (h * (p - q) for p, q in zip(v_t.tolist(), v_sc.tolist()))
    out = []
    for sx, sy, sz in ((x - a, y - b, z - c), (x, y, z), (x + a, y + b, z + c)):
        n = math.sqrt(sx * sx + sy * sy + sz * sz)
        out.append((sx / n, sy / n, sz / n))
    return out[0], np.array(out[1]), out[2], math.sqrt(x * x + y * y + z * z)


class World:
    def __init__(self, scenario):
        self.scn = sc = scenario
        self.epoch = sc.epoch
        self.jyear = julian_year_tt(*jd_utc(sc.epoch))
        self.catalog = StarCatalog.shared()
        self.sky = self.catalog.at_epoch(self.jyear)
        spc = sc.spacecraft
        self.orbit = _orbit_from(spc["orbit"], sc.epoch, 23851)
        self.ctrl_params = ControllerParams(rate_limit=spc["rate_limit_deg_s"] * DEG,
                                            accel_limit=spc["accel_limit_deg_s2"] * DEG,
                                            settle_time=spc["settle_time_s"])
        self.knowledge = KnowledgeError(bias=spc["knowledge_bias_urad"] * 1e-6, noise=spc["knowledge_noise_urad"] * 1e-6,
                                        rate_noise=spc["rate_noise_urad_s"] * 1e-6,
                                        position_noise=spc["position_noise_m"])
        tg = sc.target
        self.target = None
        self.aurora = None
        if tg["type"] == "satellite":
            orb = _orbit_from(tg["orbit"], sc.epoch, 90001, self.orbit)
            self.target = SatelliteTarget(orb, tg["mag_at_1000km"], tg["uv_offset"], tg["nominal_dt_s"],
                                          tg["nominal_bias_m"])
        elif tg["type"] == "launch":
            self.target = LaunchTarget(tg["params"], sc.epoch, sc.duration + 5.0)
        elif tg["type"] == "aurora":
            self.aurora = AuroraScene(tg["params"], sc.epoch)
        self._glow = None
        if sc.earth_glow is not False and self.aurora is None:
            self._glow = AuroraScene(AuroraParams(), sc.epoch, include_aurora=False)
        from .frames import gmst82
        self._theta0 = gmst82(*jd_utc(sc.epoch))
        self._renderers = {}
        self._att_cache = None
        self.reset()

    # -- life cycle ---------------------------------------------------------------------------------
    def reset(self):
        self._t = 0.0
        self._k = 0
        self._imager = self.scn.faults.imager_at(0.0, self.scn.imager)
        self._imager_forced = False
        self._external = False
        self._last_cmd = None
        q0, w_eci = self.profile_command(0.0)
        self.ctrl = AttitudeController(q0, self.ctrl_params, rate0=q_to_dcm(q0).T @ w_eci)
        self.ctrl.command(q0, w_eci)

    @property
    def t(self) -> float:
        return self._t

    @property
    def frame_index(self) -> int:
        return self._k

    @property
    def done(self) -> bool:
        return self._t > self.scn.duration + 1e-9

    @property
    def imager(self) -> str:
        return self._imager

    @imager.setter
    def imager(self, iid):
        if iid not in self.scn.imagers:
            raise ValueError(f"unknown imager {iid!r}; expected one of {list(self.scn.imagers)}")
        self._imager = iid
        self._imager_forced = True

    @property
    def imager_model(self):
        return self.scn.imagers[self._imager]

    @property
    def frame_dropped(self) -> bool:
        return self._k in self.scn.faults.dropped_frames

    @property
    def target_type(self):
        """"satellite", "launch", "aurora" or None."""
        return self.scn.target_type

    @property
    def config(self) -> dict:
        """The scenario's configuration (name, imager, compaction, seed, target_type, duration, epoch)."""
        return self.scn.config()

    def imager_alignment_onboard(self, iid=None):
        """Quaternion imager -> body the flight code believes (the truth may differ: ``Imager.align``)."""
        return np.asarray(self.scn.imagers[iid or self._imager].align_onboard)

    @property
    def compaction(self):
        return self.scn.compaction

    @property
    def seed(self):
        return self.scn.seed

    def advance(self, dt: float = FRAME_DT):
        if not (dt > 0):
            raise ValueError(f"dt must be > 0, got {dt!r}")
        if not self._external:
            q, w = self.profile_command(self._t + dt)
            self.ctrl.command(q, w)
        self.ctrl.step(dt)
        self._t += dt
        self._k = int(round(self._t / FRAME_DT))
        if not self._imager_forced:
            self._imager = self.scn.faults.imager_at(self._t, self.scn.imager)

    def command(self, q_target_body_to_eci):
        """The track processor's pointing command (body -> ECI); the controller slews toward it."""
        q = q_normalize(np.asarray(q_target_body_to_eci, float))
        w = np.zeros(3)
        if self._last_cmd is not None:
            t0, q0 = self._last_cmd
            if 0.0 < self._t - t0 <= 2.0:
                w = q_rate(q, q0, self._t - t0)
        self._last_cmd = (self._t, q)
        self._external = True
        self.ctrl.command(q, w if self.ctrl_params.feedforward else None)

    # -- states ---------------------------------------------------------------------------------------
    def spacecraft_state(self, t=None):
        return self.orbit.state(self._t if t is None else t)

    def true_target_state(self, t=None):
        t = self._t if t is None else t
        if self.target is not None:
            return self.target.state(t)
        if self.aurora is not None:
            return self.aurora.hot_spot(t)
        return None

    def nominal_target_state(self, t):
        """(r_eci, v_eci) of the nominal trajectory the TP is given (satellite/launch), else None."""
        return None if self.target is None else self.target.nominal_state(t)

    def profile_command(self, t):
        """(q_body_to_eci, angular velocity ECI) of the scenario's pointing profile at t."""
        q = self._profile_q(t)
        h = 0.05
        w = q_to_rotvec(q_mul(self._profile_q(t + h), q_conj(q))) / h
        return q, w

    def _profile_q(self, t):
        p = self.scn.pointing
        roll = p["roll_deg"] * DEG
        mode = p["mode"]
        if mode == "inertial":
            return q_pointing(radec_to_vec(p["ra_deg"] * DEG, p["dec_deg"] * DEG), roll=roll)
        if mode == "slew":
            a = radec_to_vec(p["ra_deg"] * DEG, p["dec_deg"] * DEG)
            b = radec_to_vec(p["to_ra_deg"] * DEG, p["to_dec_deg"] * DEG)
            ang = math.acos(min(1.0, max(-1.0, float(a @ b))))
            s = min(max(t - p["start_s"], 0.0) * p["rate_deg_s"] * DEG, ang)
            axis = np.cross(a, b)
            axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 1e-12 else np.array([0.0, 0.0, 1.0])
            d = q_to_dcm(q_from_rotvec(axis * s)) @ a
            return q_pointing(d, up_eci=axis, roll=roll)
        r, _ = self.orbit.state(t)
        if mode == "earth_point":
            th = self._theta0 + 7.2921150e-5 * t
            g = rot_z(th) @ geodetic_to_ecef(p["lat_deg"] * DEG, p["lon_deg"] * DEG, p["alt_km"] * 1e3)
            return q_pointing(g - r, up_eci=r, roll=roll)
        # track_target: nominal trajectory, optionally offset in the field by offset_px (row, col).
        # Open loop only: in a closed-loop event the TP's first command (frame 0) replaces this
        # profile and points the boresight at the target, so the offset is where the target
        # is at acquisition, not where it is held (docs/validation.md "Why `mid_offset_ahead`").
        rn, _ = self.target.nominal_state(t)
        q = q_pointing(rn - r, up_eci=r, roll=roll)
        off = p["offset_px"]
        if off[0] or off[1]:
            im = self.scn.imagers[self.scn.imager]
            # rotate the body so the target appears offset_px from the centre
            q = q_mul(q, q_from_rotvec([0.0, off[0] * im.scale_row, -off[1] * im.scale_col]))
        return q

    # -- outputs --------------------------------------------------------------------------------------
    def attitude_data(self) -> AttitudeData:
        # a pure function of (t, frame index, true attitude and rate): the closed loop asks twice per
        # frame (the harness, then render() for the truth); the second gets the copy kept from the first
        kept = self._kept_attitude()
        if kept is not None:
            return _copy_attitude(kept)
        c = self.ctrl
        r, v = self.orbit.state(self._t)
        # the frame's knowledge noise: its own xoshiro stream (1) of the frame's seed (render uses 0)
        z = np.empty(9)
        standard_normals_kernel(frame_rng_state(self.scn.seed, self._k, ATTITUDE_STREAM), z)
        a = self.knowledge.apply(self._t, c.q, c.w, r, v, draws=z,
                                 valid=self.scn.faults.attitude_valid(self._t))
        self._att_cache = (self._attitude_key(), _copy_attitude(a), self.knowledge, self.orbit,
                           self.scn.faults)
        return a

    def _attitude_key(self):
        c, kn = self.ctrl, self.knowledge
        q, w = np.asarray(c.q), np.asarray(c.w)
        return (self._t, self._k, q.dtype.str, q.tobytes(), w.dtype.str, w.tobytes(), self.scn.seed,
                np.asarray(kn.bias, float).tobytes(), kn.noise, kn.rate_noise, kn.position_noise)

    def _kept_attitude(self):
        """The untouched copy of this state's attitude data kept by :meth:`attitude_data`, or None."""
        ac = self._att_cache
        if (ac is not None and ac[2] is self.knowledge and ac[3] is self.orbit
                and ac[4] is self.scn.faults and ac[0] == self._attitude_key()):
            return ac[1]
        return None

    def _renderer(self, iid):
        r = self._renderers.get(iid)
        if r is None:
            r = Renderer(self.scn.imagers[iid], self.sky, self.catalog)
            self._renderers[iid] = r
        return r

    def render(self):
        """(frame uint16[244, 256], truth dict) for the current time and imager."""
        im = self.imager_model
        ren = self._renderer(im.id)
        t = self._t
        h = 0.5 * im.t_int
        r_sc, v_sc = self.orbit.state(t)
        a = im.align_dcm
        q_mid = self.ctrl.q
        m0, m, m1 = self.ctrl.exposure_matrices(h, a)
        sources = []
        tinfo = dict(type=self.scn.target_type, row=math.nan, col=math.nan, in_field=False,
                     los_eci=None, range_m=math.nan, r_eci=None, v_eci=None, electrons=0.0,
                     plume_electrons=0.0)
        st = self.true_target_state(t)
        if st is not None:
            rt, vt = st
            los0, los, los1, rng_m = _lines_of_sight(r_sc, v_sc, rt, vt, h)
            tinfo.update(los_eci=los, range_m=rng_m, r_eci=rt, v_eci=vt)
            if self.target is not None:
                body, plume, plen, pwid = self.target.appearance(t, rng_m, im.band)
                el = im.zp_e_per_s * 10 ** (-0.4 * body) * im.t_int
                pel = im.zp_e_per_s * 10 ** (-0.4 * plume) * im.t_int if plume is not None else 0.0
                tail = None
                if pel > 0:
                    d = rt - r_sc
                    vu = vt / np.linalg.norm(vt)
                    tail = (d - plen * vu) / np.linalg.norm(d - plen * vu)
                sources.append(PointSource(los0, los, los1, el, pel, tail, pwid / rng_m))
                tinfo.update(electrons=el, plume_electrons=pel)
        else:
            tinfo.update(los_eci=np.full(3, math.nan), r_eci=np.full(3, math.nan),
                         v_eci=np.full(3, math.nan))
        extended = None
        scene = self.aurora or self._glow
        if scene is not None and (self.aurora is not None or self.scn.earth_glow is True
                                  or self._earth_near_field(r_sc, m[0], im)):
            extended = scene.image(t, r_sc, m.T, im)
        frame, stars, src_rc = ren.render(m0, m, m1, sources, seed=self.scn.seed, frame_index=self._k,
                                          extended=extended, observer_pos=r_sc)
        if st is not None:
            if sources:
                row, col = src_rc[0]
            else:
                row, col = ren.project(m, tinfo["los_eci"])
            inside = row == row and 0 <= row < im.n_rows and 0 <= col < im.n_cols
            tinfo.update(row=row if inside else math.nan, col=col if inside else math.nan, in_field=bool(inside))
        truth = dict(t=t, frame_index=self._k, imager=im.id, stars=stars, target=tinfo,
                     spacecraft=dict(r_eci=r_sc, v_eci=v_sc, q_body_to_eci=q_mid.copy(), rate_body=self.ctrl.w.copy()),
                     q_imager_to_eci=q_normalize(q_mul(q_mid.tolist(), im.align)),
                     attitude=self._truth_attitude(), bloomed_columns=ren.bloomed_columns, real=False)
        return frame, truth

    def _truth_attitude(self) -> AttitudeData:
        """The frame's attitude data for the truth: the copy :meth:`attitude_data` kept when the
        harness asked first this frame (handed over, not copied again), else computed."""
        kept = self._kept_attitude()
        if kept is None:
            return self.attitude_data()
        self._att_cache = None
        return kept

    def _earth_near_field(self, r_sc, bore, im):
        x, y, z = r_sc.tolist()
        b0, b1, b2 = bore.tolist()
        rn = math.sqrt(x * x + y * y + z * z)
        rho = math.asin(min(1.0, (R_EARTH_M + 300e3) / rn))        # Earth + glow layer angular radius
        off = math.acos(min(1.0, max(-1.0, -(x * b0 + y * b1 + z * b2) / rn)))
        return off < rho + im.half_diagonal
