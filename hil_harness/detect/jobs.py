"""The jobs ``uvisi detect`` offers (star, streak, aurora, aurora_allsky): which shipped sequence
goes with a record, sequences by name or file, the star job's significance gate, and the part of a
fisheye field a job keeps.

Public: :func:`resolve_sequence`, :func:`job_sequence_name`, :func:`default_sequence_name`,
:func:`peak_gate_record`, :func:`tile_for`, :func:`field_scale`, :data:`JOBS`, :data:`GATE_SIGMA`,
:data:`EXTENDED_TILE`, :data:`JOB_FIELD_SCALE`.
"""
from __future__ import annotations


__all__ = ["JOBS", "GATE_SIGMA", "GATE_TOP", "EXTENDED_TILE", "JOB_FIELD_SCALE", "FIELD_SPARE",
           "resolve_sequence", "job_sequence_name", "default_sequence_name", "peak_gate_record",
           "tile_for", "field_scale"]

def __getattr__(name):
    """``resolve_sequence`` stays importable from here (it was public here before) without loading
    the flight code when only :data:`JOBS` is read (``uvisi --help`` builds its text from it)."""
    if name == "resolve_sequence":
        from hil_harness.sequences import resolve_sequence
        return resolve_sequence
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: job -> (shipped sequence, shipped record, when to use it)
JOBS = {
    "star": ("star", "star",
             "point sources (stars, distant satellites, any unresolved spot): compaction 1, "
             "centroids to a few hundredths of a pixel, brightest first; on a fisheye frame the "
             "sky above 15 deg elevation"),
    "streak": ("streak", "streak",
               "elongated trails (satellites or meteors crossing the frame, 80 px and longer, "
               "standing out of the sky): compaction 4, one candidate per trail with its "
               "orientation"),
    "aurora": ("aurora", "aurora",
               "extended glow (auroral arcs and surges in UV frames): compaction 2, no detrend"),
    "aurora_allsky": ("aurora_allsky", "aurora_allsky",
                      "the brightest auroral structure in a ground all-sky (fisheye) frame: "
                      "tuned on real THEMIS frames"),
}

#: the star job's gate: a candidate's peak in the smoothed, detrended image must be at least this
#: many pixel-noise sigmas (noise of the processed image, :func:`hil_harness.images.noise_sigma`)
GATE_SIGMA = 4.5
#: upper end of the gate window (above any 12-bit peak)
GATE_TOP = 8192.0


#: full-frame tile (compacted pixels) for the sequences of extended objects: one trail or one
#: auroral form stays in one window (point sources use detect.fullframe.DEFAULT_TILE, 64)
EXTENDED_TILE = {"streak": 128, "aurora": 128, "aurora_allsky": 128}


#: candidates the flight IP is asked for beyond ``--max-candidates`` when a field drops some
FIELD_SPARE = 64

#: the ground-side field of a job, as a fraction of the fisheye circle found in the frame (jobs not
#: named: 1, the whole circle; an equidistant lens puts elevation e at (90 - e) / 90 of the radius).
#: aurora_allsky: 0.7 of the radius, elevations above ~27 deg -- the horizon ring below it
#: (brightened by the slant path through the emitting layer, obstructions, lights, moonlight) is
#: not a pointing target; it is the region the Gillam 2008 labels were drawn in
#: (data/labels/README.md), chosen before any tuning. star: elevations above 15 deg, a common
#: horizon cut of all-sky star work (below it ~4 airmasses dim the stars while trees, lights and
#: twilight glow pass the peak gate first); the cut of the Gakona mask and catalogue list of
#: data/real/. A frame with no fisheye circle (a star tracker, a telescope) keeps its whole field.
JOB_FIELD_SCALE = {"aurora_allsky": 0.7, "star": 75.0 / 90.0}


def field_scale(record) -> float:
    """The fraction of a found fisheye circle a record's job keeps (:data:`JOB_FIELD_SCALE`, by
    the record's name as :func:`default_sequence_name` picks the job; 1 for the others)."""
    return JOB_FIELD_SCALE.get(record.name, 1.0)


def tile_for(seq) -> int:
    """Full-frame tile size (compacted pixels) for a ProcessingSequence, by its name."""
    from hil_harness.detect.fullframe import DEFAULT_TILE
    return EXTENDED_TILE.get(seq.name, DEFAULT_TILE)


def job_sequence_name(record) -> str | None:
    """The shipped sequence of the job whose record ``record`` is (:data:`JOBS`, by name), or
    None for a record of no job."""
    return next((seq for seq, rec, _ in JOBS.values() if record.name == rec), None)


def default_sequence_name(record) -> str:
    """The shipped sequence for a record: the job's own for the job records (star, streak,
    aurora, aurora_allsky), by object type otherwise (aurora -> aurora, satellite -> satellite,
    else star)."""
    return job_sequence_name(record) or {"aurora": "aurora", "satellite": "satellite"}.get(
        record.object_type, "star")


def peak_gate_record(record, noise_counts: float, sigma: float = GATE_SIGMA):
    """The star job's ranking record: ``record`` with one weighted feature, ``max_brightness``,
    turned into a window ``[cut, GATE_TOP]`` with ``cut = sigma * noise_counts``.

    Mean ``(cut + top) / 2``, sigma ``(top - cut) / 2``, weight 1 (n = 1) and GOF threshold 0.5:
    ``d = ((x - mean) / sigma)^2 <= 1`` exactly when ``cut <= x <= top``, and the flight GOF
    ``exp(-d^2 ln 2)`` is 0.5 at the cut and grows with the peak, so the ranking is brightest
    first. The other features keep their values with weight 0. ``noise_counts``: pixel noise of
    the processed (compacted) image in counts. Returns a new Record (same name, id, version).
    """
    from flightsw.messages import FEATURE_NAMES
    if not noise_counts > 0:
        raise ValueError(f"noise_counts={noise_counts!r} must be > 0")
    cut = float(sigma) * float(noise_counts)
    if not 0 < cut < GATE_TOP:
        raise ValueError(f"gate cut {cut:.6g} counts is outside 0..{GATE_TOP:g}")
    i = FEATURE_NAMES.index("max_brightness")

    def put(values, v):
        out = list(values)
        out[i] = v
        return tuple(out)

    return record.replace(
        mean=put(record.mean, (cut + GATE_TOP) / 2.0),
        sigma=put(record.sigma, (GATE_TOP - cut) / 2.0),
        weight=tuple(1.0 if k == i else 0.0 for k in range(len(FEATURE_NAMES))),
        lower=put(record.lower, cut), upper=put(record.upper, GATE_TOP),
        gof_threshold=0.5)
