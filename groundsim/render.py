"""Frame rendering: numba kernels (module level, ``@njit(**KERNEL)``) and the :class:`Renderer` that
configures and calls them.

Pipeline for one frame (electrons until the ADC):

1. ``mean`` (float32 [244, 256]) = ``(dark + sky) * t_int`` + optional extended image (aurora, limb glow).
2. Point sources (stars, satellite hard bodies) are added with a pixel-integrated Gaussian PSF (separable
   Gaussian CDF from a 1/512-sigma table, linear interpolation: error < 1e-6 of the flux); a source that
   moves during the integration (slew, target motion) is rendered as ``nsub`` equal sub-stamps spaced
   along its start->end track (at most 0.25 px apart): smear.
3. Elongated sources (plumes): a Gaussian with separate along/across sigmas and a position angle,
   sampled 3x3 per pixel and renormalised to the flux.
4. :func:`expose_kernel`: photon noise (Poisson by inversion below 12 e-, else Gaussian with the same
   mean and variance), blooming of charge above the full well up and down its column (columns that can
   reach the full well only), Gaussian read noise, ``DN = floor(bias + e/gain + 0.5)`` clipped to
   ``[0, adc_max]``. Random numbers: xoshiro256** seeded with 4 words from
   ``numpy.random.SeedSequence([seed, frame_index])``; normals from a 65536-entry inverse-CDF table.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL, callee_kernel

from .frames import R_EARTH_M
from .imagers import COL0, ROW0, Imager
from .tables import normal_tables

# ---------------------------------------------------------------------------------------------------
# tables
CDF_STEP = 1.0 / 512.0                 # sigma units
CDF_HALF = 8.0                         # table spans [-8, 8] sigma
N_GAUSS = 65536                        # equal-probability bins of the noise table (16 bits a draw)
# ndtr on the CDF grid, ndtri at the bin centres, and |z| beyond the table's extreme bins
# (groundsim.tables: SciPy's values, cached so an import need not load scipy.special)
CDF_TABLE, GAUSS_TABLE, TAIL_START = normal_tables(CDF_STEP, CDF_HALF, N_GAUSS)
POISSON_GAUSS_SWITCH = 12.0            # e-: below, exact Poisson (inversion)

STAR_DTYPE = np.dtype([("hip", np.int32), ("row", np.float64), ("col", np.float64),
                       ("counts", np.float64), ("electrons", np.float64), ("mag", np.float64)])


# ---------------------------------------------------------------------------------------------------
# kernels
@callee_kernel
def _cdf(u, table):
    x = (u + CDF_HALF) * (1.0 / CDF_STEP)
    if x <= 0.0:
        return 0.0
    n = table.shape[0] - 1
    if x >= n:
        return 1.0
    i = int(x)
    f = x - i
    return table[i] + f * (table[i + 1] - table[i])


@njit(**KERNEL)
def star_field_kernel(cand, keep, uvec, observer, cos_limit, m0, m, m1, scale_col, scale_row,
                      idx, rows, cols):
    """Select and project the candidate stars ``cand`` (int64 catalogue indices) in one pass.

    A star is kept when ``keep[i]`` (bool, per catalogue star) and, if ``cos_limit > -2``, it is not
    behind the Earth: ``uvec[i] @ observer > -cos_limit`` (``observer`` (3,) ECI position, m;
    ``cos_limit = |observer| * cos(Earth's angular radius)``). Kept stars go to ``idx`` (int64) and
    their (row, col) through the ECI -> imager matrices ``m0``, ``m``, ``m1`` (start, middle, end of the
    integration) to ``rows``/``cols`` (3, len(cand)) float64: for (a, b, c) = m_k @ u, col = b / a /
    scale_col + COL0, row = c / a / scale_row + ROW0 (NaN when a <= 1e-9, behind the imager).
    Returns the number kept (the first n entries are filled).

    Cases
    -----
    catalogue-cut : stars with ``keep`` False are left out.
    earth-occulted : stars behind the Earth are left out when an observer is given.
    behind-imager : a star behind the imager plane gets NaN row and column.
    """
    n = 0
    for j in range(cand.shape[0]):
        i = cand[j]
        if not keep[i]:
            continue
        x = uvec[i, 0]
        y = uvec[i, 1]
        z = uvec[i, 2]
        if cos_limit > -2.0 and x * observer[0] + y * observer[1] + z * observer[2] <= -cos_limit:
            continue
        idx[n] = i
        for k in range(3):
            mk = m0 if k == 0 else (m if k == 1 else m1)
            a = mk[0, 0] * x + mk[0, 1] * y + mk[0, 2] * z
            b = mk[1, 0] * x + mk[1, 1] * y + mk[1, 2] * z
            c = mk[2, 0] * x + mk[2, 1] * y + mk[2, 2] * z
            if a > 1e-9:
                cols[k, n] = b / a / scale_col + COL0
                rows[k, n] = c / a / scale_row + ROW0
            else:
                cols[k, n] = np.nan
                rows[k, n] = np.nan
        n += 1
    return n


@njit(**KERNEL)
def add_points_kernel(img, colmax, r0, c0, r1, c1, flux, sigma, table):
    """Add point sources (electrons ``flux``) moving from (r0, c0) to (r1, c1) during the integration.

    The stamp of a (sub-)source spans +-rad pixels, rad = ceil(sigma * sqrt(2 ln(f / 0.1 e-))), so
    the light left out is below ~0.1 e- per pixel (noise is >= 4 e-). ``colmax`` is raised to every value written.
    """
    nr, nc = img.shape
    inv_s = 1.0 / sigma
    wmax = 2 * (int(math.ceil(sigma * 7.0)) + 2) + 1
    wr = np.empty(wmax)
    wc = np.empty(wmax)
    for k in range(flux.shape[0]):
        f = flux[k]
        if not (f > 0.0) or not (r0[k] == r0[k]) or not (r1[k] == r1[k]):
            continue
        rad = int(math.ceil(sigma * math.sqrt(2.0 * math.log(max(f, 1.0) / 0.1))))
        if rad > (wmax - 1) // 2:
            rad = (wmax - 1) // 2
        w = 2 * rad + 1
        dr = r1[k] - r0[k]
        dc = c1[k] - c0[k]
        length = math.sqrt(dr * dr + dc * dc)
        nsub = 1 + int(length / 0.25) if length > 0.02 else 1
        if nsub > 4000:
            nsub = 4000
        fs = f / nsub
        for s in range(nsub):
            t = (s + 0.5) / nsub if nsub > 1 else 0.5
            rc = r0[k] + t * dr
            cc = c0[k] + t * dc
            ir = int(math.floor(rc))
            ic = int(math.floor(cc))
            if ir + rad < 0 or ir - rad >= nr or ic + rad < 0 or ic - rad >= nc:
                continue
            prev = _cdf((ir - rad - rc) * inv_s, table)
            for j in range(w):
                cur = _cdf((ir - rad + j + 1 - rc) * inv_s, table)
                wr[j] = cur - prev
                prev = cur
            prev = _cdf((ic - rad - cc) * inv_s, table)
            for j in range(w):
                cur = _cdf((ic - rad + j + 1 - cc) * inv_s, table)
                wc[j] = (cur - prev) * fs
                prev = cur
            for a in range(w):
                rr = ir - rad + a
                if rr < 0 or rr >= nr:
                    continue
                wa = wr[a]
                if wa < 1e-9:
                    continue
                for b in range(w):
                    cc2 = ic - rad + b
                    if cc2 >= 0 and cc2 < nc:
                        v = img[rr, cc2] + wa * wc[b]
                        img[rr, cc2] = v
                        if v > colmax[cc2]:
                            colmax[cc2] = v


@njit(**KERNEL)
def truth_kernel(out, idx, rows, cols, electrons, hip, mag, gain, n_rows, n_cols):
    """Fill the structured truth array ``out`` (STAR_DTYPE) with the stars whose centre is in the frame;
    returns their number."""
    n = 0
    for i in range(idx.shape[0]):
        r = rows[i]
        c = cols[i]
        if r >= 0.0 and r < n_rows and c >= 0.0 and c < n_cols:
            out[n]["hip"] = hip[idx[i]]
            out[n]["row"] = r
            out[n]["col"] = c
            out[n]["electrons"] = electrons[i]
            out[n]["counts"] = electrons[i] / gain
            out[n]["mag"] = mag[idx[i]]
            n += 1
    return n


@njit(**KERNEL)
def add_elongated_kernel(img, row, col, flux, sig_along, sig_across, angle):
    """Add a Gaussian of total ``flux`` centred at (row, col), long axis at ``angle`` (rad, from +col
    toward +row), sampled 3x3 per pixel and renormalised over the pixels it touches in the frame."""
    nr, nc = img.shape
    ext = int(math.ceil(4.0 * max(sig_along, sig_across))) + 1
    ca = math.cos(angle)
    sa = math.sin(angle)
    ia = 1.0 / (sig_along * sig_along)
    ic = 1.0 / (sig_across * sig_across)
    r_lo = max(0, int(row) - ext)
    r_hi = min(nr, int(row) + ext + 1)
    c_lo = max(0, int(col) - ext)
    c_hi = min(nc, int(col) + ext + 1)
    if r_lo >= r_hi or c_lo >= c_hi:
        return
    # normalisation over the full (unclipped) support so clipping at the edge loses light
    norm = 2.0 * math.pi * sig_along * sig_across
    scale = flux / norm / 9.0
    for r in range(r_lo, r_hi):
        for c in range(c_lo, c_hi):
            acc = 0.0
            for u in range(3):
                dy = r + (u + 0.5) / 3.0 - row
                for v in range(3):
                    dx = c + (v + 0.5) / 3.0 - col
                    p = dx * ca + dy * sa
                    q = -dx * sa + dy * ca
                    acc += math.exp(-0.5 * (p * p * ia + q * q * ic))
            img[r, c] += acc * scale


@callee_kernel
def _rotl(x, k):
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@callee_kernel
def _xo(s0, s1, s2, s3):
    res = _rotl(s1 * np.uint64(5), 7) * np.uint64(9)
    t = s1 << np.uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = _rotl(s3, 45)
    return res, s0, s1, s2, s3


@callee_kernel
def _poisson_small(lam, u):
    p = math.exp(-lam)
    f = p
    k = 0
    while u > f and k < 200:
        k += 1
        p *= lam / k
        f += p
    return float(k)


@callee_kernel
def _uniform(s0, s1, s2, s3):
    y, s0, s1, s2, s3 = _xo(s0, s1, s2, s3)
    return (float(y >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0), s0, s1, s2, s3


@callee_kernel
def _tail(k, s0, s1, s2, s3):
    """Exact normal tail beyond TAIL_START (Marsaglia), signed by the extreme table bin ``k``. The
    table's extreme bins (probability 2**-15 each) are replaced by it so the tails are right."""
    t0 = TAIL_START
    while True:
        u1, s0, s1, s2, s3 = _uniform(s0, s1, s2, s3)
        u2, s0, s1, s2, s3 = _uniform(s0, s1, s2, s3)
        xx = -math.log(u1) / t0
        yy = -math.log(u2)
        if 2.0 * yy > xx * xx:
            break
    z = t0 + xx if k == 65535 else -(t0 + xx)
    return z, s0, s1, s2, s3


@callee_kernel
def _normal(s0, s1, s2, s3, gtab):
    x, s0, s1, s2, s3 = _xo(s0, s1, s2, s3)
    k = int(x & np.uint64(0xFFFF))
    z = float(gtab[k])
    if k == 0 or k == 65535:
        z, s0, s1, s2, s3 = _tail(k, s0, s1, s2, s3)
    return z, s0, s1, s2, s3


@njit(**KERNEL)
def standard_normals_kernel(state, out):
    """Fill ``out`` (n,) float64 with independent N(0, 1) deviates: Box-Muller on pairs of xoshiro256**
    uniforms (53-bit, in (0, 1)) from the uint64[4] ``state`` (:func:`frame_rng_state`), which is
    advanced in place.

    Cases
    -----
    pairs : an even ``n``: n / 2 Box-Muller pairs (cosine, then sine branch).
    odd : an odd ``n``: the last deviate is the cosine branch of one more pair.
    """
    s0 = state[0]
    s1 = state[1]
    s2 = state[2]
    s3 = state[3]
    n = out.shape[0]
    for i in range(0, n, 2):
        u1, s0, s1, s2, s3 = _uniform(s0, s1, s2, s3)
        u2, s0, s1, s2, s3 = _uniform(s0, s1, s2, s3)
        rad = math.sqrt(-2.0 * math.log(u1))
        out[i] = rad * math.cos(2.0 * math.pi * u2)
        if i + 1 < n:
            out[i + 1] = rad * math.sin(2.0 * math.pi * u2)
    state[0] = s0
    state[1] = s1
    state[2] = s2
    state[3] = s3


@callee_kernel
def _note_tails(krow, r, tails, ntail):
    """Note the pixels of row ``r`` whose normal-table index ``krow`` (uint16 [nc]) is an extreme
    bin (0 or 65535), as ``(r * nc + c) * 2 + upper``, into ``tails`` from ``ntail`` on (while it has
    room); returns the new count. A branch-free scan first: most rows have none.

    Cases
    -----
    none : no extreme bin in the row -> nothing noted, the count unchanged.
    extreme : each index 0 (lower tail, even code) or 65535 (upper tail, odd code) is noted in
        column order.
    full : ``tails`` full -> the rest of the row is not noted.
    """
    nc = krow.size
    hit = False
    for c in range(nc):
        hit |= (krow[c] == 0) | (krow[c] == 65535)
    if hit:
        for c in range(nc):
            k = krow[c]
            if (k == 0 or k == 65535) and ntail < tails.shape[0]:
                tails[ntail] = (r * nc + c) * 2 + (1 if k == 65535 else 0)
                ntail += 1
    return ntail


@callee_kernel
def _digitise(e, inv_gain, bias, hi):
    v = bias + e * inv_gain + 0.5
    if v < 0.0:
        v = 0.0
    elif v > hi:
        v = hi
    return np.uint16(int(v))


@njit(**KERNEL)
def extrema_kernel(mean, colmax, rowmin):
    """Per-column maximum and per-row minimum of ``mean`` (inputs of :func:`expose_kernel`)."""
    nr, nc = mean.shape
    for c in range(nc):
        colmax[c] = -1e30
    for r in range(nr):
        rm = np.float32(1e30)
        for c in range(nc):
            v = mean[r, c]
            colmax[c] = max(colmax[c], v)
            rm = min(rm, v)
        rowmin[r] = rm


@callee_kernel
def _fast_row(mrow, orow, zrow, krow, gtab, s0, s1, s2, s3, bias32, rn2_32, igain32, hi32):
    """One common row of :func:`expose_kernel` (every mean >= POISSON_GAUSS_SWITCH, no column that
    can bloom, ``nc % 4 == 0``): Poisson(m) + N(0, rn^2) ~ N(m, m + rn^2), one normal per pixel.
    Two passes: the row's deviates (``krow`` uint16 table indices, ``zrow`` float32 values; no
    branch), then its pixels ``orow`` (uint16) from the means ``mrow`` (float32, vectorised; IEEE
    single, no FMA contraction: deterministic). Returns the advanced xoshiro256** state.

    Cases
    -----
    common : every pixel from one table deviate; the extreme bins stay in ``krow`` for the caller
        to redraw from the exact tail.
    """
    m16 = np.uint64(0xFFFF)
    nc = mrow.shape[0]
    for c4 in range(0, nc, 4):
        xx, s0, s1, s2, s3 = _xo(s0, s1, s2, s3)
        for j in range(4):
            k = int((xx >> np.uint64(16 * j)) & m16)
            krow[c4 + j] = k
            zrow[c4 + j] = gtab[k]
    zero32 = np.float32(0.0)
    for c in range(nc):
        m32 = mrow[c]
        v32 = bias32 + (m32 + math.sqrt(m32 + rn2_32) * zrow[c]) * igain32
        v32 = min(max(v32, zero32), hi32)
        orow[c] = np.uint16(int(v32))
    return s0, s1, s2, s3


@callee_kernel
def _spill(work, c, j, step, charge, full_well):
    """Blooming: put ``charge`` (electrons) into column ``c`` of ``work`` (float64 [nr, nc]) from
    row ``j`` on, moving by ``step`` (-1 up, +1 down), filling each pixel to ``full_well``; charge
    left at the frame edge is lost.

    Cases
    -----
    fits : the first pixel with room takes the rest of the charge.
    fills : pixels without room for all of it are filled to the full well, the rest goes on.
    edge : charge still left past the first or last row is dropped.
    """
    nr = work.shape[0]
    while charge > 0.0 and 0 <= j < nr:
        room = full_well - work[j, c]
        if room > 0.0:
            if room >= charge:
                work[j, c] += charge
                charge = 0.0
            else:
                work[j, c] = full_well
                charge -= room
        j += step


@njit(**KERNEL)
def expose_kernel(mean, out, work, state, gtab, colmax, rowmin, read_noise, gain, bias, full_well, adc_max,
                  reset):
    """Noise, blooming and digitisation of ``mean`` (electrons, float32 [nr, nc]) into ``out`` (uint16).

    ``work`` float64 [nr, nc] scratch; ``state`` uint64[4] xoshiro256** seed; ``gtab`` float32[65536]
    inverse normal CDF at bin centres; ``colmax`` (nc,) / ``rowmin`` (nr,) upper / lower bounds of each
    column's maximum and row's minimum of ``mean`` (:func:`extrema_kernel`, or tracked while rendering).
    ``reset`` (float, electrons): NaN leaves ``mean`` as it was; otherwise every row of ``mean`` is
    set to ``float32(reset)`` once read (the renderer's next background, without a separate fill).
    Returns the number of columns that could bloom.

    Cases
    -----
    keep : ``reset`` NaN -> ``mean`` unchanged.
    reset : ``reset`` a number -> ``mean`` all ``float32(reset)`` after, the frame the same as with
        keep (the redrawn tail pixels use the means noted before the reset).
    """
    nr, nc = mean.shape
    s0 = state[0]
    s1 = state[1]
    s2 = state[2]
    s3 = state[3]
    inv_gain = 1.0 / gain
    rn2 = read_noise * read_noise
    hi = float(adc_max)
    # a column can bloom when a mean reaches thr, where thr + 6 sqrt(thr) + 10 = full_well
    sq = -3.0 + math.sqrt(9.0 + max(full_well - 10.0, 0.0))
    thr = np.float32(sq * sq)
    flag = colmax > thr
    nflag = 0
    for c in range(nc):
        if flag[c]:
            nflag += 1
    last_m = -1.0
    last_sd = 0.0
    m16 = np.uint64(0xFFFF)
    tails = np.empty(256, np.int64)
    ntail = 0
    # float32 constants of the fast path (branch-free; IEEE single, no FMA contraction: deterministic)
    bias32 = np.float32(bias + 0.5)
    rn2_32 = np.float32(rn2)
    igain32 = np.float32(inv_gain)
    hi32 = np.float32(hi + 0.5)
    zrow = np.empty(nc, np.float32)       # one row's normal deviates (fast path)
    krow = np.empty(nc, np.uint16)        # their table indices
    tail_m = np.empty(tails.shape[0], np.float32)    # the means of the noted tail pixels
    do_reset = reset == reset
    reset32 = np.float32(reset) if do_reset else np.float32(0.0)
    for r in range(nr):
        if nflag == 0 and rowmin[r] >= POISSON_GAUSS_SWITCH and nc % 4 == 0:
            # fast path (the common row); then a branch-free scan of its table indices for the
            # extreme bins, which are noted and redrawn from the exact tail after all rows (a test
            # per deviate in the drawing loop cost ~10 us a frame)
            s0, s1, s2, s3 = _fast_row(mean[r], out[r], zrow, krow, gtab, s0, s1, s2, s3, bias32,
                                       rn2_32, igain32, hi32)
            n0 = ntail
            ntail = _note_tails(krow, r, tails, ntail)
            for t in range(n0, ntail):
                tail_m[t] = mean[r, (tails[t] >> 1) - r * nc]
            if do_reset:
                mean[r, :] = reset32
            continue
        for c4 in range(0, nc, 4):
            # one 64-bit draw feeds four pixels (16 bits each)
            xx, s0, s1, s2, s3 = _xo(s0, s1, s2, s3)
            for j in range(4):
                c = c4 + j
                if c >= nc:
                    break
                k = int((xx >> np.uint64(16 * j)) & m16)
                z = float(gtab[k])
                if k == 0 or k == 65535:
                    z, s0, s1, s2, s3 = _tail(k, s0, s1, s2, s3)
                m = float(mean[r, c])
                if m >= POISSON_GAUSS_SWITCH:
                    if not flag[c]:
                        # Poisson(m) + N(0, rn^2) ~ N(m, m + rn^2) in one draw
                        if m != last_m:
                            last_m = m
                            last_sd = math.sqrt(m + rn2)
                        out[r, c] = _digitise(m + last_sd * z, inv_gain, bias, hi)
                    else:
                        work[r, c] = m + math.sqrt(m) * z
                else:
                    if m < 0.0:
                        m = 0.0
                    u, s0, s1, s2, s3 = _uniform(s0, s1, s2, s3)
                    sig = _poisson_small(m, u)
                    if flag[c]:
                        work[r, c] = sig
                    else:
                        out[r, c] = _digitise(sig + read_noise * z, inv_gain, bias, hi)
        if do_reset:
            mean[r, :] = reset32
    for t in range(ntail):
        p = tails[t] >> 1
        z, s0, s1, s2, s3 = _tail(65535 if tails[t] & 1 else 0, s0, s1, s2, s3)
        r = p // nc
        c = p - r * nc
        m = float(tail_m[t])
        out[r, c] = _digitise(m + math.sqrt(m + rn2) * z, inv_gain, bias, hi)
    if nflag > 0:
        for c in range(nc):
            if not flag[c]:
                continue
            # blooming: excess above full well spills half up, half down, filling neighbours to the
            # full well; charge spilled past the frame edge is lost
            for r in range(nr):
                e = work[r, c]
                if e > full_well:
                    ex = e - full_well
                    work[r, c] = full_well
                    _spill(work, c, r - 1, -1, 0.5 * ex, full_well)
                    _spill(work, c, r + 1, 1, 0.5 * ex, full_well)
            for r in range(nr):
                z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3, gtab)
                out[r, c] = _digitise(work[r, c] + read_noise * z, inv_gain, bias, hi)
    return nflag


# ---------------------------------------------------------------------------------------------------
@njit(**KERNEL)
def _mix_kernel(base, frame_index, stream, out):
    # splitmix64 of (base word, frame index, stream): independent, well-mixed per-frame states
    for i in range(4):
        z = base[i] ^ (np.uint64(frame_index) * np.uint64(0x9E3779B97F4A7C15)) \
            ^ (np.uint64(stream * 4 + i + 1) * np.uint64(0xD1B54A32D192ED03))
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        out[i] = z ^ (z >> np.uint64(31))
    if out[0] == 0 and out[1] == 0 and out[2] == 0 and out[3] == 0:
        out[0] = np.uint64(1)


_BASE_CACHE: dict = {}


def frame_rng_state(seed: int, frame_index: int, stream: int = 0) -> np.ndarray:
    """uint64[4] xoshiro256** state for one frame: ``SeedSequence(seed)`` gives 4 base words (entropy
    spread as numpy does), mixed with the frame index and stream by splitmix64. Platform independent."""
    seed = int(seed)
    base = _BASE_CACHE.get(seed)
    if base is None:
        base = np.random.SeedSequence(seed).generate_state(4, np.uint64)
        _BASE_CACHE[seed] = base
    out = np.empty(4, np.uint64)
    _mix_kernel(base, int(frame_index), int(stream), out)
    return out


class PointSource:
    """A source for :meth:`Renderer.render`: ECI lines of sight (unit vectors from the imager; (3,)
    arrays or (x, y, z) tuples) at the start, middle and end of the integration, electrons, and an
    optional plume (electrons, tail LOS)."""

    __slots__ = ("los0", "los", "los1", "electrons", "plume_electrons", "plume_tail_los", "plume_width_rad")

    def __init__(self, los0, los, los1, electrons, plume_electrons=0.0, plume_tail_los=None,
                 plume_width_rad=0.0):
        self.los0, self.los, self.los1 = los0, los, los1
        self.electrons = float(electrons)
        self.plume_electrons = float(plume_electrons)
        self.plume_tail_los = plume_tail_los
        self.plume_width_rad = float(plume_width_rad)


class Renderer:
    """Renders frames of one imager against one :class:`~groundsim.sky.SkyView`.

    ``render(m0, m, m1, sources, seed, frame_index, extended=None)`` with ECI->imager rotation matrices at
    the start, middle and end of the integration returns ``(frame uint16[244,256], stars)`` where
    ``stars`` is a structured array (``STAR_DTYPE``: hip, row, col, counts (expected DN above bias, before
    saturation), electrons, mag (band)) of every star whose mid-integration centre is in the frame, and
    the projected (row, col) of each source at mid-integration.
    """

    def __init__(self, imager: Imager, sky_view, catalog=None):
        self.imager = imager
        self.sky = sky_view
        cat = catalog if catalog is not None else sky_view.catalog
        self.catalog = cat
        self.hp_cut = cat.hp_cut_for(imager.band, imager.mag_limit)
        self._bg = (imager.dark_e_per_s + imager.sky_e_per_s) * imager.t_int
        self._mean = np.empty((imager.n_rows, imager.n_cols), np.float32)
        self._mean_is_bg = False          # True when every pixel of _mean holds float32(_bg)
        self._work = np.empty((imager.n_rows, imager.n_cols), np.float64)
        self._sc, self._sr = imager.scale_col, imager.scale_row
        self._colmax = np.empty(imager.n_cols, np.float32)
        self._rowmin = np.empty(imager.n_rows, np.float32)
        # per-star electrons cached over the whole catalogue (cheap: one vector op per imager)
        mag = cat.band_mag(imager.band)
        self._mag = mag
        self._el = imager.zp_e_per_s * np.power(10.0, -0.4 * mag) * imager.t_int
        self._keep = mag <= imager.mag_limit
        self.bloomed_columns = 0
        # the star cone's radius: the half diagonal + (smear margin + PSF) pixels
        self._scale_max = max(imager.scale_col, imager.scale_row)
        self._half_diagonal, self._psf_sigma = imager.half_diagonal, float(imager.psf_sigma_px)
        self._no_observer = np.zeros(3)
        # per-frame buffers: stars then sources (grown as needed)
        self._idx = np.empty(0, np.int64)
        self._rows = np.empty((3, 0))
        self._cols = np.empty((3, 0))
        self._flux = np.empty(0)

    def star_field(self, m0, m, m1, margin_px=0.0, observer_pos=None):
        """Project the stars around the boresight: (idx, rows(3, n), cols(3, n)) for start/mid/end.
        With ``observer_pos`` (ECI, m) stars behind the Earth (sphere of radius R_EARTH_M) are left out."""
        n, idx, rows, cols = self._project_stars(m0, m, m1, margin_px, observer_pos, 0)
        return idx[:n].copy(), rows[:, :n].copy(), cols[:, :n].copy()

    def _project_stars(self, m0, m, m1, margin_px, observer_pos, extra):
        """:meth:`star_field` into the renderer's buffers, with ``extra`` columns of room after the
        stars: (n, idx int64 (cap,), rows (3, cap), cols (3, cap)), the first n entries the stars'.
        The buffers are reused by the next frame."""
        bore = m[0]  # ECI direction of imager +X (row 0 of ECI->imager)
        radius = self._half_diagonal + (margin_px + 5.0 * self._psf_sigma + 2.0) * self._scale_max
        cand = self.sky.cone(bore, radius, self.hp_cut)
        cos_limit = -3.0                     # no Earth test
        obs = self._no_observer
        if observer_pos is not None:
            obs = np.asarray(observer_pos, np.float64)
            rn = math.sqrt(float(obs @ obs))
            cos_limit = math.sqrt(max(0.0, 1.0 - (R_EARTH_M / rn) ** 2)) * rn
        need = len(cand) + extra
        if self._idx.shape[0] < need:
            cap = max(2 * need, 256)
            self._idx = np.empty(cap, np.int64)
            self._rows = np.empty((3, cap))
            self._cols = np.empty((3, cap))
            self._flux = np.empty(cap)
        n = star_field_kernel(cand, self._keep, self.sky.uvec, obs, cos_limit, m0, m, m1,
                              float(self._sc), float(self._sr), self._idx, self._rows, self._cols)
        return n, self._idx, self._rows, self._cols

    def project(self, m, los):
        """(row, col) of an ECI direction through ECI->imager ``m`` (NaN behind the imager)."""
        x, y, z = los.tolist() if isinstance(los, np.ndarray) else los
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = m.tolist()
        a = a0 * x + a1 * y + a2 * z
        if a <= 1e-9:
            return math.nan, math.nan
        return ((c0 * x + c1 * y + c2 * z) / a / self._sr + ROW0,
                (b0 * x + b1 * y + b2 * z) / a / self._sc + COL0)

    def render(self, m0, m, m1, sources=(), seed=0, frame_index=0, extended=None, out=None,
               observer_pos=None):
        im = self.imager
        mean = self._mean
        colmax, rowmin = self._colmax, self._rowmin
        if extended is not None:
            np.add(extended, self._bg, out=mean, casting="unsafe")
            extrema_kernel(mean, colmax, rowmin)
        else:
            if not self._mean_is_bg:
                mean.fill(self._bg)
            colmax.fill(self._bg)
            rowmin.fill(self._bg)
        self._mean_is_bg = False          # until the kernel below has reset it
        ns = len(sources)
        n, idx, rows, cols = self._project_stars(m0, m, m1, self._smear_px(m0, m1), observer_pos, ns)
        flux = self._flux
        np.take(self._el, idx[:n], out=flux[:n])
        # the sources' hard bodies go after the stars, into the same call (the kernel skips a zero
        # flux and a NaN start or end, as behind the imager); their plumes are added after all points
        src_rc = []
        for j, s in enumerate(sources):
            rows[0, n + j], cols[0, n + j] = self.project(m0, s.los0)
            r, c = self.project(m, s.los)
            rows[2, n + j], cols[2, n + j] = self.project(m1, s.los1)
            flux[n + j] = s.electrons
            src_rc.append((r, c))
        add_points_kernel(mean, colmax, rows[0, :n + ns], cols[0, :n + ns], rows[2, :n + ns],
                          cols[2, :n + ns], flux[:n + ns], im.psf_sigma_px, CDF_TABLE)
        for s, (r, c) in zip(sources, src_rc):
            if s.plume_electrons > 0 and s.plume_tail_los is not None and r == r:
                self._add_plume(mean, s, m, r, c)
        frame = out if out is not None else np.empty((im.n_rows, im.n_cols), np.uint16)
        state = frame_rng_state(seed, frame_index)
        # the kernel leaves ``mean`` at the background again: the next frame needs no fill
        self.bloomed_columns = expose_kernel(mean, frame, self._work, state, GAUSS_TABLE, colmax, rowmin,
                                             im.read_noise_e, im.gain_e_per_dn, im.bias_dn,
                                             im.full_well_e, im.adc_max, self._bg)
        self._mean_is_bg = True
        stars = np.empty(n, STAR_DTYPE)
        k = truth_kernel(stars, idx[:n], rows[1, :n], cols[1, :n], flux[:n], self.catalog.hip, self._mag,
                         im.gain_e_per_dn, im.n_rows, im.n_cols)
        return frame, stars[:k], src_rc

    def _add_plume(self, mean, s, m, r, c):
        """Add the plume of source ``s`` (mid-integration position (r, c) through ``m``) to ``mean``
        and bring the column maxima / row minima up to date."""
        im = self.imager
        rt, ct = self.project(m, s.plume_tail_los)
        if rt == rt:
            dr, dc = rt - r, ct - c
            length = math.hypot(dr, dc)
            width_px = s.plume_width_rad / im.scale_col
            sig_across = math.hypot(im.psf_sigma_px, width_px)
            sig_along = math.hypot(sig_across, 0.5 * length)
            add_elongated_kernel(mean, r + 0.5 * dr, c + 0.5 * dc, s.plume_electrons,
                                 sig_along, sig_across, math.atan2(dr, dc))
            extrema_kernel(mean, self._colmax, self._rowmin)

    def _smear_px(self, m0, m1):
        # angle between the start and end boresights, in pixels (an upper bound of the star trail)
        if m0 is m1:
            return 0.0
        (a0, a1, a2), (b0, b1, b2) = m0[0].tolist(), m1[0].tolist()
        ang = math.acos(min(1.0, max(-1.0, a0 * b0 + a1 * b1 + a2 * b2)))
        (a0, a1, a2), (b0, b1, b2) = m0[1].tolist(), m1[1].tolist()
        ang = max(ang, math.acos(min(1.0, max(-1.0, a0 * b0 + a1 * b1 + a2 * b2))))
        return ang / min(self.imager.scale_col, self.imager.scale_row)


def expose(imager: Imager, mean_e, seed=0, frame_index=0) -> np.ndarray:
    """Noise + blooming + ADC of a mean image (electrons, [244, 256]) through ``imager`` (tests, tools)."""
    mean = np.ascontiguousarray(mean_e, dtype=np.float32)
    if mean.shape != (imager.n_rows, imager.n_cols):
        raise ValueError(f"mean image must be {(imager.n_rows, imager.n_cols)}, got {mean.shape}")
    out = np.empty(mean.shape, np.uint16)
    work = np.empty(mean.shape, np.float64)
    colmax = np.empty(mean.shape[1], np.float32)
    rowmin = np.empty(mean.shape[0], np.float32)
    extrema_kernel(mean, colmax, rowmin)
    expose_kernel(mean, out, work, frame_rng_state(seed, frame_index), GAUSS_TABLE, colmax, rowmin,
                  imager.read_noise_e, imager.gain_e_per_dn, imager.bias_dn, imager.full_well_e,
                  imager.adc_max, math.nan)
    return out


def render_flat(imager: Imager, mean_e: float, seed=0, frame_index=0) -> np.ndarray:
    """A flat field of ``mean_e`` electrons per pixel through the imager's noise/ADC chain (tests)."""
    return expose(imager, np.full((imager.n_rows, imager.n_cols), mean_e, np.float32), seed, frame_index)
