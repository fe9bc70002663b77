"""Stricter held-out schemes (analysis/held_out.py): folds, scores and PLS's nested choice against independent
arithmetic (hand-computed values, scikit-learn's PLSRegression), and the study's table against a direct rerun."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from sklearn.cross_decomposition import PLSRegression

from roughsense.analysis.family_fits import law_settings
from roughsense.analysis.held_out import HELD_OUT_COLUMNS, judged, scheme_folds
from roughsense.analysis.study_analysis import analyse_study
from roughsense.model.peak_law.cv import peak_law_cv
from roughsense.model.pls.family import pls_scheme_predictions
from tests.analysis.test_study_analysis import synthetic_study

SHAPES = {"R2": "rectangular", "C2": "circular", "R3": "rectangular", "C3": "circular", "R4": "rectangular",
          "C4": "circular"}
WAVELENGTHS = {"R2": 2.0, "C2": 2.0, "R3": 3.0, "C3": 3.0, "R4": 4.0, "C4": 4.0}


def test_folds_hold_out_a_period_or_a_shape_whole():
    specimens = np.array(["R2", "R2", "C2", "R3", "C3", "C4"])
    period = scheme_folds("period", specimens, SHAPES, WAVELENGTHS)
    assert list(period) == ["2.0", "2.0", "2.0", "3.0", "3.0", "4.0"]
    assert list(scheme_folds("shape", specimens, SHAPES, WAVELENGTHS)) == [
        "rectangular", "rectangular", "circular", "rectangular", "circular", "circular"]
    assert list(scheme_folds("specimen", specimens, SHAPES, WAVELENGTHS)) == list(specimens)
    # A specimen of unknown period, or a single shape, cannot form the scheme: None, never a silent LOSO.
    assert scheme_folds("period", specimens, SHAPES, {**WAVELENGTHS, "C4": np.nan}) is None
    assert scheme_folds("shape", np.array(["R2", "R3"]), SHAPES, WAVELENGTHS) is None


def test_scores_by_hand():
    specimens = np.array(["R2", "R2", "C2", "C2", "R3", "R3"])
    y = np.array([0.5, 0.5, 0.8, 0.8, 1.0, 1.0])
    prediction = np.array([0.4, 0.6, 1.0, 1.2, 1.0, 1.0])
    folds = np.array(["r", "r", "c", "c", "r", "r"])
    row = judged(prediction, y, specimens, folds, SHAPES, "R3")
    # Per-specimen RMSE: R2 sqrt(0.01) = 0.1, C2 sqrt((0.04 + 0.16) / 2) = 0.3162, R3 0.
    assert row["rmse"] == pytest.approx((0.1 + np.sqrt(0.1) + 0.0) / 3)
    # Training mean under the folds: fold r's trials get C2's 0.8, fold c's the mean of R2 and R3, 0.75.
    assert row["null_rmse"] == pytest.approx((0.3 + 0.05 + 0.2) / 3)
    assert row["bias"] == pytest.approx((0.0 + 0.3 + 0.0) / 3)
    assert row["log_bias_rectangular"] == pytest.approx(0.0)
    assert row["log_bias_circular"] == pytest.approx(np.log(1.1 / 0.8))
    assert np.isnan(row["spearman_rho"])  # two rated specimens: no rank correlation


def _sklearn_fold_prediction(X, y, train, test, k):
    if k == 0:
        return np.full(test.sum(), y[train].mean())
    model = PLSRegression(n_components=k, scale=False).fit(X[train], y[train])
    return model.predict(X[test]).ravel()


def test_pls_under_a_period_left_out_chooses_its_components_without_it():
    """Each held-out period's count: the least LOSO RMSE over the training specimens (1..A), the prediction a
    refit at that count; both recomputed with scikit-learn's PLSRegression."""
    rng = np.random.default_rng(4)
    specimens = np.repeat(["R2", "C2", "R3", "C3", "R4", "C4"], 2)
    X = rng.normal(size=(12, 5))
    y = 1 + X @ np.array([0.3, -0.2, 0.1, 0.0, 0.05]) + 0.05 * rng.normal(size=12)
    folds = scheme_folds("period", specimens, SHAPES, WAVELENGTHS)
    ours = pls_scheme_predictions(X, y, specimens, folds, max_components=3)
    expected = np.empty(12)
    for fold in np.unique(folds):
        held = folds == fold
        rest = specimens[~held]
        Xr, yr = X[~held], y[~held]
        errors = []
        for k in range(1, 4):
            inner = np.empty(len(yr))
            for name in np.unique(rest):
                out = rest == name
                inner[out] = _sklearn_fold_prediction(Xr, yr, ~out, out, k)
            errors.append(np.sqrt(np.mean((inner - yr) ** 2)))
        expected[held] = _sklearn_fold_prediction(X, y, ~held, held, int(np.argmin(errors)) + 1)
    np.testing.assert_allclose(ours, expected, rtol=1e-8)


@pytest.fixture(scope="module")
def analysis():
    study, features = synthetic_study(repetitions=3, seed=5)
    return analyse_study(study, features=features, max_components=4, n_permutations=19, conditions=["2N"]), study, \
        features


def test_the_study_reports_every_scheme_and_its_period_rows_are_the_law_refitted(analysis):
    result, study, features = analysis
    table = result.held_out
    assert list(table.columns[: len(HELD_OUT_COLUMNS)]) == HELD_OUT_COLUMNS
    assert set(table["scheme"]) == {"specimen", "period", "shape"}
    # The specimen rows are the study's own LOSO numbers.
    unseen = result.unseen.set_index(["model", "pad", "condition"])
    for row in table[table.scheme == "specimen"].itertuples():
        assert row.rmse == pytest.approx(unseen.loc[(row.model, row.pad, row.condition), "rmse"])
        assert row.n_folds == result.perceived.shape[0]
    # A period left out: the law fitted without both shapes of each period, rerun here directly.
    law = table[(table.scheme == "period") & (table.model == "peak-law")].iloc[0]
    from roughsense.analysis import dataset

    X, meta = dataset.condition_matrix(features, law.pad, law.condition)
    y = dataset.targets(meta, result.perceived)
    specimens = meta["specimen"].astype(str).to_numpy()
    periods = np.array([str(result.wavelengths[s]) for s in specimens])
    settings = law_settings(X, result.freq_per_mm, study.pad_ridge_period_mm.get(law.pad), specimens)
    direct = peak_law_cv(X, y, groups=periods, **settings)[0]
    per = pd.DataFrame({"s": specimens, "e": (direct - y) ** 2}).groupby("s")["e"].mean()
    assert law.rmse == pytest.approx(float(np.sqrt(per).mean()))
    assert law.n_folds == len(set(periods)) and law.n_permutations == 19


def test_the_study_quotes_the_nested_jackknife_plus_and_its_misses(analysis):
    """The summary's coverage and misses are the nested check's; the unsure table marks each miss with its factor."""
    from roughsense.analysis.unseen import unsure_specimens

    result, _, _ = analysis
    unseen = result.unseen
    law = unseen[unseen.model == "peak-law"].iloc[0]
    fit = result.condition_fit(law.pad, law.condition, "loso", "peak-law")
    check = fit.interval_check
    assert law.jackknife_plus_coverage == pytest.approx(check["covered"].mean())
    missed = check[~check["covered"]]
    assert [part.split(" ")[0] for part in law.jackknife_plus_misses.split("; ") if part] == list(missed["specimen"])
    assert np.isnan(unseen[unseen.model == "pls"]["jackknife_plus_coverage"]).all()  # PLS has no leave-two-out fits
    unsure = unsure_specimens(result.perceived, result, "peak-law", per_pad=14)
    for row in unsure[unsure.pad == law.pad].itertuples():
        mine = check.set_index("specimen").loc[row.specimen]
        assert row.covered == mine["covered"] and row.pi90_low == pytest.approx(mine["pi90_low"])
        if not row.covered:  # outside by exp(miss_log): the perceived value over the bound it passed
            bound = row.pi90_low if row.perceived < row.pi90_low else row.pi90_high
            assert row.missed_by == pytest.approx(max(bound / row.perceived, row.perceived / bound))


def test_presses_per_surface_reach_the_loso_error_with_every_press_and_predict_says_when_too_few(analysis):
    """Read from all its presses, a held-out surface's error is LOSO's own; predict's line names the presses needed."""
    from roughsense.analysis.presses import presses_needed
    from roughsense.cli.predict import few_presses_line

    result, _, _ = analysis
    presses = result.presses
    assert set(presses["model"]) == {"peak-law"} and list(presses["n_presses"].unique()) == [1, 3]  # 3 repetitions
    unseen = result.unseen.set_index(["model", "pad", "condition"])
    for row in presses[presses["n_presses"] == 3].itertuples():  # every press: the study's LOSO surface means
        fit = result.condition_fit(row.pad, row.condition, "loso", "peak-law")
        means = fit.predictions.groupby("specimen")["prediction"].mean()
        perceived = result.perceived.set_index("specimen")["gmean"]
        assert row.rmse == pytest.approx(float(np.abs(means - perceived[means.index]).mean()), rel=1e-6)
        assert row.null_rmse == pytest.approx(unseen.loc[("peak-law", row.pad, row.condition), "null_rmse"])
    curve = pd.DataFrame({"n_presses": [1, 3, 5], "rmse": [0.32, 0.28, 0.20], "null_rmse": [0.33] * 3})
    assert presses_needed(curve) == 5  # 3 presses gain 0.05 of the 0.13 that 5 gain: less than half
    assert presses_needed(curve.assign(rmse=[0.32, 0.25, 0.20])) == 3
    assert presses_needed(curve.assign(rmse=[0.40, 0.36, 0.34])) is None
    training = {"presses": {"needed": 3, "null_rmse": 0.33, "rmse_by_presses": {"1": 0.35, "3": 0.30}}}
    line = few_presses_line(training, None, 4)
    assert line.startswith("fewer presses than this model's pad needs: a surface read from 1 press here")
    assert "needed 3 to beat the training mean clearly (held-out error 0.35 vs the training mean's 0.33)" in line
    assert few_presses_line(training, ["a"] * 3 + ["b"] * 3, 6) == ""


def test_folds_hold_out_a_land_groove_geometry_whole_and_only_where_the_study_has_one():
    specimens = np.array(["R2", "R2", "C2", "R3", "C3", "R4"])
    geometries = {"R2": "land 0.3", "R3": "land 0.5", "R4": "land 0.3", "C2": "circular", "C3": "circular"}
    folds = scheme_folds("geometry", specimens, SHAPES, WAVELENGTHS, geometries)
    assert list(folds) == ["land 0.3", "land 0.3", "circular", "land 0.5", "circular", "land 0.3"]
    # No geometries (the study has one rectangular geometry, or none known): None, never a silent other scheme.
    assert scheme_folds("geometry", specimens, SHAPES, WAVELENGTHS, {}) is None
    assert scheme_folds("geometry", specimens, SHAPES, WAVELENGTHS) is None


def test_a_study_without_land_widths_skips_the_geometry_scheme_and_says_why(analysis):
    result, _, _ = analysis
    assert "geometry" not in set(result.held_out["scheme"])
    assert result.geometry_note == "no land width (ridge_width_mm) in specimens.csv for R2 and 6 more"


def test_a_land_groove_geometry_left_out_is_the_law_fitted_without_every_grating_of_it():
    """Two of the synthetic rectangles declared land 0.3 of their period (specimens.csv's ridge_width_mm): the scheme
    holds them out together, one row per geometry, each the law refitted without that geometry, rerun directly."""
    from roughsense.analysis import dataset

    study, features = synthetic_study(repetitions=3, seed=5, pads=("smooth",))
    table = study.specimens.copy()
    narrow = table["specimen"].isin(["R2.5", "R4.5"])
    rectangular = table["shape"] == "rectangular"
    table["ridge_width_mm"] = np.where(rectangular, table["wavelength_mm"] * np.where(narrow, 0.3, 0.5), np.nan)
    study = dataclasses.replace(study, specimens=table)
    result = analyse_study(study, features=features, max_components=3, n_permutations=0, conditions=["2N"])
    assert result.geometry_note == ""
    rows = result.held_out[result.held_out.scheme == "geometry"]
    assert set(rows["held_out"]) == {"land 0.3", "land 0.5"}  # the circles held out alone are the shape scheme's row
    law = rows[(rows.model == "peak-law") & (rows.held_out == "land 0.3")].iloc[0]
    X, meta = dataset.condition_matrix(features, law.pad, law.condition)
    y = dataset.targets(meta, result.perceived)
    specimens = meta["specimen"].astype(str).to_numpy()
    groups = np.array([result.geometries[s] for s in specimens])
    settings = law_settings(X, result.freq_per_mm, None, specimens)
    direct = peak_law_cv(X, y, groups=groups, **settings)[0]
    held = groups == "land 0.3"
    per = pd.DataFrame({"s": specimens[held], "e": (direct[held] - y[held]) ** 2}).groupby("s")["e"].mean()
    assert law.rmse == pytest.approx(float(np.sqrt(per).mean()))
    assert law.n_folds == 3
