"""Pixel statistics: flat fields against Poisson + read noise (+ the 1/12 DN^2 of quantisation), and
saturation/blooming only above the full well."""
import math

import numpy as np
import pytest

from groundsim.imagers import get_imager
from groundsim.render import GAUSS_TABLE, expose, render_flat


@pytest.mark.parametrize("mean_e", [3.0, 40.0, 2000.0])
def test_flat_field_mean_and_variance(mean_e):
    im = get_imager("wfov_vis")
    f = np.stack([render_flat(im, mean_e, seed=9, frame_index=k) for k in range(4)]).astype(float)
    mean_dn = im.bias_dn + mean_e / im.gain_e_per_dn
    var_dn = (mean_e + im.read_noise_e ** 2) / im.gain_e_per_dn ** 2 + 1.0 / 12.0
    assert abs(f.mean() - mean_dn) / (mean_dn - im.bias_dn) < 0.02
    assert abs(f.var() - var_dn) / var_dn < 0.02


def test_poisson_shape_at_low_flux():
    """No read noise, unit gain, zero bias: the counts are Poisson(2) (exact, not Gaussian)."""
    im = get_imager("wfov_vis").with_(read_noise_e=0.0, gain_e_per_dn=1.0, bias_dn=0.0)
    f = np.concatenate([render_flat(im, 2.0, seed=1, frame_index=k).ravel() for k in range(4)])
    from scipy.stats import poisson
    for k in range(6):
        assert abs((f == k).mean() - poisson.pmf(k, 2.0)) < 0.004


def test_gaussian_tails_beyond_table():
    im = get_imager("wfov_vis").with_(read_noise_e=0.0, gain_e_per_dn=1.0, bias_dn=40.0)
    f = np.concatenate([render_flat(im, 2000.0, seed=3, frame_index=k).ravel() for k in range(40)])
    z = (f - 2040.0) / np.sqrt(2000.0)
    assert z.max() > 4.2 or z.min() < -4.2     # beyond the table's extreme bins (|z| < 4.17)
    from scipy.special import ndtr
    assert abs((np.abs(z) > 3.5).mean() / (2 * ndtr(-3.5)) - 1.0) < 0.25
    assert GAUSS_TABLE.dtype == np.float32


def _star_mean(im, peak_e, row=120, col=100):
    mean = np.full((im.n_rows, im.n_cols), (im.dark_e_per_s + im.sky_e_per_s) * im.t_int, np.float32)
    rr, cc = np.mgrid[:im.n_rows, :im.n_cols] + 0.5
    mean += (peak_e * np.exp(-0.5 * ((rr - row - 0.5) ** 2 + (cc - col - 0.5) ** 2) / 1.0 ** 2)).astype(np.float32)
    return mean


def test_no_saturation_or_blooming_below_full_well():
    im = get_imager("wfov_vis")
    peak = 0.8 * im.adc_saturation_e()
    f = expose(im, _star_mean(im, peak), seed=2)
    assert f.max() < im.adc_max
    bg = im.bias_dn + (im.dark_e_per_s + im.sky_e_per_s) * im.t_int / im.gain_e_per_dn
    col = f[:, 100].astype(float)
    assert np.all(np.abs(col[:110] - bg) < 8) and np.all(np.abs(col[131:] - bg) < 8)


def test_blooming_above_full_well():
    im = get_imager("wfov_vis")
    peak = 20.0 * im.full_well_e
    mean = _star_mean(im, peak)
    f = expose(im, mean, seed=2)
    sat_rows = np.flatnonzero(f[:, 100] == im.adc_max)
    # the PSF alone exceeds the full well within |d| <= 2.45 px; blooming extends the bleed far beyond
    above = np.flatnonzero(mean[:, 100] > im.full_well_e)
    assert len(sat_rows) > len(above) + 6
    assert sat_rows.min() < above.min() - 2 and sat_rows.max() > above.max() + 2
    # confined to the saturated columns: the bleed does not spread sideways
    assert not np.any(f[:, 90] == im.adc_max)
    # charge is conserved (nothing hits the frame edge here): bleed length ~ excess / full well
    excess = (mean[:, 100][mean[:, 100] > im.full_well_e] - im.full_well_e).sum()
    assert abs(len(sat_rows) - (len(above) + excess / im.full_well_e)) < 0.2 * len(sat_rows) + 3


# cases: groundsim.render.expose_kernel keep, reset; groundsim.render._fast_row common
@pytest.mark.parametrize("bloom", [False, True])
def test_expose_reset_gives_the_same_frame_and_leaves_the_background(bloom):
    """``reset`` only changes what is left in ``mean``: the frame is the one ``keep`` gives (common
    rows with their redrawn tail pixels, low-flux rows; with a column that can bloom, every row the
    pixel by pixel way), and ``mean`` is the background after."""
    from groundsim.render import expose_kernel, extrema_kernel, frame_rng_state
    im = get_imager("wfov_vis")
    bg = (im.dark_e_per_s + im.sky_e_per_s) * im.t_int
    mean = _star_mean(im, 20.0 * im.full_well_e if bloom else 1000.0)
    mean += np.linspace(0.0, 300.0, im.n_cols, dtype=np.float32)    # no pixel at the background
    mean[200:210] = 3.0                                    # exact-Poisson rows
    colmax = np.empty(im.n_cols, np.float32)
    rowmin = np.empty(im.n_rows, np.float32)
    extrema_kernel(mean, colmax, rowmin)
    frames, tails = [], 0
    for reset in (math.nan, bg):
        m = mean.copy()
        out = np.empty(mean.shape, np.uint16)
        for k in range(30):      # ~2 table-tail pixels a frame in the common rows
            m[:] = mean
            expose_kernel(m, out, np.empty(mean.shape), frame_rng_state(5, k), GAUSS_TABLE, colmax,
                          rowmin, im.read_noise_e, im.gain_e_per_dn, im.bias_dn, im.full_well_e,
                          im.adc_max, reset)
            frames.append(out.copy())
        if reset == reset:
            assert np.all(m == np.float32(bg))
        else:
            np.testing.assert_array_equal(m, mean)
    for a, b in zip(frames[:30], frames[30:]):
        np.testing.assert_array_equal(a, b)
        # a redrawn tail pixel (|z| beyond the table's 4.17 sigma) shows as a far outlier
        z = (a.astype(float) - (im.bias_dn + mean / im.gain_e_per_dn)) / (
            np.sqrt(mean + im.read_noise_e ** 2) / im.gain_e_per_dn)
        tails += int((np.abs(z[:200]) > 4.3).sum())
    assert tails > 0


def test_renderer_reuses_its_background_across_frames():
    """A renderer that drew stars and an extended image the frame before gives the same frame as a
    fresh one (its mean image is back at the background without a fill)."""
    from groundsim.quat import q_to_dcm
    from groundsim.render import Renderer
    from groundsim.sky import StarCatalog
    im = get_imager("wfov_vis")
    view = StarCatalog.shared().at_epoch(2000.0)
    m = (q_to_dcm(np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2]))
         @ im.align_dcm).T
    used = Renderer(im, view)
    glow = np.linspace(0.0, 500.0, im.n_rows * im.n_cols).reshape(im.n_rows, im.n_cols)
    used.render(m, m, m, seed=1, frame_index=0, extended=glow.astype(np.float32))
    used.render(m, m, m, seed=1, frame_index=1)
    a, sa, _ = used.render(m, m, m, seed=1, frame_index=2)
    b, sb, _ = Renderer(im, view).render(m, m, m, seed=1, frame_index=2)
    assert len(sa) > 5
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(sa, sb)
