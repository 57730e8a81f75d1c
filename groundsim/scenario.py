"""Scenario files (TOML) and the :class:`Scenario` that turns one into frames or a closed-loop
:class:`~groundsim.world.World`.

File layout (all tables but ``[scenario]`` optional; unknown keys are errors)::

    [scenario]   name, description, epoch (ISO UTC), duration (s), seed (int), imager, compaction (1|2|4)
    [spacecraft] orbit: tle = [l1, l2] | kepler = {a_km, ecc, inc_deg, raan_deg, argp_deg, mean_anomaly_deg}
                 | pass_over = {lat_deg, lon_deg, alt_km=900, inc_deg=99, ascending=true, t=0}
                 (default: pass_over lat 0, lon 0); knowledge_bias_urad = [3], knowledge_noise_urad,
                 rate_noise_urad_s, position_noise_m, rate_limit_deg_s, accel_limit_deg_s2, settle_time_s
    [pointing]   mode = "track_target" (nominal trajectory; offset_px = [row, col]) | "inertial" (ra_deg,
                 dec_deg) | "slew" (ra_deg, dec_deg, to_ra_deg, to_dec_deg, start_s, rate_deg_s) |
                 "earth_point" (lat_deg, lon_deg, alt_km); roll_deg
    [target]     type = "satellite" | "launch" | "aurora" | "none" and its keys (see _target_from)
    [imagers.<id>]  per-imager overrides of groundsim.imagers.Imager fields, plus
                 align_error_urad = [3] (truth alignment = onboard alignment rotated by this vector)
    [faults]     dropped_frames = [frame indices], imager_switch = [{t, imager}], attitude_gap = [{t0, t1}],
                 corrupt_candidate = [{frame, bits}], corrupt_command = [{frame, bits}] (bus faults:
                 flip ``bits`` bits of that frame's candidate message / track command)
    [[uplinks]]  t (s), exactly one of record = / sequence = (a shipped name: no slash, no suffix; or
                 a TOML / .words / binary words file inside the scenario's folder: the uplink path
                 rule, :func:`uplink_file`) / table = {object type = record name or id} (the IP's
                 record table), corrupt_bits = N (optional: flip N bits of the uplink words, a
                 corrupted uplink the IP must refuse)
    [background] earth_glow = "auto" | true | false
    [flight]     with = [proposal names] (flightsw.proposals; ["all"] for every one): the candidate
                 flight-software changes in force for this scenario (default none: the paper's
                 system); ``--with`` on the command line replaces it

A malformed file raises :class:`ScenarioError` naming the file, the key and the reason.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from .frames import parse_epoch
from .imagers import IMAGER_IDS, Imager, get_imager
from .quat import q_from_rotvec, q_mul, q_normalize
from .target_params import Arc, AuroraParams, LaunchParams

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"
FRAME_DT = 0.5
#: the largest seed (a signed 64-bit integer: recordings keep it as one)
MAX_SEED = 2 ** 63 - 1


class ScenarioError(ValueError):
    """A scenario file is malformed: ``file``, ``key`` (dotted) and ``reason``."""

    def __init__(self, file, key, reason):
        self.file, self.key, self.reason = str(file), key, reason
        super().__init__(f"{file}: {reason}" if key in (None, "", "-") else f"{file}: {key}: {reason}")


class _Table:
    """Typed access to one TOML table, tracking which keys were read (the rest are errors)."""

    def __init__(self, data, file, prefix):
        if not isinstance(data, dict):
            raise ScenarioError(file, prefix, f"expected a table, got {type(data).__name__}")
        self.d, self.file, self.prefix, self.used = data, file, prefix, set()

    def key(self, k):
        return f"{self.prefix}.{k}" if self.prefix else k

    def has(self, k):
        return k in self.d

    def raw(self, k, default=None):
        self.used.add(k)
        return self.d.get(k, default)

    def err(self, k, reason):
        return ScenarioError(self.file, self.key(k), reason)

    def missing(self, k):
        """The error for a missing required key; names a present unknown key that looks like a
        typo of it (``duraton`` for ``duration``)."""
        import difflib
        near = difflib.get_close_matches(k, [x for x in self.d if x not in self.used], n=1, cutoff=0.75)
        hint = f"; the table has {near[0]!r}: a typo of {k!r}?" if near else ""
        return self.err(k, f"missing (required){hint}")

    def num(self, k, default=None, lo=None, hi=None, positive=False):
        self.used.add(k)
        if k not in self.d:
            if default is None:
                raise self.missing(k)
            return float(default)
        v = self.d[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.err(k, f"expected a finite number, got {v!r}")
        if positive and not v > 0:
            raise self.err(k, f"must be > 0, got {v!r}")
        if lo is not None and v < lo:
            raise self.err(k, f"must be >= {lo}, got {v!r}")
        if hi is not None and v > hi:
            raise self.err(k, f"must be <= {hi}, got {v!r}")
        return float(v)

    def int_(self, k, default=None, choices=None, lo=None, hi=None):
        self.used.add(k)
        if k not in self.d:
            if default is None:
                raise self.missing(k)
            return int(default)
        v = self.d[k]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(k, f"expected an integer, got {v!r}")
        if choices is not None and v not in choices:
            raise self.err(k, f"must be one of {list(choices)}, got {v!r}")
        if lo is not None and v < lo:
            raise self.err(k, f"must be >= {lo}, got {v!r}")
        if hi is not None and v > hi:
            raise self.err(k, f"must be <= {hi}, got {v!r}")
        return v

    def str_(self, k, default=None, choices=None):
        self.used.add(k)
        if k not in self.d:
            if default is None:
                raise self.missing(k)
            return default
        v = self.d[k]
        if not isinstance(v, str):
            raise self.err(k, f"expected a string, got {v!r}")
        if choices is not None and v not in choices:
            raise self.err(k, f"must be one of {list(choices)}, got {v!r}")
        return v

    def bool_(self, k, default):
        self.used.add(k)
        v = self.d.get(k, default)
        if not isinstance(v, bool):
            raise self.err(k, f"expected true or false, got {v!r}")
        return v

    def vec(self, k, n, default=None):
        self.used.add(k)
        if k not in self.d:
            if default is None:
                raise self.missing(k)
            return np.asarray(default, float)
        v = self.d[k]
        if (not isinstance(v, list) or len(v) != n
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
            raise self.err(k, f"expected a list of {n} numbers, got {v!r}")
        return np.asarray(v, float)

    def tables(self, k):
        """The array of tables ``k`` ([[k]] in TOML) as a list, [] when absent."""
        v = self.raw(k, [])
        if not isinstance(v, list):
            raise self.err(k, f"expected an array of tables, got {v!r}")
        return v

    def sub(self, k, default=None):
        self.used.add(k)
        if k not in self.d:
            return None if default is None else _Table(default, self.file, self.key(k))
        return _Table(self.d[k], self.file, self.key(k))

    def done(self):
        extra = sorted(set(self.d) - self.used)
        if extra:
            raise self.err(extra[0], "unknown key")


@dataclass
class BusFault:
    """Corrupt ``bits`` bits of a bus message (``"candidate"``: the IP's candidate message,
    ``"command"``: the TP's track command, which also carries the IP's feedback) at frame ``frame``."""

    frame: int
    bits: int
    message: str


@dataclass(frozen=True)
class Uplink:
    """A ground uplink during the event: at ``t`` (s) a record or processing sequence goes to the IP.

    ``source`` is a shipped name, a TOML file or a ``.words`` file (one 4-hex-digit word per line),
    as written in the scenario; ``path`` is the real path of the file it names, inside the scenario
    file's folder (the uplink path rule, :func:`uplink_file`), None for a shipped name.
    ``corrupt_bits`` > 0 flips that many bits of the words before they are sent (a corrupted uplink
    the IP must refuse)."""

    t: float
    kind: str
    source: str
    path: str | None = None
    corrupt_bits: int = 0


@dataclass
class Faults:
    dropped_frames: frozenset = frozenset()
    imager_switch: list = field(default_factory=list)      # [(t, imager_id)] sorted
    attitude_gap: list = field(default_factory=list)       # [(t0, t1)]
    corrupt_candidate: list = field(default_factory=list)  # [BusFault] by frame
    corrupt_command: list = field(default_factory=list)    # [BusFault] by frame

    def imager_at(self, t, initial):
        im = initial
        for ts, iid in self.imager_switch:
            if t + 1e-9 >= ts:
                im = iid
        return im

    def attitude_valid(self, t):
        return not any(t0 - 1e-9 <= t < t1 - 1e-9 for t0, t1 in self.attitude_gap)


@dataclass
class Scenario:
    """A parsed scenario. ``frames()`` iterates ``(t, frame, truth)`` open loop; ``world()`` gives the
    closed-loop :class:`~groundsim.world.World`."""

    name: str
    path: Path
    description: str
    epoch: object
    duration: float
    seed: int
    imager: str
    compaction: int
    spacecraft: dict
    pointing: dict
    target: dict
    imagers: dict                      # id -> Imager (with overrides / alignment errors)
    faults: Faults
    earth_glow: object = "auto"
    raw: dict = field(default_factory=dict, repr=False)
    uplinks: list = field(default_factory=list)            # [Uplink] by time
    flight_with: tuple = ()            # [flight] with: proposal names, sorted (flightsw.proposals)

    # ------------------------------------------------------------------------------------------------
    @classmethod
    def nearest(cls, name) -> str:
        """``"; did you mean a, b?"`` for the shipped scenario names closest to ``name`` (empty
        when none is close): the hint of every "no such scenario" message."""
        import difflib
        close = difflib.get_close_matches(str(name), cls.shipped(), n=3, cutoff=0.6)
        return f"; did you mean {', '.join(close)}?" if close else ""

    @classmethod
    def load(cls, name_or_path, seed=None, uplink_dir=None) -> "Scenario":
        """Load a shipped scenario by name (``groundsim/scenarios/<name>.toml``) or a TOML file by path;
        ``seed`` overrides the file's seed; ``uplink_dir`` replaces the scenario's folder as the one
        its ``[[uplinks]]`` files are read from (the uplink path rule)."""
        p = Path(str(name_or_path))
        if not p.suffix and not p.exists():
            p = SCENARIO_DIR / f"{name_or_path}.toml"
        if not p.exists():
            where = name_or_path if p.parent == SCENARIO_DIR else p
            raise ScenarioError(where, "-", f"no such scenario: not a shipped one nor a file"
                                            f"{cls.nearest(name_or_path)} (uvisi scenarios lists them)")
        try:
            data = tomllib.loads(p.read_text())
        except tomllib.TOMLDecodeError as e:
            raise ScenarioError(p, "-", f"not valid TOML: {e}") from None
        except (OSError, UnicodeDecodeError) as e:
            raise ScenarioError(p, "-", f"cannot read the file ({e.__class__.__name__}: {e})") from None
        return cls.from_dict(data, p, seed=seed, uplink_dir=uplink_dir)

    @classmethod
    def shipped(cls) -> list:
        return sorted(x.stem for x in SCENARIO_DIR.glob("*.toml"))

    @classmethod
    def from_dict(cls, data, path="<dict>", seed=None, uplink_dir=None) -> "Scenario":
        """The scenario a parsed TOML document describes; ``path`` names it in errors, and its folder
        (``uplink_dir`` if given, the working folder for ``"<dict>"``) holds its uplink files."""
        top = _Table(data, path, "")
        sc = top.sub("scenario")
        if sc is None:
            raise ScenarioError(path, "scenario", "missing table [scenario]")
        name = sc.str_("name", default=Path(str(path)).stem)
        desc = sc.str_("description", default="")
        if not sc.has("epoch"):
            raise sc.missing("epoch")
        try:
            epoch = parse_epoch(sc.raw("epoch"))
        except (TypeError, ValueError) as e:
            raise sc.err("epoch", f"expected an ISO-8601 UTC time such as '1997-03-15T03:20:00Z' ({e})") from None
        duration = sc.num("duration", positive=True)
        fseed = sc.int_("seed", default=0, lo=0, hi=MAX_SEED)
        imager = sc.str_("imager", default="wfov_vis", choices=IMAGER_IDS)
        compaction = sc.int_("compaction", default=2, choices=(1, 2, 4))
        sc.done()

        if seed is not None and not (isinstance(seed, (int, np.integer)) and 0 <= seed <= MAX_SEED):
            raise ScenarioError(path, "seed", f"the seed {seed!r} must be an integer in 0..{MAX_SEED}")
        spc = _parse_spacecraft(top.sub("spacecraft", {}))
        pnt = _parse_pointing(top.sub("pointing", {"mode": "inertial", "ra_deg": 0.0, "dec_deg": 0.0}))
        tgt = _parse_target(top.sub("target", {"type": "none"}))
        if pnt["mode"] == "track_target" and tgt["type"] in ("none", "aurora"):
            raise ScenarioError(path, "pointing.mode", f"'track_target' needs a satellite or launch target, "
                                                       f"target.type is {tgt['type']!r}")
        imagers = _parse_imagers(top.sub("imagers", {}))
        faults = _parse_faults(top.sub("faults", {}), duration)
        uplinks = _parse_uplinks(top.raw("uplinks", []), path, duration, uplink_dir)
        bg = top.sub("background", {})
        glow = bg.raw("earth_glow", "auto")
        if glow not in ("auto", True, False):
            raise bg.err("earth_glow", f"must be 'auto', true or false, got {glow!r}")
        bg.done()
        flight_with = _parse_flight(top.sub("flight", {}), path)
        top.done()
        return cls(name=name, path=Path(str(path)), description=desc, epoch=epoch, duration=duration,
                   seed=int(fseed if seed is None else seed), imager=imager, compaction=compaction,
                   spacecraft=spc, pointing=pnt, target=tgt, imagers=imagers, faults=faults, earth_glow=glow,
                   raw=data, uplinks=uplinks, flight_with=flight_with)

    # ------------------------------------------------------------------------------------------------
    @property
    def target_type(self):
        """"satellite", "launch", "aurora" or None."""
        return None if self.target["type"] == "none" else self.target["type"]

    @property
    def tp_mode(self) -> str:
        """The track processor's mode for this target: "opportunity" for aurora (no a priori
        trajectory), else "dedicated"."""
        return "opportunity" if self.target_type == "aurora" else "dedicated"

    @property
    def n_frames(self) -> int:
        return int(math.floor(self.duration / FRAME_DT + 1e-9)) + 1

    def world(self):
        from .world import World
        return World(self)

    def frames(self):
        """Open loop: ``(t, frame uint16[244,256], truth)`` at 2 Hz (dropped frames skipped)."""
        w = self.world()
        w.reset()
        while not w.done:
            if not w.frame_dropped:
                frame, truth = w.render()
                yield w.t, frame, truth
            w.advance(FRAME_DT)

    def config(self) -> dict:
        return dict(name=self.name, imager=self.imager, compaction=self.compaction, seed=self.seed,
                    target_type=self.target_type, duration=self.duration, epoch=self.epoch.isoformat())


# ----------------------------------------------------------------------------------------------------
def _parse_spacecraft(t: _Table) -> dict:
    out = {}
    n_orbit = sum(t.has(k) for k in ("tle", "kepler", "pass_over"))
    if n_orbit > 1:
        raise t.err("tle", "give only one of tle, kepler, pass_over")
    if t.has("tle"):
        v = t.raw("tle")
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, str) for x in v)):
            raise t.err("tle", "expected a list of the two TLE lines")
        out["orbit"] = ("tle", v)
    elif t.has("kepler"):
        k = t.sub("kepler")
        out["orbit"] = ("kepler", dict(a_km=k.num("a_km", positive=True), ecc=k.num("ecc", 0.0, lo=0.0, hi=0.99),
                                       inc_deg=k.num("inc_deg", lo=0, hi=180), raan_deg=k.num("raan_deg", 0.0),
                                       argp_deg=k.num("argp_deg", 0.0), mean_anomaly_deg=k.num("mean_anomaly_deg", 0.0)))
        k.done()
    else:
        k = t.sub("pass_over", {})
        out["orbit"] = ("pass_over", dict(lat_deg=k.num("lat_deg", 0.0, lo=-90, hi=90), lon_deg=k.num("lon_deg", 0.0),
                                          alt_km=k.num("alt_km", 900.0, lo=150.0), inc_deg=k.num("inc_deg", 99.0, lo=0, hi=180),
                                          ascending=k.bool_("ascending", True), t=k.num("t", 0.0)))
        k.done()
    out["knowledge_bias_urad"] = t.vec("knowledge_bias_urad", 3, [0.0, 0.0, 0.0])
    out["knowledge_noise_urad"] = t.num("knowledge_noise_urad", 0.0, lo=0.0)
    out["rate_noise_urad_s"] = t.num("rate_noise_urad_s", 0.0, lo=0.0)
    out["position_noise_m"] = t.num("position_noise_m", 0.0, lo=0.0)
    out["rate_limit_deg_s"] = t.num("rate_limit_deg_s", 1.0, positive=True)
    out["accel_limit_deg_s2"] = t.num("accel_limit_deg_s2", 1.0, positive=True)
    out["settle_time_s"] = t.num("settle_time_s", 4.0, positive=True)
    t.done()
    return out


def _parse_pointing(t: _Table) -> dict:
    mode = t.str_("mode", default="inertial", choices=("track_target", "inertial", "slew", "earth_point"))
    out = {"mode": mode, "roll_deg": t.num("roll_deg", 0.0)}
    if mode == "track_target":
        out["offset_px"] = t.vec("offset_px", 2, [0.0, 0.0])
    elif mode == "inertial":
        out.update(ra_deg=t.num("ra_deg"), dec_deg=t.num("dec_deg", lo=-90, hi=90))
    elif mode == "slew":
        out.update(ra_deg=t.num("ra_deg"), dec_deg=t.num("dec_deg", lo=-90, hi=90), to_ra_deg=t.num("to_ra_deg"),
                   to_dec_deg=t.num("to_dec_deg", lo=-90, hi=90), start_s=t.num("start_s", 0.0),
                   rate_deg_s=t.num("rate_deg_s", positive=True))
    else:
        out.update(lat_deg=t.num("lat_deg", lo=-90, hi=90), lon_deg=t.num("lon_deg"), alt_km=t.num("alt_km", 110.0))
    t.done()
    return out


def _parse_target(t: _Table) -> dict:
    typ = t.str_("type", default="none", choices=("satellite", "launch", "aurora", "none"))
    out = {"type": typ}
    if typ == "satellite":
        n = sum(t.has(k) for k in ("tle", "kepler", "relative"))
        if n != 1:
            raise t.err("tle", "a satellite target needs exactly one of tle, kepler, relative")
        if t.has("tle"):
            v = t.raw("tle")
            if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, str) for x in v)):
                raise t.err("tle", "expected a list of the two TLE lines")
            out["orbit"] = ("tle", v)
        elif t.has("kepler"):
            k = t.sub("kepler")
            out["orbit"] = ("kepler", dict(a_km=k.num("a_km", positive=True), ecc=k.num("ecc", 0.0, lo=0, hi=0.99),
                                           inc_deg=k.num("inc_deg", lo=0, hi=180), raan_deg=k.num("raan_deg", 0.0),
                                           argp_deg=k.num("argp_deg", 0.0), mean_anomaly_deg=k.num("mean_anomaly_deg", 0.0)))
            k.done()
        else:
            k = t.sub("relative")
            out["orbit"] = ("relative", dict(d_alt_km=k.num("d_alt_km", 0.0, lo=-800.0, hi=40000.0), d_phase_deg=k.num("d_phase_deg", 0.0),
                                             d_inc_deg=k.num("d_inc_deg", 0.0), d_raan_deg=k.num("d_raan_deg", 0.0)))
            k.done()
        out["mag_at_1000km"] = t.num("mag_at_1000km", 6.0)
        out["uv_offset"] = t.num("uv_offset", 1.5)
        out["nominal_dt_s"] = t.num("nominal_dt_s", 0.0)
        out["nominal_bias_m"] = t.vec("nominal_bias_m", 3, [0.0, 0.0, 0.0])
    elif typ == "launch":
        kw = {}
        for f in fields(LaunchParams):
            if t.has(f.name):
                kw[f.name] = (tuple(t.vec(f.name, 3)) if f.name == "nominal_bias_m"
                              else t.num(f.name))
        try:
            out["params"] = LaunchParams(**kw)
        except (TypeError, ValueError) as e:
            raise t.err("-", str(e)) from None
        if out["params"].burn_s <= 0 or out["params"].accel0 <= 9.9 or out["params"].mass_ratio <= 1:
            raise t.err("accel0", "need burn_s > 0, accel0 > 9.9 m/s^2 (to lift off) and mass_ratio > 1")
    elif typ == "aurora":
        kw = {}
        for f in fields(AuroraParams):
            if f.name in ("arcs", "sun_eci"):
                continue
            if t.has(f.name):
                kw[f.name] = t.num(f.name)
        if t.has("arcs"):
            arcs_raw = t.raw("arcs")
            if not isinstance(arcs_raw, list) or not arcs_raw:
                raise t.err("arcs", "expected a non-empty array of tables [[target.arcs]]")
            arcs = []
            for i, a in enumerate(arcs_raw):
                at = _Table(a, t.file, t.key(f"arcs[{i}]"))
                akw = {f.name: at.num(f.name) for f in fields(Arc) if at.has(f.name)}
                for nm in ("wavelength_km", "width_km", "period_s"):
                    if nm in akw and akw[nm] <= 0:
                        raise at.err(nm, f"must be > 0, got {akw[nm]}")
                at.done()
                arcs.append(Arc(**akw))
            kw["arcs"] = arcs
        out["params"] = AuroraParams(**kw)
    t.done()
    return out


def _parse_imagers(t: _Table) -> dict:
    out = {}
    names = {f.name for f in fields(Imager)} - {"id", "band", "n_rows", "n_cols", "align", "align_onboard"}
    for iid in list(t.d):
        if iid not in IMAGER_IDS:
            raise t.err(iid, f"unknown imager; expected one of {list(IMAGER_IDS)}")
        it = t.sub(iid)
        kw = {}
        for k in list(it.d):
            if k == "align_error_urad":
                continue
            if k not in names:
                raise it.err(k, f"unknown imager field; expected one of {sorted(names) + ['align_error_urad']}")
            kw[k] = it.int_(k) if k == "adc_max" else it.num(k, positive=k not in ("read_noise_e", "dark_e_per_s", "sky_e_per_s", "bias_dn"), lo=0.0)
        err = it.vec("align_error_urad", 3, [0.0, 0.0, 0.0]) * 1e-6
        base = get_imager(iid)
        kw["align"] = tuple(q_normalize(q_mul(np.asarray(base.align_onboard), q_from_rotvec(err))))
        try:
            out[iid] = base.with_(**kw)
        except ValueError as e:
            raise it.err("-", str(e)) from None
        it.done()
    t.used.update(t.d)
    for iid in IMAGER_IDS:
        out.setdefault(iid, get_imager(iid))
    return out


def _parse_faults(t: _Table, duration) -> Faults:
    df = t.raw("dropped_frames", [])
    if not isinstance(df, list) or not all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in df):
        raise t.err("dropped_frames", f"expected a list of frame indices (integers >= 0), got {df!r}")
    sw = []
    for i, e in enumerate(t.tables("imager_switch")):
        et = _Table(e, t.file, t.key(f"imager_switch[{i}]"))
        sw.append((et.num("t", lo=0.0), et.str_("imager", choices=IMAGER_IDS)))
        et.done()
    gaps = []
    for i, e in enumerate(t.tables("attitude_gap")):
        et = _Table(e, t.file, t.key(f"attitude_gap[{i}]"))
        t0, t1 = et.num("t0", lo=0.0), et.num("t1", lo=0.0)
        if t1 <= t0:
            raise et.err("t1", f"must be > t0 ({t0}), got {t1}")
        et.done()
        gaps.append((t0, t1))
    bus = {}
    for key, message in (("corrupt_candidate", "candidate"), ("corrupt_command", "command")):
        entries = t.raw(key, [])
        if not isinstance(entries, list):
            raise t.err(key, "expected a list of tables {frame = k, bits = N}")
        out = []
        for i, e in enumerate(entries):
            et = _Table(e, t.file, t.key(f"{key}[{i}]"))
            frame = et.int_("frame", lo=0)
            bits = et.int_("bits", default=1, lo=1)
            if bits > 64:
                raise et.err("bits", f"at most 64 bits per message, got {bits}")
            et.done()
            out.append(BusFault(frame, bits, message))
        bus[key] = sorted(out, key=lambda f: f.frame)
    t.done()
    return Faults(frozenset(df), sorted(sw), gaps, bus["corrupt_candidate"], bus["corrupt_command"])


def _parse_flight(ft, file) -> tuple:
    """``[flight] with = [...]`` -> the proposal names (expanded, sorted); unknown names refused."""
    from flightsw.proposals import expand
    names = ft.raw("with", [])
    ft.done()
    if not isinstance(names, list):
        raise ft.err("with", f"expected a list of proposal names, got {type(names).__name__}")
    try:
        return expand(names, "with")
    except ValueError as e:
        raise ScenarioError(file, "flight.with", str(e).split(": ", 1)[1]) from None


def _table_source(et) -> str:
    """``table = {aurora = "aurora_surge", star = 2}`` (object type -> shipped record name or record
    id) -> its source text "aurora=aurora_surge,star=2" (the words are built by the harness)."""
    v = et.raw("table")
    if not isinstance(v, dict) or not v:
        raise et.err("table", "expected a table {object type = record name or id, ...}")
    for k, x in v.items():
        if isinstance(x, bool) or not isinstance(x, (str, int)) or (isinstance(x, str) and not x):
            raise et.err(f"table.{k}", f"{x!r}: expected a shipped record name or a record id")
    return ",".join(f"{k}={x}" for k, x in v.items())


def _parse_uplinks(entries, file, duration, uplink_dir=None) -> list:
    if not isinstance(entries, list):
        raise ScenarioError(file, "uplinks", "expected an array of tables [[uplinks]]")
    if uplink_dir is not None:
        base = Path(uplink_dir).resolve()
    elif str(file).startswith("<"):
        base = Path.cwd().resolve()
    else:
        base = Path(str(file)).resolve().parent
    out = []
    for i, e in enumerate(entries):
        et = _Table(e, file, f"uplinks[{i}]")
        t = et.num("t", lo=0.0)
        if t > duration:
            raise et.err("t", f"{t} is after the end of the event ({duration} s)")
        kinds = [k for k in ("record", "sequence", "table") if et.has(k)]
        if len(kinds) != 1:
            raise et.err("record", "give exactly one of record = ..., sequence = ..., table = ...")
        kind = kinds[0]
        if kind == "table":
            out.append(Uplink(t, kind, _table_source(et), None, et.int_("corrupt_bits", default=0,
                                                                         lo=0)))
            et.done()
            continue
        source = et.str_(kind)
        path = uplink_file(source, base, et, kind, uplink_dir is not None)
        bits = et.int_("corrupt_bits", default=0, lo=0)
        et.done()
        out.append(Uplink(t, kind, source, path, bits))
    return sorted(out, key=lambda u: u.t)


def is_uplink_file(source: str) -> bool:
    """Whether an ``[[uplinks]]`` entry names a file (a slash or a suffix) or a shipped name."""
    return "/" in source or "\\" in source or Path(source).suffix != "" or source in (".", "..")


def uplink_file(source: str, base: Path, et: _Table, kind: str, given: bool = False) -> str | None:
    """The uplink path rule: the real path of the file an ``[[uplinks]]`` entry names, inside
    ``base`` (the scenario file's folder, or ``--uplink-dir``); None for a shipped name. An absolute
    path, a ``..`` or a symlink leading outside ``base`` is refused naming the field, never reading
    the file."""
    if not is_uplink_file(source):
        return None
    where = "the folder given with --uplink-dir" if given else "the scenario's folder"
    rule = f"uplink files are named relative to {where} {str(base)!r} (the uplink path rule)"
    p = Path(source)
    if p.is_absolute() or source.startswith("~"):
        raise et.err(kind, f"{source!r} is an absolute path (or names a home folder): {rule}")
    if ".." in p.parts:
        raise et.err(kind, f"{source!r} is outside {where} ('..'): {rule}")
    try:
        real = (base / p).resolve()
        inside, found = real.is_relative_to(base), real.is_file()
    except (OSError, ValueError, RuntimeError) as exc:   # NUL byte, symlink loop, long name
        raise et.err(kind, f"{source!r} is not a usable file name ({exc.__class__.__name__})") \
            from None
    if not inside:
        raise et.err(kind, f"{source!r} is outside {where} (a symlink leads out): {rule}")
    if not found:
        raise et.err(kind, f"no such file {source!r} in {where} {str(base)!r}")
    return str(real)
