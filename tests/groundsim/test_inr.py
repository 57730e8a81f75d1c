"""INR 3-sigma verification with platinum measurements (issue 11; Carr & Madani, seeds/000_...).

Oracles: closed-form statistics (1 - e^-2, eq. 4-1 by hand), known sub-pixel shifts, and
skimage.registration.phase_cross_correlation for the image-to-image correlation.
"""
import json
import math

import numpy as np
import pytest
from scipy.ndimage import fourier_shift, gaussian_filter
from scipy.stats import norm
from skimage.registration import phase_cross_correlation

from groundsim.assess.inr import (
    ERF3, InrConfig, MeasurementTable, assess, correlate_chips, kalman_veto, measurements_from_arrays,
    percentile_ci, platinum_mask, quality_metric, read_csv, synthetic_config, synthetic_population,
    type2_threshold, write_csv,
)


@pytest.fixture(scope="module")
def paper():
    table, truth = synthetic_population(seed=0)
    return table, truth, assess(table, synthetic_config())


# --- statistics ---------------------------------------------------------------------------------------

def test_ellipse_fraction_of_2d_normal():
    rng = np.random.default_rng(1)
    N = 20000
    C = np.array([[40.0, 12.0], [12.0, 15.0]])
    x = rng.multivariate_normal([0, 0], C, N)
    frac = platinum_mask(x, n=2).mean()
    p = 1 - math.exp(-2)                                   # 86.47 %
    assert abs(frac - p) < 4 * math.sqrt(p * (1 - p) / N)
    # n = 1 and n = 3 follow the same law
    assert abs(platinum_mask(x, n=1).mean() - (1 - math.exp(-0.5))) < 0.015
    assert abs(platinum_mask(x, n=3).mean() - (1 - math.exp(-4.5))) < 0.005


def test_type2_threshold_eq_4_1():
    r = 0.7
    by_hand = 1 - math.erf(3 / math.sqrt(2)) / math.erf(3 / (math.sqrt(2) * r))
    assert type2_threshold(r) == pytest.approx(by_hand, rel=1e-12)
    assert type2_threshold(r) == pytest.approx(0.0027, abs=5e-5)
    assert type2_threshold(1.0) == pytest.approx(0.0, abs=1e-15)
    ratios = np.array([0.1, 0.5, 0.7, 0.9, 0.99, 0.999, 1.0])
    p = type2_threshold(ratios)
    assert p.shape == ratios.shape and np.all(np.diff(p) < 0)          # falls to 0 as ratio -> 1
    assert p[-2] < 1e-4 and p[-1] == pytest.approx(0.0, abs=1e-15)
    assert type2_threshold(1e-6) == pytest.approx(1 - ERF3, rel=1e-12)  # "3-sigma reliable"
    assert type2_threshold(1.2) < 0                                     # fails even if infallible


def test_percentile_ci_is_an_order_statistic_interval():
    rng = np.random.default_rng(2)
    true = norm.ppf(0.997)                                   # 99.7th percentile of N(0, 1)
    hits = 0
    for _ in range(300):
        ci = percentile_ci(rng.standard_normal(4000), 99.7, 0.95)
        hits += ci["lower"] <= true <= ci["upper"]
    assert ci["coverage"] >= 0.95 and ci["l"] < ci["u"]
    assert hits / 300 > 0.92


def test_quality_metric_eq_3_1():
    f = {"a": np.array([1.0, 0.81, 0.5]), "b": np.array([1.0, 1.0, 0.5])}
    assert np.allclose(quality_metric(f), [1.0, 0.9, 0.5])
    assert np.allclose(quality_metric(f, {"a": 2.0}), [1.0, 0.81, 0.5 ** 1.5])
    with pytest.raises(ValueError, match="outside"):
        quality_metric({"a": np.array([1.2])})


# --- image-to-image correlation -----------------------------------------------------------------------

def _star_image(shape, rc, sigma=1.2, amp=1000.0, bg=50.0):
    r, c = np.mgrid[0:shape[0], 0:shape[1]] + 0.5
    img = np.full(shape, bg)
    for (y, x) in np.atleast_2d(rc):
        img += amp * np.exp(-((r - y) ** 2 + (c - x) ** 2) / (2 * sigma ** 2))
    return img


@pytest.mark.parametrize("shift", [(0.3, -0.45), (-0.7, 0.2), (1.25, 0.9), (0.0, 0.0)])
def test_correlation_recovers_known_subpixel_shift(shift):
    base = np.array([[16.2, 15.7], [11.0, 20.5], [21.3, 12.4]])
    prev = _star_image((32, 32), base)
    cur = _star_image((32, 32), base + np.array(shift))
    chip, nb = prev[8:25, 8:25], cur[5:28, 5:28]            # search +/-3 px
    s, rho, ok = correlate_chips(chip, nb)
    assert ok and rho > 0.9
    assert np.all(np.abs(s - shift) < 0.06), s


def test_correlation_agrees_with_phase_cross_correlation():
    rng = np.random.default_rng(4)
    tex = gaussian_filter(rng.standard_normal((64, 64)), 2.0)
    shift = np.array([0.4, -1.3])
    moved = np.fft.ifftn(fourier_shift(np.fft.fftn(tex), shift)).real
    oracle, _, _ = phase_cross_correlation(tex, moved, upsample_factor=100)
    s, rho, ok = correlate_chips(tex[20:45, 20:45], moved[16:49, 16:49])
    assert ok and rho > 0.95
    assert np.all(np.abs(s - (-oracle)) < 0.1) and np.all(np.abs(s - shift) < 0.1)


def test_measurements_from_arrays_relative_matches_absolute_difference():
    rng = np.random.default_rng(5)
    F, S = 6, 3
    t = np.arange(F) * 0.5
    stars = np.array([[30.3, 40.6], [60.8, 25.2], [45.1, 70.9]])
    pred = np.repeat(stars[None], F, 0) + np.arange(F)[:, None, None] * np.array([0.37, -0.21])
    err = rng.normal(0, 0.4, (F, S, 2))                      # true pointing error, px
    truth = pred + err
    frames = np.stack([_star_image((100, 100), truth[f]) for f in range(F)])
    meas = truth + rng.normal(0, 0.02, truth.shape)
    tab = measurements_from_arrays(t, [101, 102, 103], meas, pred, 50.0, frames=frames, imager="WFOV_VIS")
    assert len(tab) == F * S
    A = tab.abs_err.reshape(F, S, 2)                         # rows are frame-major
    R = tab.rel_err.reshape(F, S, 2)
    assert np.allclose(A, (meas - pred)[..., ::-1] * 50.0)
    assert np.all(np.isnan(R[0]))
    d = R[1:] - (A[1:] - A[:-1])
    assert np.max(np.abs(d)) < 0.1 * 50.0                    # < 0.1 px
    assert np.all(tab.rho.reshape(F, S)[1:] > 0.9)
    assert np.allclose(tab.rel_dt.reshape(F, S)[1:], 0.5)


# --- the paper's situation ----------------------------------------------------------------------------

def test_paper_scale_valid_at_threshold_platinum_complies(paper):
    table, truth, a = paper
    vis = a.compliance["nav"]["valid"]["VIS"]
    assert vis["n"] == 1781
    assert vis["n_noncompliant"] == 5 and vis["compliance_pct"] == pytest.approx(99.719, abs=5e-4)
    assert vis["margin"] == 0                                 # at the threshold of failure
    plat = a.compliance["nav"]["platinum"]["VIS"]
    assert plat["n_noncompliant"] == 0 and plat["meets"] and plat["n"] > 0.98 * 1781
    assert not a.platinum[truth["invalid_abs"]].any()
    for key, n_paper in (("900s", 706), ("5400s", 922)):
        ffr = a.compliance["ffr"][key]
        assert ffr["valid"]["VIS"]["n_noncompliant"] == 2
        assert ffr["platinum"]["VIS"]["n_noncompliant"] == 0
        assert abs(ffr["valid"]["VIS"]["n"] - n_paper) < 0.1 * n_paper
    assert not a.platinum_rel[truth["invalid_rel"]].any()
    # the IR channel-only excursion is consistent (platinum FFR) but a coregistration outlier: tarnished
    k = truth["ir_excursion"]
    assert a.platinum_rel[k].all() and a.tarnished[k].all() and not a.platinum[k].any()
    assert a.coreg["IR"]["coef_ns"][0] == pytest.approx(-6.0, abs=1.0)
    assert a.coreg["IR"]["coef_ew"][0] == pytest.approx(10.0, abs=1.0)


def test_real_excursion_is_not_removed_by_platinum():
    table, truth = synthetic_population(seed=0, excursion_urad=100.0, second_imager=False)
    a = assess(table, synthetic_config())
    ex = truth["excursion"]
    assert ex.size > 50
    assert a.platinum[ex].all()                               # consistent in A and R: platinum
    big = np.max(np.abs(a.nav[ex]), axis=1) > 65
    plat = a.compliance["nav"]["platinum"]["all"]
    assert plat["n_noncompliant"] >= big.sum() > 0.9 * ex.size
    assert not plat["meets"]
    # the Kalman veto, in contrast, removes most of it (outlier editing in the domain of the spec)
    av = assess(table, synthetic_config(kf_veto_sigma=4.0))
    assert av.vetoed[ex].mean() > 0.5


def test_kalman_veto_spares_gold(paper):
    table, truth, _ = paper
    a = assess(table, synthetic_config(kf_veto_sigma=4.0))
    inv = truth["invalid_abs"]
    assert np.array_equal(a.vetoed[inv], ~a.gold[inv])        # gold invalid pass, others vetoed
    assert a.gold[inv].sum() == 2 and a.vetoed.sum() <= len(inv) + 2
    # unit check: an isolated outlier is vetoed unless gold, and does not move the filter
    t = np.arange(50.0)
    z = np.zeros((50, 2))
    z[25] = [200.0, 0.0]
    v, nu = kalman_veto(t, z, np.zeros(50, bool), 4.0, 5.0, 0.1)
    assert np.flatnonzero(v).tolist() == [25] and abs(nu[26, 0]) < 1
    g = np.zeros(50, bool)
    g[25] = True
    assert not kalman_veto(t, z, g, 4.0, 5.0, 0.1)[0].any()


# --- CSV ----------------------------------------------------------------------------------------------

def _same(a: MeasurementTable, b: MeasurementTable):
    for name in ("time", "abs_err", "contamination", "rel_err", "rho", "rel_dt"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert (a.landmark_id == b.landmark_id).all() and (a.imager == b.imager).all()
    assert a.qm_factors.keys() == b.qm_factors.keys() and a.extra.keys() == b.extra.keys()
    for k in a.qm_factors:
        np.testing.assert_array_equal(a.qm_factors[k], b.qm_factors[k])


def test_csv_round_trip(tmp_path, paper):
    table, _, a = paper
    p = write_csv(table, tmp_path / "lm.csv")
    back = read_csv(p)
    _same(table, back)
    b = assess(back, synthetic_config())
    assert b.summary["compliance"] == a.summary["compliance"]


def test_bad_csv_names_column_and_line(tmp_path):
    hdr = "time,landmark_id,imager,ew_err_urad,ns_err_urad,qmf_fit"
    p = tmp_path / "missing.csv"
    p.write_text("time,landmark_id,imager,ew_err_urad,qmf_fit\n0,a,VIS,1.0,0.95\n")
    with pytest.raises(ValueError, match="missing required column 'ns_err_urad'"):
        read_csv(p)
    p = tmp_path / "nonnum.csv"
    p.write_text(f"{hdr}\n0,a,VIS,1.0,2.0,0.95\n1,a,VIS,abc,2.0,0.95\n")
    with pytest.raises(ValueError, match=r"line 3: column 'ew_err_urad': 'abc' is not a number"):
        read_csv(p)
    p = tmp_path / "range.csv"
    p.write_text(f"# c\n{hdr}\n0,a,VIS,1.0,2.0,1.5\n")
    with pytest.raises(ValueError, match=r"'qmf_fit' must lie in \[0, 1\]; line 3"):
        read_csv(p)
    p = tmp_path / "noqm.csv"
    p.write_text("time,landmark_id,imager,ew_err_urad,ns_err_urad\n0,a,VIS,1,2\n")
    with pytest.raises(ValueError, match="qm"):
        read_csv(p)


# --- report and CLI -----------------------------------------------------------------------------------

def test_cli_synthetic_and_report(tmp_path, capsys):
    from hil_harness.cli import main
    out = tmp_path / "syn"
    # two of the six injected type-II outliers carry gold-level QM, so the gold verdict fails: exit 1
    assert main(["inr", "synthetic", "--out", str(out), "--csv"]) == 1
    for name in ("inr_report.md", "summary.json", "inr_nav.png", "inr_inconsistency_VIS.png",
                 "inr_coregistration_IR.png", "inr_ffr_900s.png", "inr_ffr_5400s.png", "inr_type2.png"):
        assert (out / name).stat().st_size > 0, name
    s = json.loads((out / "summary.json").read_text())
    assert s["compliance"]["nav"]["valid"]["VIS"]["n_noncompliant"] == 5
    assert not s["compliance"]["nav"]["gold"]["VIS"]["meets"]
    printed = capsys.readouterr()
    assert "99.719" in printed.out and "Kalman veto not applied;" in printed.out
    assert "2 verdict(s) FAIL" in printed.err
    md = (out / "inr_report.md").read_text()
    assert "not applied sigma" not in md and "{" not in md.split("## Screening")[1].split("##")[0]
    # the CSV the synthetic command wrote, reported with the defaults: the same verdicts
    rep = tmp_path / "rep"
    assert main(["inr", "report", str(out / "inr_synthetic.csv"), "--out", str(rep)]) == 1
    r = json.loads((rep / "summary.json").read_text())
    assert r["compliance"] == s["compliance"]
    assert main(["inr", "report", str(out / "inr_synthetic.csv"), "--out", str(rep), "--veto-sigma", "none",
                 "--theta-ffr", "900:36", "--theta-ffr", "5400:49", "--moment", "core"]) == 1
    bad = tmp_path / "bad.csv"
    bad.write_text("time,landmark_id\n")
    assert main(["inr", "report", str(bad), "--out", str(rep)]) == 2
    assert "missing required column" in capsys.readouterr().err


@pytest.mark.parametrize("opts, named", [
    (["--veto-sigma", "-3"], "--veto-sigma"), (["--theta-ffr", "abc"], "--theta-ffr"),
    (["--theta-ffr", "900:x"], "--theta-ffr threshold"), (["--theta-nav", "0"], "--theta-nav"),
    (["--coreg-period", "nan"], "--coreg-period")])
def test_cli_bad_option_values_name_the_option(tmp_path, capsys, opts, named):
    from hil_harness.cli import main
    assert main(["inr", "synthetic", "--out", str(tmp_path / "o"), *opts]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()          # refused before anything is written


def test_cli_outlier_input_sets_the_verdict(tmp_path, capsys):
    """The paper's "5 of 1781" is an input of the synthetic population: with no outliers injected
    nothing is noncompliant and every verdict meets (exit 0)."""
    from hil_harness.cli import main
    out = tmp_path / "o0"
    assert main(["inr", "synthetic", "--out", str(out), "--outliers", "0"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["compliance"]["nav"]["valid"]["VIS"]["n_noncompliant"] == 0


def test_single_imager_default_config_runs():
    table, _ = synthetic_population(seed=1, second_imager=False, n_valid=400, n_sites=40)
    a = assess(table, InrConfig(theta_ffr_urad=40.0))
    assert a.coreg == {} and a.summary["counts"]["platinum"] > 300
    assert set(a.compliance["nav"]["valid"]) == {"all"}
