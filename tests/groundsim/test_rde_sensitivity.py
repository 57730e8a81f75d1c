"""The RDE study's sensitivity to its a priori error model (``rde study --sensitivity``)."""
import csv
import dataclasses
import json

import numpy as np
import pytest

from groundsim.assess.rde_models import ErrorModel
from groundsim.assess.rde_sensitivity import (PARAMETERS, needed_standard_error, run_sensitivity,
                                              scaled_error_model)
from groundsim.assess.rde_study import StudyConfig, epsilon90_grid

# a coarse time grid and a tiny study grid keep every test here to a few seconds
CFG = StudyConfig(lines_per_scene=10)
TINY = dict(parameters=("sigma1", "sigma_pos0"), scales=(0.5, 1.0, 2.0), realisations=16,
            config=CFG, fig2_densities=(2, 8), fig2_sigmas=(3.0, 6.7), lengths=(2, 4),
            densities=(2, 4, 8, 16, 32, 64))


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("sens")
    return out, run_sensitivity(out, **TINY)


def test_tiny_grid_has_the_promised_rows_columns_and_files(tiny):
    out, res = tiny
    rows = res["rows"]
    assert [(r["parameter"], r["scale"]) for r in rows] == [
        (p, s) for p in ("sigma1", "sigma_pos0") for s in (0.5, 1.0, 2.0)]
    for ns in (18, 12):
        for d in (2, 8):
            assert {f"eps90_{ns}s_d{d}", f"eps90_{ns}s_d{d}_se"} <= set(rows[0])
    assert {"needed_18s_L2", "needed_18s_L4", "needed_18s_L4_se", "ordering_holds",
            "max_rel_12_vs_18"} <= set(rows[0])
    # the unscaled model is run once and shared: identical rows apart from the parameter's name
    base = [r for r in rows if r["scale"] == 1.0]
    assert all(base[0][k] == base[1][k] for k in base[0] if k not in ("parameter", "field", "value"))
    with open(out / "rde_sensitivity.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 6 and set(table[0]) == set(rows[0])
    md = (out / "rde_sensitivity.md").read_text().splitlines()
    assert sum(line.startswith("| sigma") for line in md) == 6
    doc = json.loads((out / "rde_sensitivity.json").read_text())   # strict JSON: NaN as null
    assert doc["settings"]["realisations"] == 16 and len(doc["rows"]) == 6
    assert (out / "rde_sensitivity.png").stat().st_size > 5000
    assert not list(out.glob("*.tmp*"))


def test_a_failed_write_leaves_no_files(tiny, tmp_path, monkeypatch):
    import groundsim.assess.rde_sensitivity as sens

    def broken_plot(result, path):
        raise RuntimeError("disk full")

    monkeypatch.setattr(sens, "plot_sensitivity", broken_plot)
    with pytest.raises(RuntimeError):
        sens.write_sensitivity(tiny[1], tmp_path / "o")
    assert list((tmp_path / "o").iterdir()) == []


def test_scaling_follows_the_named_sigma():
    base = ErrorModel()
    # sigma1 is the square root of the PSD q_att_angle: x2 on sigma1 is x4 on the PSD
    assert scaled_error_model(base, "sigma1", 2.0).q_att_angle == pytest.approx(4 * base.q_att_angle)
    assert scaled_error_model(base, "sigma_pos0", 0.25).sigma_pos0 == pytest.approx(7.5)
    em = scaled_error_model(base, "sigma_align_rate0", 4.0)
    assert em.sigma_align_rate0 == pytest.approx(1.0e-7) and em.sigma_align0 == base.sigma_align0
    assert set(PARAMETERS) == {"sigma1", "sigma_align_rate0", "sigma_att0", "sigma_align0",
                               "sigma_pos0"}
    with pytest.raises(ValueError, match="unknown error-model parameter"):
        scaled_error_model(base, "sigma9", 2.0)
    with pytest.raises(ValueError, match="positive"):
        scaled_error_model(base, "sigma1", 0.0)


def test_a_larger_random_walk_or_measurement_error_never_lowers_eps90(tiny):
    """For the matched (18-state) estimator the smoother's error covariance is non-decreasing in
    the process noise and in the measurement noise (Riccati comparison), and the truth it must
    follow grows too; on a common seed set epsilon_90 and the density needed must not fall."""
    _, res = tiny
    rows = [r for r in res["rows"] if r["parameter"] == "sigma1"]
    for col in ("eps90_18s_d2", "eps90_18s_d8", "needed_18s_L4"):
        vals = [r[col] for r in rows]
        assert np.all(np.diff(vals) > 0), (col, vals)
    for run in res["runs"]:
        e = run["figure2"]["eps90_mean"]                       # (D, S, E)
        assert np.all(e[:, 1, :] > e[:, 0, :])                 # 6.7 m error worse than 3 m
        assert run["ordering"]["rises_with_sigma"]


def test_needed_density_standard_error_of_a_power_law():
    """eps90 = A d^-b with relative standard error c: the density needed is (A / r)^(1/b) and, to
    first order, its standard error is that times c / b."""
    A, b, c, r = 20.0, 0.8, 0.03, 4.9
    d = np.array([1, 2, 4, 8, 16, 32], dtype=float)
    e = A * d ** -b
    se = needed_standard_error(d, e, c * e, r)
    assert se == pytest.approx((A / r) ** (1 / b) * c / b, rel=1e-12)
    assert np.isnan(needed_standard_error(d, e, c * e, 100.0))     # met at the first density
    assert np.isnan(needed_standard_error(d, e, c * e, 0.1))       # never met


def test_scaling_the_whole_model_and_the_measurement_error_scales_eps90_exactly():
    """Closed form: multiplying every a priori and process-noise sigma and the measurement error by
    k leaves the Kalman gains unchanged (P0, Q, R all scale by k^2) while truth and noise scale by
    k, so every residual and epsilon_90 scale by exactly k."""
    k = 2.0
    base = ErrorModel()
    sig = {f.name: getattr(base, f.name) * k for f in dataclasses.fields(base)
           if f.name.startswith("sigma_")}
    psd = {n: getattr(base, n) * k * k for n in ("q_acc", "q_att_angle", "q_att_drift")}
    scaled = dataclasses.replace(CFG, error_model=dataclasses.replace(base, **sig, **psd))
    kw = dict(realisations=3, chunk=3)
    a = epsilon90_grid([2], (3,), (6.7,), (18, 12), config=CFG, **kw)["eps90_mean"]
    b = epsilon90_grid([2], (3,), (6.7 * k,), (18, 12), config=scaled, **kw)["eps90_mean"]
    np.testing.assert_allclose(b, k * a, rtol=1e-9)


def test_cli_sensitivity_writes_table_with_progress(tmp_path, capsys, monkeypatch):
    from hil_harness.cli import main
    import groundsim.assess.rde_sensitivity as sens
    orig = sens.run_sensitivity
    seen = {}

    def small(out, **kw):           # the CLI's own options, on the tiny grid
        seen.update(kw)
        tiny_kw = {k: v for k, v in TINY.items() if k not in ("realisations", "scales")}
        return orig(out, **{**tiny_kw, **kw, "lengths": (2,), "densities": (2, 8, 32)})

    monkeypatch.setattr(sens, "run_sensitivity", small)
    monkeypatch.setenv("UVISI_PROGRESS", "1")
    assert main(["rde", "study", "--sensitivity", "--quick", "--realisations", "2",
                 "--workers", "1", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert seen["realisations"] == 2 and seen["scales"] == (0.5, 1.0, 2.0)
    assert "| sigma1 | x0.5 |" in cap.out and "rde sensitivity" in cap.err
    assert (tmp_path / "rde_sensitivity.csv").exists() and (tmp_path / "rde_sensitivity.png").exists()


@pytest.mark.parametrize("argv, needle", [
    (["--realisations", "1"], "--realisations 1"),
    (["--workers", "0"], "--workers 0"),
    (["--out", "FILE"], "is a file, not a folder"),
])
def test_cli_sensitivity_bad_options_are_one_line_errors(tmp_path, capsys, argv, needle):
    from hil_harness.cli import main
    f = tmp_path / "afile"
    f.write_text("x")
    names_file = "FILE" in argv
    argv = [str(f) if a == "FILE" else a for a in argv]
    assert main(["rde", "study", "--sensitivity"] + argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("uvisi rde: error:") and needle in err[0]
    assert str(f) in err[0] or not names_file


def test_study_report_says_figure3_level_is_calibrated(tmp_path, capsys, monkeypatch):
    from hil_harness.cli import main
    import groundsim.assess.rde_study as st
    orig = st.run_study

    def small(out, **kw):
        return orig(out, config=CFG, figure2_kw=dict(densities=(2, 8), sigmas=(3.0, 6.7)),
                    figure3_kw=dict(n_scenes_list=(2,), densities=(2, 8, 32)), **kw)

    monkeypatch.setattr(st, "run_study", small)
    assert main(["rde", "study", "--quick", "--realisations", "2", "--workers", "1",
                 "--out", str(tmp_path)]) == 0
    assert "rde study --sensitivity" in capsys.readouterr().out
    doc = json.loads((tmp_path / "rde_study.json").read_text())
    assert set(doc["config"]["calibrated"]["inputs"]) == {
        f"error_model.{PARAMETERS[p][0]}" for p in ("sigma1", "sigma_align_rate0")}
