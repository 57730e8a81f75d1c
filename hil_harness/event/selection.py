"""Onboard imager and record selection (MSX paper, "Image processing algorithms": "One of the four
imagers is selected for input to the IP; onboard control logic and ground commands determine which
imager is used as well as the criteria for switching from one imager to another").

The logic, with every criterion an uplinkable parameter of :class:`SelectionParams`:

* **acquire** in the scenario's imager (normally a wide field of view);
* **hand over** to the narrow-FOV imager of the same band once the track processor has held its lock
  for ``handover_lock_frames`` consecutive frames *and* its predicted object lies inside the narrow
  field with ``handover_margin_px`` (wide-FOV pixels) to spare -- off by default, as on a dedicated
  event the imager is part of the plan;
* **fall back** to the acquisition imager after ``fallback_unlocked_frames`` consecutive frames
  without lock in the narrow field;
* a **ground command** (the scenario's ``[faults] imager_switch``) forces an imager at a time and
  suspends the automatic logic for the rest of the event.

The IP holds the shipped record of every object type (:func:`power_on_store`) and a table object type
-> record; the event's record (the scenario's object type's, :data:`RECORD_FOR_TYPE`, or the user's
``--record``) is the entry for the event's type. After each frame the IP ranks with the record the
table gives for the object type the TP feeds back (:mod:`flightsw.ip.record_table`): the paper's IP
"can dynamically change which a priori feature record is used from information supplied by the TP".

Every switch is returned as a :class:`Switch` with its reason, and the harness records it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: object type (the scenario's) -> shipped a priori record name. Aurora: the paper's Table 1
#: (record ``aurora``: "used the a priori feature record listed in Table 1 for all image
#: sequences"); ``aurora_surge``, tuned in closed loop with the ``aurora_track`` sequence, is an
#: operator choice (``--record aurora_surge``; figures in ``data/records/README.md``)
RECORD_FOR_TYPE = {"satellite": "satellite", "launch": "plume", "plume": "plume",
                   "aurora": "aurora", "star": "star", None: "star", "": "star",
                   "none": "star"}

#: narrow-FOV partner of each wide-FOV imager (same band)
NARROW_OF = {"wfov_vis": "nfov_vis", "wfov_uv": "nfov_uv"}


@dataclass
class SelectionParams:
    """Uplinkable imager-selection criteria.

    Attributes
    ----------
    handover : bool
        Enable the wide -> narrow FOV hand-over.
    handover_lock_frames : int
        Consecutive locked frames before the hand-over.
    handover_margin_px : float
        The predicted object must be this far (wide-FOV pixels) inside the narrow field.
    fallback_unlocked_frames : int
        Consecutive unlocked frames in the narrow field before falling back to the wide field.
    """

    handover: bool = False
    handover_lock_frames: int = 10
    handover_margin_px: float = 4.0
    fallback_unlocked_frames: int = 4

    def __post_init__(self):
        for name in ("handover_lock_frames", "fallback_unlocked_frames"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"SelectionParams.{name}={v!r} must be an int >= 1")
        if not np.isfinite(self.handover_margin_px) or self.handover_margin_px < 0:
            raise ValueError(f"SelectionParams.handover_margin_px={self.handover_margin_px!r} must be "
                             f">= 0")


@dataclass
class Switch:
    """One imager or record switch: frame, time, what, from, to, why."""

    frame: int
    t: float
    kind: str            # "imager" or "record"
    old: str
    new: str
    reason: str


@dataclass
class ImagerSelector:
    """The onboard imager selection state machine (``reset`` / ``update`` cycle).

    Parameters
    ----------
    initial : str
        Acquisition imager id.
    params : SelectionParams
    ground : list of (t, imager id)
        Ground commands, sorted by time.
    geometry : dict, optional
        imager id -> (scale_col, scale_row, q_imager_to_body) used to test whether a predicted wide-FOV
        pixel lies inside the narrow field (both boresights assumed co-aligned unless the alignments
        say otherwise).
    """

    initial: str
    params: SelectionParams = field(default_factory=SelectionParams)
    ground: list = field(default_factory=list)
    geometry: dict = field(default_factory=dict)

    def __post_init__(self):
        self.reset()

    def reset(self):
        self.current = self.initial
        self._locked_run = 0
        self._unlocked_run = 0
        self._ground_i = 0
        self.forced = False
        self.switches: list[Switch] = []

    def _switch(self, frame, t, new, reason):
        sw = Switch(int(frame), float(t), "imager", self.current, new, reason)
        self.switches.append(sw)
        self.current = new
        self._locked_run = 0
        self._unlocked_run = 0
        return sw

    def _inside_narrow(self, row, col, wide, narrow) -> bool:
        g = self.geometry
        if wide not in g or narrow not in g:
            return False
        rn, cn = convert_pixel(row, col, g[wide], g[narrow])
        if not (np.isfinite(rn) and np.isfinite(cn)):
            return False
        m_c = self.params.handover_margin_px * g[wide][0] / g[narrow][0]
        m_r = self.params.handover_margin_px * g[wide][1] / g[narrow][1]
        return bool(m_c <= cn <= 256 - m_c and m_r <= rn <= 244 - m_r)

    def update(self, frame: int, t: float, locked: bool, pred_row: float = np.nan,
               pred_col: float = np.nan) -> Switch | None:
        """Apply ground commands due by ``t`` and the automatic logic after a frame whose TP output
        was ``locked`` with prediction ``(pred_row, pred_col)`` in the current imager's pixels; returns
        the switch made (the imager for the *next* frame) or None."""
        sw = None
        while self._ground_i < len(self.ground) and t + 1e-9 >= self.ground[self._ground_i][0]:
            new = self.ground[self._ground_i][1]
            self._ground_i += 1
            self.forced = True
            if new != self.current:
                sw = self._switch(frame, t, new, "ground command")
        if sw is not None or self.forced:
            return sw
        p = self.params
        self._locked_run = self._locked_run + 1 if locked else 0
        self._unlocked_run = 0 if locked else self._unlocked_run + 1
        narrow = NARROW_OF.get(self.current)
        if p.handover and narrow and self.current == self.initial:
            if self._locked_run >= p.handover_lock_frames and self._inside_narrow(
                    pred_row, pred_col, self.current, narrow):
                return self._switch(frame, t, narrow,
                                    f"locked {p.handover_lock_frames} frames and the predicted object "
                                    f"is inside the narrow field")
        if self.current != self.initial and self._unlocked_run >= p.fallback_unlocked_frames:
            return self._switch(frame, t, self.initial,
                                f"no lock for {p.fallback_unlocked_frames} frames in {self.current}")
        return None


def convert_pixel(row: float, col: float, g_from, g_to) -> tuple[float, float]:
    """A full-resolution pixel of one imager -> the same direction in another imager's pixels.

    ``g_from``, ``g_to``: ``(scale_col, scale_row, q_imager_to_body)`` (rad/pixel, rad/pixel, scalar-first
    quaternion). Uses the pixel convention of ``flightsw.messages``. NaN in -> NaN out; a direction
    behind the second imager -> NaN.
    """
    if not (np.isfinite(row) and np.isfinite(col)):
        return float("nan"), float("nan")
    from groundsim.quat import q_to_dcm
    sc_a, sr_a, qa = g_from
    sc_b, sr_b, qb = g_to
    v = np.array([1.0, (col - 128.0) * sc_a, (row - 122.0) * sr_a])
    b = q_to_dcm(np.asarray(qa, float)) @ (v / np.linalg.norm(v))
    n = q_to_dcm(np.asarray(qb, float)).T @ b
    if n[0] <= 0:
        return float("nan"), float("nan")
    return float(122.0 + n[2] / n[0] / sr_b), float(128.0 + n[1] / n[0] / sc_b)


def power_on_store(store: dict | None = None) -> tuple[list, dict]:
    """The records the IP holds at power-on and its table object type -> record id
    (:mod:`flightsw.ip.record_table`): the shipped record of every object type of
    :data:`RECORD_FOR_TYPE` (a recording's ``store``, ``{"records": [words...], "table": {...}}``,
    when given: what the event ran with)."""
    from flightsw.ip.record_table import TABLE_TYPES
    from flightsw.records import Record, load_record
    if store is not None:
        recs = [Record.from_words(np.asarray(w, np.int64), name=str(n))
                for n, w in zip(store["names"], store["records"])]
        return recs, {str(t): int(i) for t, i in store["table"].items()}
    names = list(dict.fromkeys(RECORD_FOR_TYPE[t] for t in TABLE_TYPES if t in RECORD_FOR_TYPE))
    recs = [load_record(n) for n in names]
    ids = {r.name: r.record_id for r in recs}
    return recs, {t: ids[RECORD_FOR_TYPE[t]] for t in TABLE_TYPES if t in RECORD_FOR_TYPE}


def record_name_for(object_type) -> str:
    """The shipped a priori record for an object type (unknown types -> the star record)."""
    return RECORD_FOR_TYPE.get(object_type, "star")
