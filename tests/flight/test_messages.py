"""Message codecs (flightsw.messages): word layouts against hand-made words, the CRC against the
standard check value and Python's binascii.crc_hqx, 1750A floats against MIL-STD-1750A's own table,
round-trip properties (hypothesis) and a mutation fuzz of every decoder.

Fuzz size: ``UVISI_FUZZ_CASES`` streams per decoder (default 300; ``make fuzz`` runs 10,000 and a
tenth of that in hypothesis examples per property).
"""
import binascii
import math
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flightsw.arith import m1750 as _m1750
from flightsw.messages import (_CRC_TABLE, CANDIDATE_DTYPE, FEATURE_NAMES, IMAGER_CODES,
                               OBJECT_TYPE_CODES, TC_STATUS_NAMES, CandidateMessage, MessageError,
                               TrackCommand, _crc_range, crc16_ccitt, crc16_ccitt_bytes)
from flightsw.records import Record, RecordError, load_record

FUZZ_CASES = int(os.environ.get("UVISI_FUZZ_CASES", "300"))
FEW, MORE = max(40, FUZZ_CASES // 10), max(150, FUZZ_CASES // 10)   # hypothesis examples


# ------------------------------------------------------------------------------------------------
# oracles: the CRC from the standard library, 1750A values from the closed form M * 2**(E - W)
# ------------------------------------------------------------------------------------------------
def crc_oracle(words) -> int:
    """CRC-16/CCITT-FALSE of 16-bit words fed MSB first: binascii.crc_hqx with init 0xFFFF."""
    return binascii.crc_hqx(np.asarray(words, ">u2").tobytes(), 0xFFFF)


def f1750(mant: int, exp: int, w: int = 23) -> float:
    """Value of a 1750A float from its 2's-complement mantissa (W fraction bits) and exponent."""
    return math.ldexp(mant, exp - w)


def words32(mant: int, exp: int) -> list:
    """The two words of a 32-bit float from the format definition (MIL-STD-1750A 4.1.5)."""
    p = ((mant & 0xFFFFFF) << 8) | (exp & 0xFF)
    return [p >> 16, p & 0xFFFF]


def words48(mant: int, exp: int) -> list:
    """The three words of a 48-bit float (40-bit mantissa, 4.1.6)."""
    m = mant & 0xFFFFFFFFFF
    return [m >> 24, ((m >> 16) & 0xFF) << 8 | (exp & 0xFF), m & 0xFFFF]


@pytest.mark.cases("flightsw.messages._crc_range", "typical")
def test_crc_check_value_and_stdlib_oracle():
    assert binascii.crc_hqx(b"123456789", 0xFFFF) == 0x29B1          # the catalogue check value
    assert crc16_ccitt_bytes(b"123456789") == 0x29B1
    assert crc16_ccitt([0x3132, 0x3334, 0x3536, 0x3738]) == crc_oracle([0x3132, 0x3334, 0x3536,
                                                                         0x3738])
    rng = np.random.default_rng(1)
    for n in (1, 2, 15, 55, 129):
        w = rng.integers(0, 0x10000, n)
        assert crc16_ccitt(w) == crc_oracle(w)
    with pytest.raises(ValueError):
        crc16_ccitt([0x10000])


# MIL-STD-1750A Tables III/IV (docs/processors.md): value, words
STANDARD_32 = [(0.9999998 * 2.0 ** 127, 0x7FFF, 0xFF7F, (0x7FFFFF, 127)),
               (0.5 * 2.0 ** 127, 0x4000, 0x007F, (0x400000, 127)),
               (10.0, 0x5000, 0x0004, (0x500000, 4)), (1.0, 0x4000, 0x0001, (0x400000, 1)),
               (0.5, 0x4000, 0x0000, (0x400000, 0)), (0.25, 0x4000, 0x00FF, (0x400000, -1)),
               (0.5 * 2.0 ** -128, 0x4000, 0x0080, (0x400000, -128)),
               (0.0, 0x0000, 0x0000, (0, 0)), (-1.0, 0x8000, 0x0000, (-0x800000, 0)),
               (-0.5000001 * 2.0 ** -128, 0xBFFF, 0xFF80, (-0x400001, -128)),
               (-0.7500001 * 2.0 ** 4, 0x9FFF, 0xFF04, (-0x600001, 4))]


def _message(k, alpha=3.0):
    c = np.zeros(k, CANDIDATE_DTYPE)
    return CandidateMessage(frame_count=5, time_tag=1.0, imager="nfov_uv", compaction=2,
                            window_row0=-8, window_col0=128, window_rows=64, window_cols=64,
                            alpha=alpha, record_id=7, candidates=c)


@pytest.mark.parametrize("value,w0,w1,mant_exp", STANDARD_32)
@pytest.mark.cases("flightsw.messages._f32_at", "typical")
def test_standard_32_bit_floats_travel_as_the_standards_words(value, w0, w1, mant_exp):
    assert [w0, w1] == words32(*mant_exp)
    exact = f1750(*mant_exp)
    assert exact == pytest.approx(value, rel=2.0 ** -22, abs=0.0)
    w = _message(0, alpha=exact).to_words()
    assert [int(w[11]), int(w[12])] == [w0, w1]                       # alpha, words 11-12
    assert CandidateMessage.from_words(w).alpha == exact


@pytest.mark.cases("flightsw.messages._cand_encode_k", "header", "candidates", "crc")
@pytest.mark.cases("flightsw.messages._cand_check_k", "well-formed")
@pytest.mark.cases("flightsw.messages._cand_fill_k", "typical")
@pytest.mark.cases("flightsw.messages._crc_range", "prefix")
@pytest.mark.cases("flightsw.messages._f48_at", "typical")
def test_candidate_message_hand_made_layout():
    m = _message(1)
    m.candidates["label"] = 0x0102
    m.candidates["distance"] = 10.0                                    # 5000 0004
    m.candidates["gof"] = -1.0                                         # 8000 0000
    m.candidates["size"] = 0.25                                        # 4000 00FF
    w = m.to_words()
    head = [0x4950, 15 + 29 + 1, 5, *words48(0x4000000000, 1), (3 << 8) | 2, 0xFFF8, 128, 64, 64,
            0x6000, 0x0002, 7, 1]                                      # 1.0 = 4000 0001 0000
    body = [0x0102, 0x5000, 0x0004, 0x8000, 0x0000, 0x4000, 0x00FF] + [0] * 22
    assert w.dtype == np.uint16 and w.tolist() == head + body + [crc_oracle(head + body)]
    assert words48(-0x8000000000, -1) == [0x8000, 0x00FF, 0]           # the standard's 48-bit
    assert words48(-0x6000000000, -1) == [0xA000, 0x00FF, 0]           # examples
    assert CandidateMessage.from_words(w) == m


@pytest.mark.cases("flightsw.messages._track_encode_k", "present-groups", "absent-groups",
                   "reserved-and-crc")
@pytest.mark.cases("flightsw.messages._track_check_k", "well-formed")
@pytest.mark.cases("flightsw.messages._group", "all-finite", "all-nan")
def test_track_command_hand_made_layout():
    c = TrackCommand(frame_count=9, time_tag=0.5, imager="wfov_uv", object_type="aurora",
                     locked=True, status=0x0041, n_star_gates=3, n_object_gates=4, decided_frame=2,
                     object_index=-1, mode="opportunity", predicted_row=10.0, predicted_col=1.0,
                     los_eci=np.array([1.0, 0.0, -1.0]))
    w = c.to_words()
    head = [0x5450, 55, 9, 0x4000, 0x0000, 0x0000, (2 << 8) | 5, 0x0041, 0x01 | 0x02 | 0x08 | 0x20,
            3, 4, 2, 0]
    body = ([0] * 8 + [0x5000, 0x0004, 0x4000, 0x0001] + [0x4000, 0x0001, 0, 0, 0x8000, 0x0000]
            + [0] * 22 + [0])
    assert w.tolist() == head + body + [crc_oracle(head + body)]
    assert TrackCommand.from_words(w) == c


# ------------------------------------------------------------------------------------------------
# valid messages (random 1750A values built from the format definition)
# ------------------------------------------------------------------------------------------------
def _f32_values(rng, n):
    """n random 1750A 32-bit values (normalised mantissas, full exponent range, some zeros)."""
    m = rng.integers(0x400000, 0x800000, n) * rng.choice([-1, 1], n)
    m = np.where(m == -0x400000, -0x800000, m)
    e = rng.integers(-128, 128, n)
    v = np.array([f1750(int(a), int(b)) for a, b in zip(m, e)])
    return np.where(rng.random(n) < 0.1, 0.0, v)


def _f48_value(rng):
    m = int(rng.integers(0x4000000000, 0x8000000000)) * int(rng.choice([-1, 1]))
    return 0.0 if rng.random() < 0.05 else f1750(m, int(rng.integers(-128, 128)), 39)


def random_candidate_message(rng, kmax=23):
    k = int(rng.integers(0, kmax + 1))
    c = np.zeros(k, CANDIDATE_DTYPE)
    c["label"] = rng.integers(0, 0x10000, k)
    for name in ("distance", "gof") + FEATURE_NAMES:
        c[name] = _f32_values(rng, k)
    return CandidateMessage(
        frame_count=int(rng.integers(0, 0x10000)), time_tag=_f48_value(rng),
        imager=str(rng.choice(list(IMAGER_CODES))), compaction=int(rng.integers(1, 256)),
        window_row0=int(rng.integers(-32768, 32768)), window_col0=int(rng.integers(-32768, 32768)),
        window_rows=int(rng.integers(0, 0x10000)), window_cols=int(rng.integers(0, 0x10000)),
        alpha=float(_f32_values(rng, 1)[0]), record_id=int(rng.integers(0, 0x10000)), candidates=c)


def _unit_q(rng):
    """A unit quaternion as 1750A 32-bit values (a pointing quaternion: Q_NORM_TOL)."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return np.array([_m1750.decode32(_m1750.encode32(float(x), rounding="nearest")) for x in q])


def random_track_command(rng):
    nan3 = np.full(3, np.nan)
    pred, est, point = rng.random(3) < 0.7
    status = 0
    for bit in TC_STATUS_NAMES:
        status |= bit if rng.random() < 0.3 else 0
    return TrackCommand(
        frame_count=int(rng.integers(0, 0x10000)), time_tag=_f48_value(rng),
        q_point=_unit_q(rng) if point else np.full(4, np.nan),
        predicted_row=float(_f32_values(rng, 1)[0]) if pred else math.nan,
        predicted_col=float(_f32_values(rng, 1)[0]) if pred else math.nan,
        imager=str(rng.choice(list(IMAGER_CODES))),
        object_type=str(rng.choice(list(OBJECT_TYPE_CODES))), locked=bool(rng.random() < 0.5),
        status=status, n_star_gates=int(rng.integers(0, 0x10000)),
        n_object_gates=int(rng.integers(0, 0x10000)),
        decided_frame=int(rng.integers(-1, 0x10000)) if rng.random() < 0.5 else -1,
        object_index=int(rng.integers(-1, 0x10000)) if rng.random() < 0.5 else -1,
        mode="opportunity" if rng.random() < 0.5 else "dedicated",
        los_eci=_f32_values(rng, 3) if pred else nan3,
        r_est=np.array([_f48_value(rng) for _ in range(3)]) if est else nan3,
        v_est=np.array([_f48_value(rng) for _ in range(3)]) if est else nan3,
        sigma_pos=float(_f32_values(rng, 1)[0]) if est else math.nan,
        sigma_vel=float(_f32_values(rng, 1)[0]) if est else math.nan)


def random_record(rng):
    base = load_record(str(rng.choice(["aurora", "star", "satellite", "plume"])))
    return base.replace(record_id=int(rng.integers(0, 0x10000)),
                        version=int(rng.integers(0, 0x10000)),
                        gof_threshold=float(rng.random()), quantize=bool(rng.random() < 0.5))


# ------------------------------------------------------------------------------------------------
# mutation fuzz
# ------------------------------------------------------------------------------------------------
SPECIAL = (0, 1, 0x00FF, 0x0100, 0x7FFF, 0x8000, 0xFFFF, 0x4000, 0xC000)


def mutate(rng, words):
    """One mutation of a valid stream (int64); about 60 % of the results get a re-computed valid
    CRC so that the decoder's meaning checks, not the CRC, are what is fuzzed."""
    w = np.asarray(words, np.int64).copy()
    kind = int(rng.integers(7))
    n = len(w)
    if kind == 0:                                         # flip 1..3 bits
        for _ in range(int(rng.integers(1, 4))):
            w[rng.integers(n)] ^= 1 << int(rng.integers(16))
    elif kind == 1:                                       # one random word
        w[rng.integers(n)] = rng.integers(0, 0x10000)
    elif kind == 2:                                       # a special value in a header word
        w[rng.integers(min(n, 16))] = rng.choice(SPECIAL)
    elif kind == 3:                                       # a special value anywhere
        w[rng.integers(n)] = rng.choice(SPECIAL)
    elif kind == 4:                                       # drop or add words
        if rng.random() < 0.5 and n > 1:
            w = np.delete(w, rng.integers(n))
        else:
            w = np.insert(w, rng.integers(n + 1), rng.integers(0, 0x10000))
    elif kind == 5:                                       # swap two words
        i, j = rng.integers(n, size=2)
        w[i], w[j] = w[j], w[i]
    else:                                                 # several random words
        idx = rng.integers(n, size=int(rng.integers(2, 6)))
        w[idx] = rng.integers(0, 0x10000, len(idx))
    if len(w) > 1 and rng.random() < 0.6:
        w[-1] = crc_oracle(w[:-1])
    return w


def fuzz(decoder_cls, make, error, cases, seed):
    """Counts over ``cases`` mutated streams: crc_valid, accepted, rejected (the module's error),
    foreign (any other exception: list of reprs), mismatch (accepted but re-encoded differently
    or refused by the encoder)."""
    rng = np.random.default_rng(seed)
    out = {"cases": cases, "crc_valid": 0, "accepted": 0, "rejected": 0, "foreign": [],
           "mismatch": []}
    for _ in range(cases):
        w = mutate(rng, make(rng).to_words())
        if len(w) > 1 and crc_oracle(w[:-1]) == w[-1]:
            out["crc_valid"] += 1
        try:
            m = decoder_cls.from_words(w.astype(np.uint16))
        except error:
            out["rejected"] += 1
            continue
        except Exception as exc:                          # noqa: BLE001 - what is counted
            out["foreign"].append(repr(exc))
            continue
        out["accepted"] += 1
        try:
            again = m.to_words()
        except Exception as exc:                          # noqa: BLE001
            out["mismatch"].append(f"encoder refuses: {exc!r}")
            continue
        if not np.array_equal(again.astype(np.int64), w):
            out["mismatch"].append(f"re-encodes differently at words "
                                   f"{np.flatnonzero(again.astype(np.int64) != w)[:5].tolist()}")
    return out


DECODERS = {"candidate": (CandidateMessage, random_candidate_message, MessageError),
            "track": (TrackCommand, random_track_command, MessageError),
            "record": (Record, random_record, RecordError)}


@pytest.mark.parametrize("name", sorted(DECODERS))
def test_fuzz_decoder_only_own_error_and_exact_re_encoding(name):
    cls, make, error = DECODERS[name]
    r = fuzz(cls, make, error, FUZZ_CASES, seed=sum(map(ord, name)))
    assert r["crc_valid"] >= r["cases"] // 2
    assert r["foreign"] == [] and r["mismatch"] == []
    assert r["accepted"] > 0 and r["rejected"] > 0        # both outcomes are reached


def test_decoders_refuse_foreign_input_with_their_own_error():
    good = _message(2).to_words()
    for cls in (CandidateMessage, TrackCommand):
        for bad in (None, "words", [[1, 2], [3]], good.astype(float) + 0.5, good.reshape(2, -1),
                    good.astype(bool), np.array([-1] * 55), np.array([0x10000] * 55),
                    [object()] * 55, np.zeros(0, np.uint16), 7):
            with pytest.raises(MessageError):
                cls.from_words(bad)
    with pytest.raises(RecordError):
        Record.from_words("not words")


# ------------------------------------------------------------------------------------------------
# properties (hypothesis)
# ------------------------------------------------------------------------------------------------
def _st_f(w):
    """1750A values with W fraction bits, from the closed form (normalised mantissa or zero)."""
    top = 1 << w
    mant = st.one_of(st.integers(top >> 1, top - 1), st.integers(-top, -(top >> 1) - 1))
    return st.one_of(st.just(0.0), st.builds(lambda m, e: f1750(m, e, w), mant,
                                             st.integers(-128, 127)))


F32, F48 = _st_f(23), _st_f(39)
U16 = st.integers(0, 0xFFFF)


@st.composite
def candidate_messages(draw):
    k = draw(st.integers(0, 23))
    c = np.zeros(k, CANDIDATE_DTYPE)
    c["label"] = draw(st.lists(U16, min_size=k, max_size=k))
    for name in ("distance", "gof") + FEATURE_NAMES:
        c[name] = draw(st.lists(F32, min_size=k, max_size=k))
    return CandidateMessage(
        frame_count=draw(U16), time_tag=draw(F48), imager=draw(st.sampled_from(list(IMAGER_CODES))),
        compaction=draw(st.integers(1, 255)), window_row0=draw(st.integers(-32768, 32767)),
        window_col0=draw(st.integers(-32768, 32767)), window_rows=draw(U16),
        window_cols=draw(U16), alpha=draw(F32), record_id=draw(U16), candidates=c)


@st.composite
def track_commands(draw):
    def group(n, f):
        return np.array(draw(st.lists(f, min_size=n, max_size=n))) if draw(st.booleans()) \
            else np.full(n, np.nan)
    pred, est = group(5, F32), np.concatenate([group(6, F48), np.full(2, np.nan)])
    if np.isfinite(est[0]):
        est[6:] = draw(st.lists(F32, min_size=2, max_size=2))
    status = draw(st.sets(st.sampled_from(sorted(TC_STATUS_NAMES))))
    q = np.full(4, np.nan)                 # a pointing quaternion is a unit one (Q_NORM_TOL)
    if draw(st.booleans()):
        q = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4)))
        q = q / np.linalg.norm(q) if np.linalg.norm(q) > 0.1 else np.array([1.0, 0.0, 0.0, 0.0])
        q = np.array([_m1750.decode32(_m1750.encode32(float(x), rounding="nearest")) for x in q])
    return TrackCommand(
        frame_count=draw(U16), time_tag=draw(F48), q_point=q,
        predicted_row=float(pred[0]), predicted_col=float(pred[1]), los_eci=pred[2:5],
        imager=draw(st.sampled_from(list(IMAGER_CODES))),
        object_type=draw(st.sampled_from(list(OBJECT_TYPE_CODES))), locked=draw(st.booleans()),
        status=sum(status), n_star_gates=draw(U16), n_object_gates=draw(U16),
        decided_frame=draw(st.integers(-1, 0xFFFF)), object_index=draw(st.integers(-1, 0xFFFF)),
        mode=draw(st.sampled_from(["dedicated", "opportunity"])), r_est=est[0:3], v_est=est[3:6],
        sigma_pos=float(est[6]), sigma_vel=float(est[7]))


@settings(max_examples=FEW, deadline=None)
@given(candidate_messages())
def test_candidate_decode_of_encode_is_identity(m):
    w = m.to_words()
    assert len(w) == 16 + 29 * m.count and w[-1] == crc_oracle(w[:-1])
    assert CandidateMessage.from_words(w) == m


@settings(max_examples=MORE, deadline=None)
@given(track_commands())
def test_track_decode_of_encode_is_identity(c):
    w = c.to_words()
    assert len(w) == 55 and w[-1] == crc_oracle(w[:-1])
    assert TrackCommand.from_words(w) == c


def _accepted_streams_re_encode_exactly(cls, msg, edits, fix_crc):
    w = msg.to_words().astype(np.int64)
    for i, v in edits:
        w[i % len(w)] = v
    if fix_crc:
        w[-1] = crc_oracle(w[:-1])
    try:
        m = cls.from_words(w)
    except MessageError:
        return False
    assert np.array_equal(m.to_words().astype(np.int64), w)
    return True


@settings(max_examples=FEW, deadline=None)
@given(candidate_messages(), st.lists(st.tuples(st.integers(0, 700), U16), min_size=1, max_size=3),
       st.booleans())
def test_candidate_streams_accepted_re_encode_exactly(m, edits, fix_crc):
    _accepted_streams_re_encode_exactly(CandidateMessage, m, edits, fix_crc)


@settings(max_examples=MORE, deadline=None)
@given(track_commands(), st.lists(st.tuples(st.integers(0, 54), U16), min_size=1, max_size=3),
       st.booleans())
def test_track_streams_accepted_re_encode_exactly(c, edits, fix_crc):
    _accepted_streams_re_encode_exactly(TrackCommand, c, edits, fix_crc)


# ------------------------------------------------------------------------------------------------
# each rule, by hand: the error names the word and the field
# ------------------------------------------------------------------------------------------------
def _with_crc(w):
    w = np.asarray(w, np.int64)
    w[-1] = crc_oracle(w[:-1])
    return w


@pytest.mark.parametrize("word,value,match", [
    (6, 0x0300, r"word 6 \(imager/compaction\): compaction 0"),
    (6, 0x0702, r"word 6 \(imager/compaction\): unknown imager code"),
    (3, 0x2000, r"word 3 \(time_tag\): not a normalised"),
    (11, 0xC000, r"word 11 \(alpha\): not a normalised"),
    (11, 0x0000, r"word 11 \(alpha\): not a normalised"),           # zero mantissa, exponent 2
    (16, 0x0000, r"word 16 \(candidate 0 distance\): not a normalised"),
    (19, 0x0001, r"word 18 \(candidate 0 gof\): not a normalised"),   # gof 0.0 -> exponent 1
    (20, 0x2000, r"word 20 \(candidate 0 size\): not a normalised"),
    (14, 24, r"word 14 \(count\): candidate count above 23"),
    (1, 44, r"word 1 \(length\)"), (0, 0x4951, r"word 0 \(id\): wrong message id")])
@pytest.mark.cases("flightsw.messages._cand_check_k", "compaction-zero", "bad-imager",
                   "bad-time-tag", "bad-alpha", "bad-candidate-float", "bad-count", "bad-length",
                   "bad-id")
def test_candidate_rules(word, value, match):
    m = _message(1)
    m.candidates["distance"], m.candidates["size"] = 10.0, 0.25
    w = m.to_words().astype(np.int64)
    w[word] = value
    with pytest.raises(MessageError, match=match) as exc:
        CandidateMessage.from_words(_with_crc(w))
    assert exc.value.word == int(match.split()[1])


@pytest.mark.parametrize("word,value,match", [
    (6, 0x0208, r"word 6 \(imager/object_type\): unknown object type"),
    (8, 0x0080 | 0x2B, r"word 8 \(flags\): undefined bits"),
    (8, 0x2B & ~0x08, r"word 11 \(decided_frame\): reserved or absent"),   # decided flag cleared
    (12, 5, r"word 12 \(object_index\): reserved or absent"),
    (53, 1, r"word 53 \(reserved\): reserved or absent"),
    (14, 1, r"word 13 \(q_point\): reserved or absent"),                    # q_point absent
    (23, 0x0000, r"word 23 \(predicted_col\): not a normalised"),
    (31, 0x0001, r"word 31 \(r_est\): reserved or absent"),                  # estimate absent
    (1, 56, r"word 1 \(length\)")])
@pytest.mark.cases("flightsw.messages._track_check_k", "bad-object-type", "status-bits",
                   "flags-bits", "absent-header-word", "reserved-word", "absent-value", "bad-float",
                   "bad-length")
def test_track_command_rules(word, value, match):
    c = TrackCommand(frame_count=9, time_tag=0.5, imager="wfov_uv", object_type="aurora",
                     locked=True, decided_frame=2, mode="opportunity", predicted_row=10.0,
                     predicted_col=1.0, los_eci=np.array([1.0, 0.0, -1.0]))
    w = c.to_words().astype(np.int64)
    assert w[8] == 0x2B
    w[word] = value
    with pytest.raises(MessageError, match=match):
        TrackCommand.from_words(_with_crc(w))


@pytest.mark.cases("flightsw.messages._cand_encode_k", "non-finite")
@pytest.mark.cases("flightsw.messages._track_encode_k", "partial-group")
@pytest.mark.cases("flightsw.messages._group", "mixed")
def test_encoders_refuse_what_the_format_cannot_carry():
    with pytest.raises(MessageError, match="compaction"):
        CandidateMessage(compaction=0).to_words()
    with pytest.raises(MessageError, match="at most 23"):
        CandidateMessage(candidates=np.zeros(24, CANDIDATE_DTYPE)).to_words()
    with pytest.raises(MessageError, match="time_tag"):
        CandidateMessage(time_tag=math.inf).to_words()
    bad = np.zeros(2, CANDIDATE_DTYPE)
    bad["gof"][1] = math.nan
    with pytest.raises(MessageError, match=r"candidates\[1\]: holds a non-finite"):
        CandidateMessage(candidates=bad).to_words()
    with pytest.raises(MessageError, match="status"):
        TrackCommand(status=0x10000).to_words()
    with pytest.raises(MessageError, match="all finite or all NaN"):
        TrackCommand(predicted_row=1.0).to_words()
    with pytest.raises(MessageError, match="mode"):
        TrackCommand(mode="hover").to_words()
    with pytest.raises(MessageError, match="q_point"):
        TrackCommand(q_point=np.zeros(3)).to_words()


# ------------------------------------------------------------------------------------------------
# the codec kernels' remaining cases (issue 22): each checked through the public codec where it
# can be reached, against the format definition and the standard-library CRC
# ------------------------------------------------------------------------------------------------
@pytest.mark.cases("flightsw.messages._crc_range", "empty")
def test_crc_of_no_words_is_the_initial_value():
    assert _crc_range(np.array([0x1234, 0x5678], np.int64), 0, _CRC_TABLE) == 0xFFFF
    assert crc_oracle([]) == 0xFFFF


@pytest.mark.cases("flightsw.messages._words_ok", "all-words", "negative", "too-large")
@pytest.mark.cases("flightsw.messages._cand_check_k", "bad-word")
@pytest.mark.cases("flightsw.messages._track_check_k", "bad-word")
def test_words_outside_16_bits_are_refused_naming_the_first():
    good = _message(1).to_words().astype(np.int64)
    good[7] = 0xFFFF                                      # the top of the range is a word
    CandidateMessage.from_words(_with_crc(good))
    for bad in ({3: -1, 9: 0x10000}, {9: 0x10000, 20: -5}):
        w = good.copy()
        for i, v in bad.items():
            w[i] = v
        with pytest.raises(MessageError, match="not a 16-bit word") as exc:
            CandidateMessage.from_words(w)
        assert exc.value.word == min(bad)
    w = TrackCommand().to_words().astype(np.int64)
    w[40] = 0x10000
    with pytest.raises(MessageError, match=r"word 40 .*not a 16-bit word"):
        TrackCommand.from_words(w)


@pytest.mark.cases("flightsw.messages._cand_encode_k", "no-candidates", "bad-label")
def test_candidate_message_without_candidates_and_with_a_bad_label():
    w = _message(0).to_words()
    head = [0x4950, 16, 5, *words48(0x4000000000, 1), (3 << 8) | 2, 0xFFF8, 128, 64, 64,
            0x6000, 0x0002, 7, 0]
    assert w.tolist() == head + [crc_oracle(head)]
    for label in (-1, 0x10000):
        m = _message(3)
        m.candidates["label"][2] = label
        with pytest.raises(MessageError, match=r"candidates\[2\]: label must be 0..65535"):
            m.to_words()


@pytest.mark.cases("flightsw.messages._cand_check_k", "short", "bad-crc")
def test_candidate_message_too_short_or_with_a_bad_crc():
    w = _message(1).to_words().astype(np.int64)
    for n, word in ((15, 1), (2, 1), (1, 0)):
        with pytest.raises(MessageError, match="length") as exc:
            CandidateMessage.from_words(w[:n])
        assert exc.value.word == word
    w[-1] ^= 1
    with pytest.raises(MessageError, match=r"word 44 \(crc\): bad checksum") as exc:
        CandidateMessage.from_words(w)


@pytest.mark.cases("flightsw.messages._group", "infinite")
def test_an_infinite_value_makes_its_group_neither_present_nor_absent():
    with pytest.raises(MessageError, match="all finite or all NaN"):
        TrackCommand(q_point=np.full(4, np.inf)).to_words()


@pytest.mark.parametrize("word,value,match", [
    (0, 0x5451, r"word 0 \(id\): wrong message id"),
    (54, None, r"word 54 \(crc\): bad checksum"),
    (6, 0x0705, r"word 6 \(imager/object_type\): unknown imager code"),
    (3, 0x2000, r"word 3 \(time_tag\): not a normalised"),
    (31, 0x2000, r"word 31 \(r_est\): not a normalised")])          # a 48-bit value present
@pytest.mark.cases("flightsw.messages._track_check_k", "bad-id", "bad-crc", "bad-imager",
                   "bad-time-tag", "bad-float")
def test_track_command_header_rules_and_48_bit_values(word, value, match):
    c = TrackCommand(frame_count=9, time_tag=0.5, imager="wfov_uv", object_type="aurora",
                     r_est=np.array([1.0, 2.0, 3.0]), v_est=np.array([0.5, 0.5, 0.5]),
                     sigma_pos=1.0, sigma_vel=1.0)
    w = c.to_words().astype(np.int64)
    if value is None:
        w[word] ^= 0x8000
    else:
        w[word] = value
        w = _with_crc(w)
    with pytest.raises(MessageError, match=match):
        TrackCommand.from_words(w)
