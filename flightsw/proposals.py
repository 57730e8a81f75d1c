"""Proposals: candidate flight-software changes the MSX paper's system did not have.

The flight code's default is the paper's system (``docs/fidelity.md`` classes every behaviour).
Each behaviour below was added to the emulator to meet a tracking target on simulated events; it
is kept as a *proposal*: a named change, off by default, that a user switches on alone or with
others (``--with NAME[,NAME...]`` / ``--with all`` on the CLI, ``with = [...]`` under ``[flight]``
in scenario and campaign TOML, ``proposals=(...)`` in Python) and weighs against the flown
baseline with ``uvisi compare``.

A proposal changes only what it names. Its parameters live where the flight code would carry them
(an uplink word of the TP, a word of the IP's sequence uplink, or a :class:`~flightsw.tp.TPConfig`
key), and are accepted only while the proposal is in force: with it off, the parameter keeps its
"off" value and an uplink or file that sets it is refused.

The public names are the eight keys of :data:`PROPOSALS`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Proposal", "PROPOSALS", "ALL", "expand", "applicable", "check_applicable",
           "floor_params", "FLOOR_FIELDS", "sequence_floor_fields", "flight_profile"]


@dataclass(frozen=True)
class Proposal:
    """One candidate flight-software change.

    Attributes
    ----------
    name : str
        Its public name.
    summary : str
        One line: what it changes.
    processor : "ip" | "tp"
        The flight processor it changes.
    modes : tuple of str
        The TP modes whose events it acts on ("dedicated": satellites, launches, stars;
        "opportunity": aurora and ``uvisi track``).
    carrier : str
        The uplink word or configuration key that carries its parameters.
    on : dict
        The parameters' values when it is on (TPConfig fields), for TP proposals.
    evidence : str
        Which families it was chosen on and what it bought there.
    """

    name: str
    summary: str
    processor: str
    modes: tuple
    carrier: str
    evidence: str
    on: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON-ready (``uvisi proposals --json``)."""
        return {"name": self.name, "summary": self.summary, "processor": self.processor,
                "modes": list(self.modes), "carrier": self.carrier, "evidence": self.evidence,
                "parameters": dict(self.on) or floor_params(self.name)}


_BOTH = ("dedicated", "opportunity")
_DED = ("dedicated",)

PROPOSALS: dict[str, Proposal] = {p.name: p for p in (
    Proposal(
        "alpha_floor_sparse",
        "without lock, on a frame with fewer than sparse_blobs blobs, alpha may fall below the "
        "sequence's alpha_min, as far as alpha_min_sparse",
        "ip", _BOTH,
        "sequence uplink words 14-15 (threshold step alpha_min_sparse, sparse_blobs); "
        "satellite_track: 0.25 under 20 blobs",
        "satellite training family (seeds 211-225, satellite_track): the magnitude-8.1 target "
        "satellite_train_faint_far decided on 14 of 15 events instead of 1; every other training "
        "event held the same frames"),
    Proposal(
        "alpha_floor_locked",
        "while the TP holds lock, on a frame with fewer than locked_blobs blobs, alpha steps down "
        "below the sequence's alpha_min, as far as alpha_min_locked",
        "ip", _BOTH,
        "sequence uplink words 16-17 (threshold step alpha_min_locked, locked_blobs); "
        "satellite_track: 0.5 under 60 blobs",
        "satellite training family (seeds 211-225, 75 events, satellite_track): held after lock "
        "10849/11151 (97.3 %) against 10710/11151 (96.0 %); goal met on 58/75 either way"),
    Proposal(
        "rule_guards",
        "rules 1 and 2 ask the populated gate's accumulated residual within the threshold; rule 3 "
        "asks the object gate populated n successive frames; rule 4 asks the star gate populated",
        "tp", _DED,
        "TPConfig.proposals (configuration word C_RULE_GUARDS; no uplink code)",
        "synthetic streams of tests/tp (1000 events): the rules as stated decide a star or a "
        "clutter point as the object in 2-5 % of events, with the guards ~0.2 %; rule 3's n frames "
        "after one stray blob verified a noise pair on a fresh satellite evaluation event"),
    Proposal(
        "rule5",
        "a fifth, a priori rule: a pair undecided after n_apriori populated frames is decided by "
        "position (the object if it holds the observation nearest the nominal's prediction)",
        "tp", _DED, "TP uplink code 19 (n_apriori; 0: off)",
        "satellite families: decides faint targets whose stars hardly move against them (eval9 "
        "slow_faint_high was never decided without it); 40 frames is the smallest count that "
        "changes nothing on the satellite training family",
        on={"n_apriori": 40}),
    Proposal(
        "ekf_reset",
        "the EKF's covariance is reset to its initial value after ekf_max_rejects successive "
        "frames with an innovation refused on either axis",
        "tp", _DED, "TP uplink code 10 (ekf_max_rejects; 0: off)",
        "satellite_train_mid_offset seed 220: without it the EKF refused every row centroid and "
        "predicted 2 px off for 170 frames (median error 1.9 processed px); 6 frames reset it "
        "during star crossings, 12 did not",
        on={"ekf_max_rejects": 12}),
    Proposal(
        "opp_startup",
        "a new target-of-opportunity track weighs its first observations with the growing-memory "
        "(least-squares) start-up gains instead of the steady alpha-beta",
        "tp", ("opportunity",), "TPConfig.opp_startup (configuration key; no uplink code)",
        "aurora training families (campaigns/aurora_train_events.toml and aurora_train2): the "
        "steady gains lag a moving spot by ~v dt / alpha for tens of frames after acquisition",
        on={"opp_startup": True}),
    Proposal(
        "aim_offset",
        "the pointing puts the target on the centre of a compacted pixel (aim_row_px, "
        "aim_col_px imager px off +X's pixel) instead of on the boresight",
        "tp", _DED, "TP uplink codes 20, 21 (aim_row_px, aim_col_px; 0, 0: off)",
        "ten seen satellite evaluation families: goal met on 104/114 events against 98/114 aimed "
        "at (0.8, 0.67); eval9 slow_faint_high held 286/314 frames against 100/390",
        on={"aim_row_px": 1.0, "aim_col_px": 1.0}),
    Proposal(
        "aim_scan",
        "while an object is held the aim point circles (a dither) of aim_scan_px every "
        "aim_scan_frames frames, so a one-pixel target's centroids average to the truth",
        "tp", _DED, "TP uplink codes 22, 23 (aim_scan_px, aim_scan_frames; 0 px: off)",
        "satellite training family (seeds 211-225): goal met on 60 of 75 events against 58; "
        "satellite_train_faint_far median errors at most 0.25 processed px on 13 of 15 events "
        "against 3",
        on={"aim_scan_px": 0.5}),
)}

#: every proposal's name, sorted (what ``--with all`` expands to)
ALL = tuple(sorted(PROPOSALS))

#: the sequence's threshold-step fields each IP proposal carries (their words 14-17)
FLOOR_FIELDS = {"alpha_floor_sparse": ("alpha_min_sparse", "sparse_blobs"),
                "alpha_floor_locked": ("alpha_min_locked", "locked_blobs")}
#: the floors' values for the shipped sequences they were chosen with (an operator sets them for
#: another sequence in its threshold step, accepted only while the proposal is on)
_FLOORS_BY_SEQUENCE = {
    "alpha_floor_sparse": {"satellite_track": {"alpha_min_sparse": 0.25, "sparse_blobs": 20}},
    "alpha_floor_locked": {"satellite_track": {"alpha_min_locked": 0.5, "locked_blobs": 60}},
}


def floor_params(name: str, sequence_name: str | None = None) -> dict:
    """The floor fields a floor proposal gives the shipped sequence ``sequence_name`` ({} for a
    sequence it has no values for); with no sequence name, {sequence name: fields}."""
    table = _FLOORS_BY_SEQUENCE.get(name, {})
    if sequence_name is None:
        return {k: dict(v) for k, v in table.items()}
    return dict(table.get(sequence_name, {}))


def sequence_floor_fields() -> tuple:
    """Every threshold-step field a floor proposal carries."""
    return tuple(f for pair in FLOOR_FIELDS.values() for f in pair)


def expand(names, where: str = "--with") -> tuple:
    """Proposal names (an iterable, or one comma-separated string; ``all`` for every one) ->
    the sorted tuple of distinct names; ``ValueError`` naming ``where`` on an unknown name."""
    if names is None:
        return ()
    if isinstance(names, str):
        names = [n for n in names.split(",")]
    out = set()
    for n in names:
        if not isinstance(n, str):
            raise ValueError(f"{where}: {n!r} is not a proposal name; known: {', '.join(ALL)}")
        n = n.strip()
        if n == "all":
            out.update(ALL)
        elif n in PROPOSALS:
            out.add(n)
        elif n:
            raise ValueError(f"{where}: unknown proposal {n!r}; known: {', '.join(ALL)}, all")
    return tuple(sorted(out))


def applicable(name: str, mode: str) -> bool:
    """Whether the proposal ``name`` acts on an event whose TP runs in ``mode``."""
    return mode in PROPOSALS[name].modes


def check_applicable(names, mode: str, where: str = "--with") -> tuple:
    """Expand ``names`` and refuse (``ValueError`` naming ``where``) one named explicitly that a
    ``mode`` event never uses; ``all`` is always accepted (it records all eight)."""
    listed = [names] if isinstance(names, str) else list(names or ())
    explicit = [n.strip() for item in listed for n in str(item).split(",") if n.strip() != "all"]
    got = expand(names, where)
    for n in explicit:
        if n and not applicable(n, mode):
            what = "target-of-opportunity" if mode == "opportunity" else "dedicated (velocity-filter)"
            raise ValueError(f"{where}: proposal {n!r} is never used on a {what} event "
                             f"(it acts in {'/'.join(PROPOSALS[n].modes)} mode)")
    return got


def flight_profile(proposals) -> dict:
    """The ``flight`` entry of a run's summary, recording, rows and JSON: ``profile`` "paper" (no
    proposal: the paper's system), "all-proposals" (all eight) or "paper+NAME,NAME"; ``with`` the
    proposals in force, sorted."""
    names = sorted(proposals or ())
    if not names:
        profile = "paper"
    elif tuple(names) == ALL:
        profile = "all-proposals"
    else:
        profile = "paper+" + ",".join(names)
    return {"profile": profile, "with": names}
