"""The screens of ``bench/allsky_exact_choice.py`` (every sequence it writes is one the flight's
loader accepts, as the grid says, with no two alike) and ``bench/allsky_sparse_choice.py`` (every
small set of features but the centroids, once)."""
from __future__ import annotations

import numpy as np

from bench.allsky_exact_choice import grid, sequence_toml
from flightsw.ip.detrend import default_taps


def test_every_screened_sequence_loads_as_its_grid_entry(tmp_path):
    from hil_harness.detect.jobs import resolve_sequence
    specs = grid()
    assert len(specs) == len(set(specs)) == 210
    for i, spec in enumerate(specs):
        comp, detrend, sigma, filt, alpha, mode = spec
        path = tmp_path / f"s{i}.toml"
        path.write_text(sequence_toml(spec))
        seq = resolve_sequence(str(path))
        assert seq.preprocess.compaction == comp == 4
        ops = {step.op: step for step in seq.steps}
        assert ("detrend" in ops) == (detrend != "none")
        if detrend != "none":
            assert ops["detrend"].params.method == detrend
        if detrend == "highpass":
            assert np.array_equal(ops["detrend"].params.taps, default_taps(sigma))
        assert ("filter" in ops) == (filt != "none")
        if filt != "none":
            assert ops["filter"].params.name == filt
        assert ops["threshold"].params.alpha_q12 == round(alpha * 4096)     # Q4.12
        assert ops["threshold"].params.mode == mode


def test_the_sparse_screen_covers_every_small_set_of_non_centroid_features():
    from math import comb

    from bench.allsky_sparse_choice import subsets
    from flightsw.messages import FEATURE_NAMES
    sets = subsets(3)
    assert len(sets) == len(set(sets)) == comb(10, 1) + comb(10, 2) + comb(10, 3)
    assert [len(s) for s in sets] == sorted(len(s) for s in sets)       # smaller sets first
    for s in sets:
        assert not {"row", "col"} & set(s) and set(s) <= set(FEATURE_NAMES)
        assert list(s) == sorted(s, key=FEATURE_NAMES.index)
    assert subsets(1) == [(f,) for f in FEATURE_NAMES if f not in ("row", "col")]
