"""Configuration of the track processor (plain dataclass, validated; the kernels get packed words).

Defaults and where they come from:

* ``alpha = 0.25, beta = 0`` -- the paper: *"alpha = 0.25 provides a 90% response in eight frames
  (4 s). The velocity gain beta is almost always set to 0 ... it must be 0 or both types of gates
  will follow the data and differentiation based on velocity cannot occur."*
* ``n_empty = 3`` frames (rules 1, 2; with the proposal ``rule_guards``, rule 3's populated run) and
  ``residual_threshold_px2 = 16`` px^2 (rules 3, 4). The squared residual of a wrong hypothesis
  approaches ``(d / alpha)^2`` per frame for an apparent-velocity difference of d px/frame (4 px^2
  at d = 0.5 px/frame; 16 px^2 is reached on the 9th frame with the transient), a right one ``4
  sigma^2 / (2 - alpha) ~ 2.3 sigma^2`` per frame (0.09 px^2 at sigma = 0.2 px). The paper gives no
  values ("n successive frames", "a specified amount"); these were chosen on the synthetic streams
  of ``tests/tp/test_tp.py`` with the rule guards on (the configuration of that choice): 99.8 % of
  1000 events decided for the right candidate, median latency 4 frames (2 s), p95 11 frames; gate 3
  px or threshold 8-12 px^2 give the same within 0.3 %. ``n_empty_object`` /
  ``residual_threshold_star_px2`` (rules 2 and 4: concluding "star", which deletes both gates)
  default to the same values.
* ``gate_px = 4`` -- half-width of the square gate in pixels of the current imager (it must hold the
  first-frame lag of the right hypothesis, ``d``, and the steady lag ``d (1 - alpha) / alpha``
  plus the centroid noise).
* EKF: measurement sigma 0.5 px, innovation gate 5 sigma, white-acceleration PSD 1e-3 m^2/s^3
  (covers unmodelled drag and, with ``j2=False``, part of J2 over a pass), initial sigmas 1 km and
  10 m/s about the nominal (the a priori trajectory the gates already trust).
* Targets of opportunity: ``opp_alpha = 0.25``, ``opp_beta = alpha^2 / (2 - alpha)`` (the
  Benedict-Bordner relation, 0.0357), gate 8 px. With the proposal ``opp_startup`` (off by
  default: the paper's TP runs the steady alpha-beta) a new track's first
  observations are weighed with the growing-memory (least-squares) start-up gains of Kalata 1984 /
  Brookner, "Tracking and Kalman Filtering Made Easy" (1998) sec. 1.2.6, ``alpha_k = 2(2k-1)/
  (k(k+1))``, ``beta_k = 6/(k(k+1))`` after the k-th observation, each until it falls to its
  steady value (k <= 14 at the defaults), instead of acquiring with zero velocity and the steady
  gains, which lag a moving spot by ~``v dt / alpha`` for tens of frames. Chosen on the training
  aurora families (docs/validation.md, the evaluation families).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from flightsw.messages import IMAGER_CODES, OBJECT_TYPE_CODES
from flightsw.proposals import PROPOSALS, expand
from flightsw.tp.dynamics import NominalTrajectory
from flightsw.tp.geometry import ImagerGeometry

__all__ = ["TPConfig", "MODES", "TP_PROPOSALS", "PROPOSAL_OFF"]

MODES = ("dedicated", "opportunity")
#: the proposals (:mod:`flightsw.proposals`) that change the TP
TP_PROPOSALS = tuple(n for n, p in PROPOSALS.items() if p.processor == "tp")
#: each TP proposal parameter's value with its proposal off (the paper's system)
PROPOSAL_OFF = {"n_apriori": 0, "ekf_max_rejects": 0, "opp_startup": False, "aim_row_px": 0.0,
                "aim_col_px": 0.0, "aim_scan_px": 0.0}


def _num(name, v, lo=None, hi=None, lo_open=False, hi_open=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) and not hasattr(v, "__float__"):
        raise ValueError(f"TPConfig.{name}={v!r} must be a number")
    x = float(v)
    if not math.isfinite(x):
        raise ValueError(f"TPConfig.{name}={v!r} must be finite")
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise ValueError(f"TPConfig.{name}={v!r} must be {'>' if lo_open else '>='} {lo}")
    if hi is not None and (x > hi or (hi_open and x == hi)):
        raise ValueError(f"TPConfig.{name}={v!r} must be {'<' if hi_open else '<='} {hi}")
    return x


def _int(name, v, lo, hi):
    if isinstance(v, bool) or not isinstance(v, int) and not (hasattr(v, "__index__")):
        raise ValueError(f"TPConfig.{name}={v!r} must be an integer")
    i = int(v)
    if not lo <= i <= hi:
        raise ValueError(f"TPConfig.{name}={v!r} must be in {lo}..{hi}")
    return i


@dataclass
class TPConfig:
    """Track processor configuration.

    Parameters
    ----------
    imagers : dict[str, ImagerGeometry]
        The imagers whose candidate messages the TP accepts (keys of
        :data:`flightsw.messages.IMAGER_CODES`).
    mode : "dedicated" | "opportunity"
        Dedicated events (a nominal trajectory is supplied): velocity filtering with star/object
        gates and the 6-state EKF. Targets of opportunity (e.g. aurora): no velocity filtering,
        the highest-ranked candidate inside the angular gate feeds an alpha-beta track.
    object_type : str
        Type reported to the IP on every command (a key of
        :data:`flightsw.messages.OBJECT_TYPE_CODES`; uplink code 24). INTERPRETED: the event's
        configured type, whether or not an object is held yet: the TP is tracking that type from
        the first frame (its nominal and gates are that object's), and the IP keeps ranking with
        the record for it while the TP acquires (:mod:`flightsw.ip.record_table`).
    nominal : NominalTrajectory or None
        The a priori trajectory (dedicated mode). None in dedicated mode: nothing can be
        discriminated; the TP reports status ``TC_NO_NOMINAL`` and commands nothing. Ignored in
        opportunity mode.
    alpha, beta : float
        Gate alpha-beta gains (0 < alpha <= 1, 0 <= beta < 2).
    gate_px : float
        Half-width of the square star/object gate, pixels of the message's imager.
    n_empty : int
        Rule 1: a star gate empty for n successive frames (object gate populated) -> object.
        Rule 3 asks for the object gate populated the last n frames as well.
    n_empty_object : int or None
        Rule 2's n (object gate empty -> star); None: ``n_empty``.
    residual_threshold_px2 : float
        Rule 3: star-gate accumulated residual exceeding the object gate's by this (px^2) ->
        object.
    residual_threshold_star_px2 : float or None
        Rule 4's amount (object residual exceeding the star residual -> star); None: same.
    n_lost : int
        The verified object's gate empty this many successive frames -> object lost.
    n_apriori : int or None
        Rule 5, the proposal ``rule5`` (:mod:`flightsw.proposals`; :func:`flightsw.tp.rules.
        apriori_rule`): with no object held, a pair whose gates have both been populated on this
        many frames is the object when its object gate holds the observation nearest the nominal's
        predicted position (within the gate of it), a star otherwise. None: 40 with the proposal
        on, 0 (off, the paper's four rules) otherwise. 40 frames (20 s) was the smallest count that
        changed nothing on the satellite training family.
    aim_row_px, aim_col_px : float or None
        The proposal ``aim_offset``: the pointing puts the target this many imager pixels (rows,
        columns) off the pixel that +X body falls on, through the imager's scale and alignment
        (uplink codes 20, 21). None: 1.0, 1.0 with the proposal on (the centre of compacted pixel
        (61, 64) at compaction 2, where a faint target's light stays in one compacted pixel), 0, 0
        otherwise: the paper's TP points at the object.
    aim_scan_px, aim_scan_frames : float or None, int
        The proposal ``aim_scan``: while an object is held, the aim point circles the aim above:
        ``aim + aim_scan_px (cos 2 pi n / N, sin 2 pi n / N)`` imager pixels (rows, cols) on the
        n-th frame of the hold, N = ``aim_scan_frames`` (uplink codes 22, 23). A dither, as in
        quantised control: a faint target that passes the threshold in one compacted pixel reads
        that pixel's centre wherever in the pixel it lies; a slow circle sweeps it across the
        pixel's edges, where the centroid does move. None: 0.5 px with the proposal on, 0 (off)
        otherwise; 32 frames (16 s). The evidence is in :data:`flightsw.proposals.PROPOSALS` and
        ``docs/fidelity.md``.
    frame_dt : float
        Nominal frame period, s (the prediction horizon of the feedback and pointing).
    max_coast_s : float
        A time gap longer than this deletes every gate (the EKF keeps predicting).
    j2 : bool
        J2 in the plant (nominal propagation and EKF).
    max_step : float
        Longest RK4 step, s.
    ekf_meas_sigma_px, ekf_gate_sigma, ekf_accel_psd, ekf_sigma_pos0, ekf_sigma_vel0 : float
        EKF measurement sigma (px), innovation gate (sigma), white-acceleration PSD (m^2/s^3),
        initial sigmas (m, m/s).
    ekf_max_rejects : int or None
        The proposal ``ekf_reset``: successive frames with a scalar update (either axis) rejected
        before the covariance is reset to its initial value (status ``TC_EKF_RESET``; uplink code
        10). None: 12 frames (6 s) with the proposal on, 0 (never: the paper's EKF) otherwise.
    opp_alpha, opp_beta, opp_gate_px, opp_n_lost
        Target-of-opportunity alpha-beta gains, gate half-width (px) and frames without an
        observation before the track is dropped.
    opp_startup : bool or None
        The proposal ``opp_startup``: growing-memory start-up gains for a new opportunity track
        (see above); ignored (off) when ``opp_beta == 0``, where the filter estimates no velocity.
        None: True with the proposal on, False (the paper's steady alpha-beta) otherwise.
    max_rate : float
        Attitude rates above this (rad/s) are "out of range" (attitude treated as invalid).
    quat_norm_tol : float
        Accepted deviation of the attitude quaternion's norm from 1.
    max_time_skew : float
        Largest accepted |attitude time - frame time|, s.
    proposals : tuple of str
        The TP proposals in force (names of :data:`flightsw.proposals.PROPOSALS`; ``"all"``
        expands): ``rule_guards``, ``rule5``, ``ekf_reset``, ``opp_startup``, ``aim_offset``,
        ``aim_scan``; the IP's two floor proposals are accepted and do nothing here. Default ():
        the paper's TP. A proposal's parameter set away from its off value while the proposal is
        off is refused.
    """

    imagers: dict
    mode: str = "dedicated"
    object_type: str = "satellite"
    nominal: NominalTrajectory | None = None
    alpha: float = 0.25
    beta: float = 0.0
    gate_px: float = 4.0
    n_empty: int = 3
    n_empty_object: int | None = None
    residual_threshold_px2: float = 16.0
    residual_threshold_star_px2: float | None = None
    n_lost: int = 6
    n_apriori: int | None = None
    aim_row_px: float | None = None
    aim_col_px: float | None = None
    aim_scan_px: float | None = None
    aim_scan_frames: int = 32
    frame_dt: float = 0.5
    max_coast_s: float = 10.0
    j2: bool = True
    max_step: float = 0.5
    ekf_meas_sigma_px: float = 0.5
    ekf_gate_sigma: float = 5.0
    ekf_accel_psd: float = 1e-3
    ekf_sigma_pos0: float = 1000.0
    ekf_sigma_vel0: float = 10.0
    ekf_max_rejects: int | None = None
    opp_alpha: float = 0.25
    opp_beta: float = 0.25 ** 2 / (2.0 - 0.25)
    opp_gate_px: float = 8.0
    opp_n_lost: int = 6
    opp_startup: bool | None = None
    max_rate: float = 0.2
    quat_norm_tol: float = 1e-3
    max_time_skew: float = 0.25
    proposals: tuple = ()
    _validated: bool = field(default=False, init=False, repr=False, compare=False)

    def __post_init__(self):
        self.proposals = expand(self.proposals, "TPConfig.proposals")
        for name in TP_PROPOSALS:                   # a parameter left None: its proposal's value
            for fld, on in PROPOSALS[name].on.items():
                if getattr(self, fld) is None:
                    setattr(self, fld, on if name in self.proposals else PROPOSAL_OFF[fld])
        self.validate()

    @property
    def rule_guards(self) -> bool:
        """The rule guards (proposal ``rule_guards``) are in force."""
        return "rule_guards" in self.proposals

    @property
    def aim(self) -> bool:
        """The pointing is aimed off the object (proposals ``aim_offset`` or ``aim_scan``)."""
        return "aim_offset" in self.proposals or "aim_scan" in self.proposals

    def _check_proposals(self) -> None:
        """A proposal's parameter set away from its off value while the proposal is off."""
        for name in TP_PROPOSALS:
            if name in self.proposals:
                continue
            for fld in PROPOSALS[name].on:
                if getattr(self, fld) != PROPOSAL_OFF[fld]:
                    raise ValueError(f"TPConfig.{fld}={getattr(self, fld)!r} is a parameter of the "
                                     f"proposal {name!r}, which is off (switch it on with --with "
                                     f"{name}, or proposals=({name!r},))")
        if self.ekf_max_rejects == 0 and "ekf_reset" in self.proposals:
            raise ValueError("TPConfig.ekf_max_rejects=0 with the proposal 'ekf_reset' on: must be "
                             ">= 1")

    def validate(self) -> "TPConfig":
        """Check every field; ``ValueError`` naming the field on the first bad one."""
        if not isinstance(self.imagers, dict) or not self.imagers:
            raise ValueError("TPConfig.imagers must be a non-empty dict {imager id: ImagerGeometry}")
        for k, g in self.imagers.items():
            if k not in IMAGER_CODES:
                raise ValueError(f"TPConfig.imagers: unknown imager id {k!r}; expected one of "
                                 f"{sorted(IMAGER_CODES)}")
            if not isinstance(g, ImagerGeometry):
                raise ValueError(f"TPConfig.imagers[{k!r}] must be an ImagerGeometry, got "
                                 f"{type(g).__name__}")
        if self.mode not in MODES:
            raise ValueError(f"TPConfig.mode={self.mode!r} must be one of {MODES}")
        if self.object_type not in OBJECT_TYPE_CODES:
            raise ValueError(f"TPConfig.object_type={self.object_type!r} must be one of "
                             f"{sorted(k for k in OBJECT_TYPE_CODES if k)}")
        if self.nominal is not None and not isinstance(self.nominal, NominalTrajectory):
            raise ValueError(f"TPConfig.nominal must be a NominalTrajectory or None, got "
                             f"{type(self.nominal).__name__}")
        _num("alpha", self.alpha, 0.0, 1.0, lo_open=True)
        _num("beta", self.beta, 0.0, 2.0, hi_open=True)
        _num("gate_px", self.gate_px, 0.5, 128.0)
        _int("n_empty", self.n_empty, 1, 1000)
        if self.n_empty_object is not None:
            _int("n_empty_object", self.n_empty_object, 1, 10 ** 6)
        _num("residual_threshold_px2", self.residual_threshold_px2, 0.0, 1e30, lo_open=True)
        if self.residual_threshold_star_px2 is not None:
            _num("residual_threshold_star_px2", self.residual_threshold_star_px2, 0.0, 1e30,
                 lo_open=True)
        _int("n_lost", self.n_lost, 1, 1000)
        _int("n_apriori", self.n_apriori, 0, 100000)
        _num("aim_row_px", self.aim_row_px, -4.0, 4.0)
        _num("aim_col_px", self.aim_col_px, -4.0, 4.0)
        _num("aim_scan_px", self.aim_scan_px, 0.0, 2.0)
        _int("aim_scan_frames", self.aim_scan_frames, 3, 100000)
        _num("frame_dt", self.frame_dt, 0.0, 60.0, lo_open=True)
        _num("max_coast_s", self.max_coast_s, 0.0, 3600.0, lo_open=True)
        if not isinstance(self.j2, bool):
            raise ValueError(f"TPConfig.j2={self.j2!r} must be a bool")
        _num("max_step", self.max_step, 0.01, 10.0)
        _num("ekf_meas_sigma_px", self.ekf_meas_sigma_px, 0.0, 100.0, lo_open=True)
        _num("ekf_gate_sigma", self.ekf_gate_sigma, 1.0, 1e3)
        _num("ekf_accel_psd", self.ekf_accel_psd, 0.0, 1e6, lo_open=True)
        _num("ekf_sigma_pos0", self.ekf_sigma_pos0, 0.0, 1e7, lo_open=True)
        _num("ekf_sigma_vel0", self.ekf_sigma_vel0, 0.0, 1e4, lo_open=True)
        _int("ekf_max_rejects", self.ekf_max_rejects, 0, 10 ** 6)
        _num("opp_alpha", self.opp_alpha, 0.0, 1.0, lo_open=True)
        _num("opp_beta", self.opp_beta, 0.0, 2.0, hi_open=True)
        _num("opp_gate_px", self.opp_gate_px, 0.5, 256.0)
        _int("opp_n_lost", self.opp_n_lost, 1, 1000)
        if not isinstance(self.opp_startup, bool):
            raise ValueError(f"TPConfig.opp_startup={self.opp_startup!r} must be a bool")
        _num("max_rate", self.max_rate, 0.0, 10.0, lo_open=True)
        _num("quat_norm_tol", self.quat_norm_tol, 0.0, 0.5, lo_open=True)
        _num("max_time_skew", self.max_time_skew, 0.0, 60.0)
        self._check_proposals()
        self._validated = True
        return self
