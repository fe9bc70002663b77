"""The groove family through the analysis' own loops (analysis/family_fits.py, analysis/controls.py), handed
synthetic contact measures in FoldSettings as the study will hand them: its LOSO fit, held-out flags, interval
check and permutation control, beside PLS under the same folds."""
from __future__ import annotations

import numpy as np
import pandas as pd

from roughsense.analysis.controls import control_row, specimen_permutations
from roughsense.analysis.family_fits import fit_all
from tests.model.groove.test_family import grating_study


def _tables(specimens, y):
    meta = pd.DataFrame({"specimen": specimens, "repetition": pd.Series(specimens).groupby(specimens).cumcount() + 1,
                         "image": [f"images/{s}_{i}.png" for i, s in enumerate(specimens)]})
    perceived = pd.DataFrame({"specimen": pd.unique(specimens)})
    perceived["gmean"] = perceived["specimen"].map(dict(zip(specimens, y)))
    perceived["sd"] = 0.1 * perceived["gmean"]
    return meta, perceived


def test_the_groove_family_runs_through_the_studys_loops_with_contact_measures():
    X, y, specimens, settings = grating_study(reps=3)
    y = pd.Series(y).groupby(specimens).transform("mean").to_numpy()  # one perceived value per specimen
    meta, perceived = _tables(specimens, y)
    pls, groove = fit_all(("pls", "groove"), X, y, meta, perceived, "smooth", "combined", "loso", settings,
                          max_components=3)
    assert groove.model == "groove" and list(groove.predictions["image"]) == list(pls.predictions["image"])
    assert groove.curve[0] == pls.curve[0]  # one null model under the same folds, whichever family
    assert groove.curve[1] < 0.3 * groove.curve[0]  # the groove width carries the roughness
    assert groove.held_out_flags.dtype == bool and groove.held_out_flags.any()  # the widest groove, left out
    assert len(groove.interval_check) == 12
    permutations = specimen_permutations(12, 199, 0)
    row = control_row(groove, X, y, specimens, permutations, settings)
    assert row["passes"] and row["permutation_p"] == 1 / 200  # no shuffling of 12 specimens comes near it
    pls_row = control_row(pls, X, y, specimens, permutations, settings)
    assert not pls_row["beats_permutation"]  # the spectra here are noise: PLS finds nothing
    np.testing.assert_allclose(row["rmse"], groove.curve[1], rtol=1e-12)
