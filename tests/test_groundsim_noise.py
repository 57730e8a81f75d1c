"""Pixel statistics: flat fields against Poisson + read noise (+ the 1/12 DN^2 of quantisation), and
saturation/blooming only above the full well."""
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
