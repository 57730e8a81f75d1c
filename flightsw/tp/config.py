"""Configuration of the track processor: small declared parts, one definition per parameter.

Each parameter is declared once, in the part that holds its job, with a one-line doc, its unit,
its bounds and its class (:data:`CLASSES`):

* ``paper`` -- the value is the MSX paper's (quoted in :mod:`flightsw.tp.gates` and
  ``docs/fidelity.md``), e.g. the gates' *"alpha = 0.25 provides a 90% response in eight frames
  (4 s). The velocity gain beta is almost always set to 0"*;
* ``interpretation`` -- the paper states the behaviour but no value ("n successive frames", "a
  specified amount"): the value is ours, chosen as ``docs/fidelity.md`` says, and how it was
  measured is in ``docs/validation.md`` (the TP's parameters);
* ``proposal`` -- the parameter of a proposal (:mod:`flightsw.proposals`), at its off value (the
  paper's system) unless its proposal is in force; ``None`` at construction takes the proposal's
  value when on, :data:`PROPOSAL_OFF` otherwise.

The parts (:data:`PARTS`): :class:`Gates`, :class:`Rules`, :class:`EKFParams`,
:class:`OpportunityTrack`, :class:`Aim`, :class:`Timing`, :class:`InputChecks`; the proposals in
force are the part ``proposals`` (a tuple of names). :class:`TPConfig` holds the event's
description (imagers, mode, object type, nominal) and one of each part. It is built from flat
keywords (``TPConfig(imagers=..., gate_px=3.0)``: each key goes to the part that declares it; the
form scenario ``[tp]`` tables, recordings and uplinks use) or from parts, and read either way
(``cfg.gates.gate_px`` or ``cfg.gate_px``). :meth:`TPConfig.describe` lists every parameter with
its part, unit, class and doc.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from flightsw.messages import IMAGER_CODES, OBJECT_TYPE_CODES
from flightsw.proposals import PROPOSALS, expand
from flightsw.tp.dynamics import NominalTrajectory
from flightsw.tp.geometry import ImagerGeometry

__all__ = ["TPConfig", "MODES", "TP_PROPOSALS", "PROPOSAL_OFF", "CLASSES", "PARTS", "Gates",
           "Rules", "EKFParams", "OpportunityTrack", "Aim", "Timing", "InputChecks"]

MODES = ("dedicated", "opportunity")
#: the classes of a parameter (module docstring)
CLASSES = ("paper", "interpretation", "proposal")
#: the proposals (:mod:`flightsw.proposals`) that change the TP
TP_PROPOSALS = tuple(n for n, p in PROPOSALS.items() if p.processor == "tp")
#: each TP proposal parameter's value with its proposal off (the paper's system)
PROPOSAL_OFF = {"n_apriori": 0, "ekf_max_rejects": 0, "opp_startup": False, "aim_row_px": 0.0,
                "aim_col_px": 0.0, "aim_scan_px": 0.0}


#: a parameter's check (the keywords of :func:`param` after its doc) and their defaults
CHECK_DEFAULTS = {"kind": "num", "lo": None, "hi": None, "lo_open": False, "hi_open": False,
                  "optional": False}


def param(default, unit: str, cls: str, doc: str, **check):
    """A declared parameter: a dataclass field whose metadata holds its doc, unit, class and check
    (``kind`` "num", "int" or "bool"; bounds ``lo``/``hi``, ``lo_open``/``hi_open`` for open
    ones; ``optional``: None is accepted, meaning what the doc says)."""
    if cls not in CLASSES:
        raise ValueError(f"parameter class {cls!r} must be one of {CLASSES}")
    unknown = set(check) - set(CHECK_DEFAULTS)
    if unknown:
        raise ValueError(f"param: unknown check {sorted(unknown)}")
    return field(default=default, metadata={"unit": unit, "class": cls, "doc": doc,
                                            **CHECK_DEFAULTS, **check})


def check_value(name: str, v, meta: dict):
    """``v`` checked against a parameter's declaration; ``ValueError`` naming ``TPConfig.name``."""
    if v is None and meta["optional"]:
        return v
    if meta["kind"] == "bool":
        if not isinstance(v, bool):
            raise ValueError(f"TPConfig.{name}={v!r} must be a bool")
        return v
    if meta["kind"] == "int":
        if isinstance(v, bool) or not isinstance(v, int) and not hasattr(v, "__index__"):
            raise ValueError(f"TPConfig.{name}={v!r} must be an integer")
        i = int(v)
        if not meta["lo"] <= i <= meta["hi"]:
            raise ValueError(f"TPConfig.{name}={v!r} must be in {meta['lo']}..{meta['hi']}")
        return i
    if isinstance(v, bool) or not isinstance(v, (int, float)) and not hasattr(v, "__float__"):
        raise ValueError(f"TPConfig.{name}={v!r} must be a number")
    x = float(v)
    if not math.isfinite(x):
        raise ValueError(f"TPConfig.{name}={v!r} must be finite")
    lo, hi = meta["lo"], meta["hi"]
    if lo is not None and (x < lo or (meta["lo_open"] and x == lo)):
        raise ValueError(f"TPConfig.{name}={v!r} must be {'>' if meta['lo_open'] else '>='} {lo}")
    if hi is not None and (x > hi or (meta["hi_open"] and x == hi)):
        raise ValueError(f"TPConfig.{name}={v!r} must be {'<' if meta['hi_open'] else '<='} {hi}")
    return x


# ---- the parts ----------------------------------------------------------------------------------
@dataclass
class Gates:
    """The star and object gates of a dedicated event (paper, "Velocity filtering")."""

    alpha: float = param(0.25, "1", "paper", "position gain of the gates' alpha-beta filter",
                         lo=0.0, hi=1.0, lo_open=True)
    beta: float = param(0.0, "1", "paper", "velocity gain (0: the gates keep the a priori "
                        "velocities)", lo=0.0, hi=2.0, hi_open=True)
    gate_px: float = param(4.0, "px", "interpretation", "half-width of the square star/object "
                           "gate, pixels of the message's imager", lo=0.5, hi=128.0)


@dataclass
class Rules:
    """The decision rules between a pair's star and object hypotheses (paper, rules 1-4)."""

    n_empty: int = param(3, "frames", "interpretation", "rule 1: a star gate empty this many "
                         "successive frames (object gate populated) -> object", kind="int",
                         lo=1, hi=1000)
    n_empty_object: int | None = param(None, "frames", "interpretation", "rule 2's count (object "
                                       "gate empty -> star); None: n_empty", kind="int", lo=1,
                                       hi=10 ** 6, optional=True)
    residual_threshold_px2: float = param(16.0, "px^2", "interpretation", "rule 3: star residual "
                                          "exceeding the object's by this -> object", lo=0.0,
                                          hi=1e30, lo_open=True)
    residual_threshold_star_px2: float | None = param(
        None, "px^2", "interpretation", "rule 4's amount (object residual exceeding the star's -> "
        "star); None: residual_threshold_px2", lo=0.0, hi=1e30, lo_open=True, optional=True)
    n_lost: int = param(6, "frames", "interpretation", "the verified object's gate empty this many "
                        "successive frames -> object lost", kind="int", lo=1, hi=1000)
    n_apriori: int | None = param(None, "frames", "proposal", "rule 5 (proposal rule5): a pair "
                                  "populated this many frames is decided by the nominal (0: off)",
                                  kind="int", lo=0, hi=100000, optional=True)


@dataclass
class EKFParams:
    """The 6-state extended Kalman filter on the verified object (paper, "Object tracking")."""

    ekf_meas_sigma_px: float = param(0.5, "px", "interpretation", "measurement sigma of a "
                                     "centroid", lo=0.0, hi=100.0, lo_open=True)
    ekf_gate_sigma: float = param(5.0, "sigma", "interpretation", "innovation gate", lo=1.0,
                                  hi=1e3)
    ekf_accel_psd: float = param(1e-3, "m^2/s^3", "interpretation", "white-acceleration process "
                                 "noise PSD", lo=0.0, hi=1e6, lo_open=True)
    ekf_sigma_pos0: float = param(1000.0, "m", "interpretation", "initial position sigma about "
                                  "the nominal", lo=0.0, hi=1e7, lo_open=True)
    ekf_sigma_vel0: float = param(10.0, "m/s", "interpretation", "initial velocity sigma about "
                                  "the nominal", lo=0.0, hi=1e4, lo_open=True)
    ekf_max_rejects: int | None = param(None, "frames", "proposal", "proposal ekf_reset: frames "
                                        "with an update rejected before the covariance is reset "
                                        "(0: never)", kind="int", lo=0, hi=10 ** 6, optional=True)
    j2: bool = param(True, "-", "interpretation", "J2 in the plant (nominal propagation and EKF)",
                     kind="bool")
    max_step: float = param(0.5, "s", "interpretation", "longest RK4 step", lo=0.01, hi=10.0)


@dataclass
class OpportunityTrack:
    """The alpha-beta track of a target of opportunity (paper: "no velocity filtering. The
    highest-ranked candidate observation that falls within the angular tracking gate window is
    input to a simpler alpha-beta tracking filter")."""

    opp_alpha: float = param(0.25, "1", "interpretation", "position gain (the gates' alpha)",
                             lo=0.0, hi=1.0, lo_open=True)
    opp_beta: float = param(0.25 ** 2 / (2.0 - 0.25), "1", "interpretation", "velocity gain "
                            "(Benedict-Bordner: alpha^2 / (2 - alpha))", lo=0.0, hi=2.0,
                            hi_open=True)
    opp_gate_px: float = param(8.0, "px", "interpretation", "half-width of the angular gate",
                               lo=0.5, hi=256.0)
    opp_n_lost: int = param(6, "frames", "interpretation", "frames without an observation before "
                            "the track is dropped", kind="int", lo=1, hi=1000)
    opp_startup: bool | None = param(None, "-", "proposal", "proposal opp_startup: growing-memory "
                                     "start-up gains for a new track", kind="bool", optional=True)


@dataclass
class Aim:
    """Where the pointing puts the held object (the paper's TP points at it)."""

    aim_row_px: float | None = param(None, "px", "proposal", "proposal aim_offset: rows off the "
                                     "pixel +X body falls on", lo=-4.0, hi=4.0, optional=True)
    aim_col_px: float | None = param(None, "px", "proposal", "proposal aim_offset: columns off "
                                     "that pixel", lo=-4.0, hi=4.0, optional=True)
    aim_scan_px: float | None = param(None, "px", "proposal", "proposal aim_scan: radius of the "
                                      "circle the aim point follows while held", lo=0.0, hi=2.0,
                                      optional=True)
    aim_scan_frames: int = param(32, "frames", "proposal", "proposal aim_scan: frames of one "
                                 "circle", kind="int", lo=3, hi=100000)


@dataclass
class Timing:
    """The TP's clock."""

    frame_dt: float = param(0.5, "s", "paper", "frame period (2 Hz): the prediction horizon of "
                            "the feedback and pointing", lo=0.0, hi=60.0, lo_open=True)
    max_coast_s: float = param(10.0, "s", "interpretation", "a time gap longer than this deletes "
                               "every gate (the EKF keeps predicting)", lo=0.0, hi=3600.0,
                               lo_open=True)


@dataclass
class InputChecks:
    """The TP's checks on the attitude data it is given."""

    max_rate: float = param(0.2, "rad/s", "interpretation", "attitude rates above this are out of "
                            "range (attitude treated as invalid)", lo=0.0, hi=10.0, lo_open=True)
    quat_norm_tol: float = param(1e-3, "1", "interpretation", "accepted deviation of the attitude "
                                 "quaternion's norm from 1", lo=0.0, hi=0.5, lo_open=True)
    max_time_skew: float = param(0.25, "s", "interpretation", "largest accepted |attitude time - "
                                 "frame time|", lo=0.0, hi=60.0)


#: part attribute of :class:`TPConfig` -> its class, in order
PARTS = {"gates": Gates, "rules": Rules, "ekf": EKFParams, "opportunity": OpportunityTrack,
         "aim": Aim, "timing": Timing, "checks": InputChecks}
#: flat parameter name -> the part that declares it
PART_OF = {f.name: part for part, cls in PARTS.items() for f in dataclasses.fields(cls)}


class TPConfig:
    """Track processor configuration: the event's description and the declared parts.

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
    proposals : tuple of str
        The TP proposals in force (names of :data:`flightsw.proposals.PROPOSALS`; ``"all"``
        expands): ``rule_guards``, ``rule5``, ``ekf_reset``, ``opp_startup``, ``aim_offset``,
        ``aim_scan``; the IP's two floor proposals are accepted and do nothing here. Default ():
        the paper's TP. A proposal's parameter set away from its off value while the proposal is
        off is refused.
    gates, rules, ekf, opportunity, aim, timing, checks : the part, optional
        A part given whole (default: the part's declared defaults).
    **params
        Any declared parameter by its flat name (:data:`PART_OF`), applied over the parts.

    ``ValueError`` names the field (``TPConfig.gate_px=...``) on the first bad value.
    """

    def __init__(self, imagers, mode: str = "dedicated", object_type: str = "satellite",
                 nominal: NominalTrajectory | None = None, proposals=(), **params):
        self.imagers, self.mode, self.object_type, self.nominal = imagers, mode, object_type, nominal
        self.proposals = expand(proposals, "TPConfig.proposals")
        for part, cls in PARTS.items():
            given = params.pop(part, None)
            if given is not None and not isinstance(given, cls):
                raise ValueError(f"TPConfig.{part} must be a {cls.__name__}, got "
                                 f"{type(given).__name__}")
            object.__setattr__(self, part, dataclasses.replace(given) if given else cls())
        for name, v in params.items():
            if name not in PART_OF:
                raise ValueError(f"TPConfig: unknown parameter {name!r}")
            setattr(getattr(self, PART_OF[name]), name, v)
        for name in TP_PROPOSALS:                   # a parameter left None: its proposal's value
            for fld, on in PROPOSALS[name].on.items():
                if getattr(self, fld) is None:
                    setattr(self, fld, on if name in self.proposals else PROPOSAL_OFF[fld])
        self.validate()

    # ---- flat reads and writes go to the part that declares the parameter ------------------------
    def __getattr__(self, name):
        part = PART_OF.get(name)
        if part is None or part not in self.__dict__:
            raise AttributeError(f"TPConfig has no attribute {name!r}")
        return getattr(self.__dict__[part], name)

    def __setattr__(self, name, value):
        part = PART_OF.get(name)
        if part is not None:
            setattr(self.__dict__[part], name, value)
        else:
            object.__setattr__(self, name, value)

    def __eq__(self, other):
        return isinstance(other, TPConfig) and self.as_dict() == other.as_dict()

    def __repr__(self):
        return (f"TPConfig(mode={self.mode!r}, object_type={self.object_type!r}, imagers="
                f"{sorted(self.imagers)}, proposals={self.proposals}, "
                + ", ".join(f"{p}={getattr(self, p)!r}" for p in PARTS) + ")")

    def replace(self, **changes) -> "TPConfig":
        """A copy with ``changes`` (flat parameter names, parts or the description's fields)
        applied and checked; ``ValueError`` naming the field."""
        kw = {"imagers": self.imagers, "mode": self.mode, "object_type": self.object_type,
              "nominal": self.nominal, "proposals": self.proposals}
        kw.update({p: getattr(self, p) for p in PARTS})
        kw.update(changes)
        return TPConfig(**kw)

    def as_dict(self) -> dict:
        """Every declared parameter by its flat name -> value (the parts flattened)."""
        return {name: getattr(self, name) for name in PART_OF}

    @staticmethod
    def defaults() -> dict:
        """Every declared parameter's default, by flat name (None: its proposal decides)."""
        return {f.name: f.default for cls in PARTS.values() for f in dataclasses.fields(cls)}

    @staticmethod
    def describe() -> list[dict]:
        """Every declared parameter: ``{"name", "part", "default", "unit", "class", "doc"}``."""
        return [{"name": f.name, "part": part, "default": f.default, "unit": f.metadata["unit"],
                 "class": f.metadata["class"], "doc": f.metadata["doc"]}
                for part, cls in PARTS.items() for f in dataclasses.fields(cls)]

    @property
    def rule_guards(self) -> bool:
        """The rule guards (proposal ``rule_guards``) are in force."""
        return "rule_guards" in self.proposals

    @property
    def aim_on(self) -> bool:
        """The pointing is aimed off the object (proposals ``aim_offset`` or ``aim_scan``)."""
        return "aim_offset" in self.proposals or "aim_scan" in self.proposals

    def check_proposals(self) -> None:
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
        for part, cls in PARTS.items():
            obj = getattr(self, part)
            for f in dataclasses.fields(cls):
                setattr(obj, f.name, check_value(f.name, getattr(obj, f.name), f.metadata))
        self.check_proposals()
        return self
