"""Star and object gates: their per-frame sizes, their propagation to the frame, and their
smoothing with the observation associated to them.

MSX paper, "Track processing algorithms": *"During initialization, two tracking gates are centered
on each observation: one object gate and one star gate. These gates are then propagated to the next
frame in accordance with velocity assumptions for the respective object and star hypotheses. Star
gates are propagated on the basis of spacecraft attitude rate only, whereas object gates must be
propagated considering both the a priori object motion and attitude rate. Each hypothesis gate is
then smoothed with the new observation(s) inside the gate using an alpha-beta tracker, and the
squared differences or residuals between the observation and the gate center are accumulated."*

* Gate position = body tangent coordinates ``(a, b)`` (:mod:`flightsw.tp.geometry`).
* Star gate prediction: an inertially fixed direction moves in body axes by the attitude change
  since the last frame, ``(a, b) <- T(dR (1, a, b))``, ``T(v) = (v_y/v_x, v_z/v_x)``
  (:func:`flightsw.tp.attitude.frame_attitude` forms ``dR``).
* Object gate prediction: the star prediction plus the a priori object motion ``V.dn[0]`` (the
  nominal's) or, for the verified object with the EKF running, ``V.de[0]``
  (:mod:`flightsw.tp.trajectory`).
* The verified object's gate, once the EKF runs, is put on the EKF's predicted line of sight before
  the association (:func:`centre_object_gate`; its tangent coordinates come from
  :func:`flightsw.tp.trajectory.predict_ekf`, which forms them for ``V.de[0]`` anyway). ASSUMED:
  the paper does not say how the verified object's gate moves once the EKF runs. Left to its own
  smoothing it follows whatever falls in it: a star crossing a faint target that the IP missed for
  a frame or two took the gate with it, the EKF refused the star's centroids (one axis rejected a
  frame, which then did not count towards a covariance reset) and the pointing drifted off the
  target (satellite_train_faint_mid, seeds 214 and 215, frames 28-140). Chosen on the satellite
  training family (docs/validation.md, the evaluation families).
* A learned velocity (beta > 0) moves a gate by ``v dt`` too; every gate keeps its last apparent
  velocity for the recording.
* Smoothing: :func:`flightsw.tp.alphabeta.ab_update` with the associated observation; the squared
  residual ``r_a^2 + r_b^2`` (rad^2) is accumulated per gate; the gate's successive empty frames
  (``G.miss``), successive populated frames (``G.run``) and populated frames in all (``G.hits``,
  rule 5) count what the rules test.

Gate rows: ``2p`` is the star gate and ``2p + 1`` the object gate of pair p (``G``, GATE_DTYPE [NG],
packed 32-bit coordinates, 16-bit integer copies for the membership tests).
"""
from __future__ import annotations

from flightsw.arith.m1750 import fa32, fc32, fd32, fm32, fs32
from flightsw.messages import TC_OBJECT_LOST
from flightsw.numba_cache import callee_kernel
from flightsw.tp.alphabeta import AB_UPDATE_MIX, ab_update
from flightsw.tp.f1750 import cycles, mix
from flightsw.tp.geometry import rot_tan, tan_int
from flightsw.tp.state import NG, NPAIR

_ONE32 = 0x40000001
GATE_PRED_MIX = {"FM": 8, "FA": 6, "FD": 1, "L": 6, "ST": 4}
GATE_OBJ_MIX = {"FA": 2}
GATE_VEL_MIX = {"FS": 2, "FM": 2, "ST": 2}
GATE_INT_MIX = {"FM": 2, "FIX": 2, "ST": 2}
GATE_HIT_MIX = mix(mix(AB_UPDATE_MIX, times=2), {"FM": 2, "FA": 2, "ST": 4, "INCDEC": 1})
GATE_MISS_MIX = {"ST": 2, "INCDEC": 1}
CYC_GATE_PRED = cycles(mix(GATE_PRED_MIX, GATE_VEL_MIX, GATE_INT_MIX))
CYC_GATE_OBJ = cycles(GATE_OBJ_MIX)
CYC_GATE_HIT = cycles(GATE_HIT_MIX)
CYC_GATE_MISS = cycles(GATE_MISS_MIX)
CYC_GATE_SETUP = cycles({"FM": 6, "FIX": 2, "L": 6})



@callee_kernel
def kill_pair(G, p):
    """Delete both gates of pair p (rows ``2p``, ``2p + 1`` of ``G``, GATE_DTYPE [NG]).

    Cases
    -----
    typical : both gates of pair p dead, every other row untouched.
    """
    G[2 * p].alive = 0
    G[2 * p + 1].alive = 0


@callee_kernel
def any_gate_alive(G):
    """True when any gate of ``G`` (GATE_DTYPE [NG]) is alive.

    Cases
    -----
    none-alive : every row dead -> False.
    last-row-alive : only the last row (``NG - 1``) alive -> True (the scan reaches the table end).
    """
    for row in range(NG):
        if G[row].alive != 0:
            return True
    return False


@callee_kernel
def drop_all_gates(S, G, V):
    """After a gap longer than ``max_coast_s`` no gate can be trusted: all deleted, the verified
    object lost.

    Cases
    -----
    gates-deleted : every live gate deleted, half-dead pairs included.
    object-held-lost : an object held -> ``S.dec = -1``, ``S.nlost`` counted, ``TC_OBJECT_LOST``.
    no-object : none held -> no status bit, no count.
    """
    for p in range(NPAIR):
        if G[2 * p].alive != 0 or G[2 * p + 1].alive != 0:
            kill_pair(G, p)
    if S.dec >= 0:
        V.status |= TC_OBJECT_LOST
        S.dec = -1
        S.nlost += 1


@callee_kernel
def gate_params(C, IMG, V, GP, cyc):
    """This frame's gate constants into ``GP`` (a GATE_PARAMS_DTYPE record): the gate half-width
    as a 16-bit integer (LSB 2**-16 rad; ``gate_px`` times the larger pixel scale), the rules'
    residual thresholds in rad^2 (pixel^2 thresholds times scale_col * scale_row), ``1/dt`` and
    ``beta/dt`` (packed 32-bit; 0 when dt is 0 or beta is 0).

    ``C`` config, ``IMG`` imager table (IMAGER_DTYPE records), ``V`` frame words, ``cyc``
    ledger (int64).

    Cases
    -----
    col-scale-larger : ``scale_col >= scale_row`` -> half-width ``FIX(gate_px scale_col 2**16)``.
    row-scale-larger : ``scale_row > scale_col`` -> half-width from ``scale_row``.
    thresholds : residual thresholds ``thr_px2 * scale_col * scale_row`` (rad^2).
    beta : dt and beta non-zero -> ``1/dt`` and ``beta/dt``.
    beta-zero : beta 0 -> ``GP.gain_v = 0`` (``1/dt`` still formed).
    dt-zero : dt 0 (first frame) -> ``GP.inv_dt = GP.gain_v = 0``, no division.
    """
    fl = 0
    img = IMG[V.img]
    sc = img.sc
    sr = img.sr
    smax = sc if fc32(sc, sr) >= 0 else sr
    gw, g = fm32(C.gate_px, smax); fl |= g
    GP.half = tan_int(gw)
    s2, g = fm32(sc, sr); fl |= g
    GP.thr_obj, g = fm32(C.thr_obj, s2); fl |= g
    GP.thr_star, g = fm32(C.thr_star, s2); fl |= g
    GP.inv_dt = 0
    GP.gain_v = 0
    dt = V.dt
    if dt != 0:
        GP.inv_dt, g = fd32(_ONE32, dt); fl |= g
        if C.beta != 0:
            GP.gain_v, g = fm32(C.beta, GP.inv_dt); fl |= g
    cyc.gates += CYC_GATE_SETUP
    V.aflags |= fl


@callee_kernel
def propagate_gates(S, G, V, GP, dR, cyc):
    """Every live gate moved to this frame (star: attitude change; object: plus the a priori
    motion; both: a learned velocity); its apparent velocity kept, its observation cleared.

    ``dR`` (int64 [9], packed 32-bit) the body's rotation since the last frame.

    Cases
    -----
    star-gate : even row moved by the attitude change only, ``(a, b) <- T(dR (1, a, b))``.
    object-gate-nominal : odd row moved by the attitude change plus the nominal's ``V.dn``.
    object-gate-ekf : the verified object's gate with the EKF running moves by ``V.de``; the other
        object gates still by ``V.dn``.
    learned-velocity : a gate with ``(G.dva, G.dvb) != 0`` also moves by ``v dt``.
    velocity-kept : ``(G.va, G.vb) = (new - old) / dt`` when ``1/dt`` is known.
    dt-zero : ``GP.inv_dt == 0`` -> ``G.va``, ``G.vb`` left as they were.
    dead-skipped : dead rows untouched (``G.obs`` not cleared).
    """
    fl = 0
    dt = V.dt
    inv_dt = GP.inv_dt
    obj_row = 2 * S.dec + 1
    ekf_dir = V.ekf_on != 0
    ngl = 0
    for row in range(NG):
        if G[row].alive == 0:
            continue
        ngl += 1
        a0 = G[row].a
        b0 = G[row].b
        a, b, g = rot_tan(dR, a0, b0); fl |= g
        if row & 1:                                     # object gate: a priori motion
            m = V.de if (row == obj_row and ekf_dir) else V.dn
            a, g = fa32(a, m[0]); fl |= g
            b, g = fa32(b, m[1]); fl |= g
            cyc.gates += CYC_GATE_OBJ
        if G[row].dva != 0 or G[row].dvb != 0:  # learned velocity (beta > 0)
            p, g = fm32(G[row].dva, dt); fl |= g
            a, g = fa32(a, p); fl |= g
            p, g = fm32(G[row].dvb, dt); fl |= g
            b, g = fa32(b, p); fl |= g
        if inv_dt != 0:
            p, g = fs32(a, a0); fl |= g
            G[row].va, g = fm32(p, inv_dt); fl |= g
            p, g = fs32(b, b0); fl |= g
            G[row].vb, g = fm32(p, inv_dt); fl |= g
        G[row].obs = -1
        G[row].a = a
        G[row].b = b
        G[row].ia = tan_int(a)
        G[row].ib = tan_int(b)
    cyc.gates += ngl * CYC_GATE_PRED
    V.aflags |= fl


CYC_CENTRE = cycles({"L": 3, "ST": 4})


@callee_kernel
def centre_object_gate(S, G, V, cyc):
    """The verified object's gate put on the running EKF's predicted line of sight, whose body
    tangent coordinates :func:`flightsw.tp.trajectory.predict_ekf` left in ``V.etan[0]``.

    Cases
    -----
    centred : a verified object, its gate alive, ``V.etan_ok`` -> ``G.a``, ``G.b`` (and the integer
        coordinates) = ``V.etan[0]``.
    otherwise : nothing changed.
    """
    if S.dec < 0 or V.etan_ok == 0:
        return
    row = 2 * S.dec + 1
    if G[row].alive == 0:
        return
    a, b = V.etan[0], V.etan[1]
    G[row].a = a
    G[row].b = b
    G[row].ia = tan_int(a)
    G[row].ib = tan_int(b)
    cyc.gates += CYC_CENTRE


@callee_kernel
def smooth_gates(C, G, OBS, V, GP, cyc):
    """Each live gate with an associated observation (``G.obs``) smoothed by the alpha-beta tracker,
    its squared residual accumulated, its populated run counted; the others counted empty.

    ``OBS`` observations (OBSERVATION_DTYPE [MAX_OBS], packed 32-bit tangent coordinates, rad).

    Cases
    -----
    fed : ``x <- x_p + alpha (z - x_p)`` per axis, ``G.res += r_a^2 + r_b^2``, ``G.miss = 0``,
        ``G.run``, ``G.hits`` + 1; velocity unchanged with ``gain_v == 0``.
    fed-with-beta : ``gain_v = beta/dt != 0`` -> velocity ``v + gain_v r`` per axis.
    empty : no observation -> ``G.miss`` + 1, ``G.run = 0``, position unchanged.
    dead-skipped : dead rows untouched.
    """
    fl = 0
    gain_v = GP.gain_v
    for row in range(NG):
        if G[row].alive == 0:
            continue
        j = G[row].obs
        if j >= 0:
            a, va, ra, g = ab_update(G[row].a, G[row].dva, OBS[j].a, C.alpha, gain_v)
            fl |= g
            b, vb, rb, g = ab_update(G[row].b, G[row].dvb, OBS[j].b, C.alpha, gain_v)
            fl |= g
            G[row].a = a
            G[row].b = b
            G[row].dva = va
            G[row].dvb = vb
            p, g = fm32(ra, ra); fl |= g
            res, g = fa32(G[row].res, p); fl |= g
            p, g = fm32(rb, rb); fl |= g
            G[row].res, g = fa32(res, p); fl |= g
            G[row].miss = 0
            G[row].run += 1
            G[row].hits += 1
            cyc.gates += CYC_GATE_HIT
        else:
            G[row].miss += 1
            G[row].run = 0
            cyc.gates += CYC_GATE_MISS
    V.aflags |= fl
