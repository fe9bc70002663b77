"""The study analysis, checked against independent refits (scikit-learn), scipy and closed forms.

The study here is synthetic and in memory: spectra with a peak at 1/wavelength plus noise, and
ratings drawn around the paper's perceived roughness, so the analysis runs in seconds.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, stats
from sklearn.cross_decomposition import PLSRegression

from roughsense import paper as published
from roughsense.analysis import dataset
from roughsense.analysis.study_analysis import analyse_study
from roughsense.errors import InputError
from roughsense.io.sensor_settings import SensorSettings
from roughsense.io.study import Study
from roughsense.model.registry import names as family_names

FREQS = np.linspace(0.1, 1.0, 45)
FREQ_COLUMNS = dataset.spectrum_columns(FREQS)


def synthetic_study(*, repetitions: int = 6, seed: int = 0, pads=("smooth", "fingerprint")):
    rng = np.random.default_rng(seed)
    perceived = published.perceived_roughness()
    specimens = perceived[["specimen", "shape", "wavelength_mm"]].copy()
    rows = []
    for pad in pads:
        for _, spec in specimens.iterrows():
            peak = 1.0 / spec.wavelength_mm * (1.05 if spec["shape"] == "circular" else 1.0)
            for rep in range(1, repetitions + 1):
                jitter = rng.normal(0, 0.02)
                for force in (1.0, 2.0, 3.0):
                    spectrum = np.exp(-0.5 * ((FREQS - peak - jitter) / (0.04 + 0.01 * force)) ** 2)
                    if pad == "fingerprint":
                        spectrum += 0.5 * np.exp(-0.5 * ((FREQS - 1.0) / 0.03) ** 2)
                    spectrum += rng.normal(0, 0.05, FREQS.size) ** 2
                    spectrum /= np.trapezoid(spectrum, FREQS)
                    rows.append({"image": f"images/{pad}_{spec.specimen}_{rep}_{force:g}.png", "specimen": spec.specimen,
                                 "pad": pad, "force_n": force, "repetition": rep, "nominal_force_n": force,
                                 "condition": f"{force:g}N", **dict(zip(FREQ_COLUMNS, spectrum))})
    features = pd.DataFrame(rows)
    ratings = []
    for participant in range(1, 11):
        scale = rng.lognormal(0, 0.2)
        for session in range(1, 4):
            for _, p in perceived.iterrows():
                if p.specimen == "R3":
                    continue
                ratings.append({"participant": f"P{participant}", "session": str(session), "specimen": p.specimen,
                                "rating": p.perceived_gmean * scale * rng.lognormal(0, 0.1)})
    manifest = features[["image", "specimen", "pad", "force_n", "repetition", "nominal_force_n", "condition"]]
    study = Study(root=__import__("pathlib").Path("/nonexistent"), name="synthetic", reference_specimen="R3",
                  sensor=SensorSettings(), forces_n=(1.0, 2.0, 3.0), specimens=specimens, manifest=manifest,
                  ratings=pd.DataFrame(ratings),
                  pad_ridge_period_mm={"fingerprint": 1.0} if "fingerprint" in pads else {})
    return study, features


@pytest.fixture(scope="module")
def analysis_and_inputs():
    study, features = synthetic_study()
    analysis = analyse_study(study, features=features, max_components=8, n_permutations=9)
    return analysis, study, features


def _gmean_of_medians(ratings: pd.DataFrame) -> pd.Series:
    medians = ratings.groupby(["specimen", "participant"])["rating"].median()
    return medians.groupby("specimen").apply(lambda m: float(np.exp(np.log(m).mean())))


def _regression_data(study, features, pad: str, condition: str):
    """Rows, X and y of one pad and condition, built independently of roughsense.analysis.dataset."""
    rows = features[(features.pad == pad) & (features.condition == condition)].reset_index(drop=True)
    gmean = _gmean_of_medians(study.ratings)
    gmean["R3"] = 1.0
    return rows, rows[FREQ_COLUMNS].to_numpy(), rows["specimen"].map(gmean).to_numpy()


def test_loo_predictions_match_sklearn_refits(analysis_and_inputs):
    analysis, study, features = analysis_and_inputs
    fit = analysis.condition_fit("smooth", "2N", "loo")
    rows, X, y = _regression_data(study, features, "smooth", "2N")
    expected = np.empty(len(y))
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        model = PLSRegression(n_components=fit.best, scale=False).fit(X[keep], y[keep])
        expected[i] = model.predict(X[i : i + 1]).ravel()[0]
    got = fit.predictions.merge(rows[["specimen", "repetition"]].assign(expected=expected), on=["specimen", "repetition"])
    np.testing.assert_allclose(got["prediction"], got["expected"], rtol=1e-6, atol=1e-9)
    # The chosen count is the argmin of the CV curve over 1..max.
    assert fit.best == 1 + int(np.argmin(fit.curve[1:]))


def test_loso_never_trains_or_chooses_on_the_held_out_specimen(analysis_and_inputs):
    """Nested LOSO, recomputed with scikit-learn: inner LOSO over the other specimens picks k, then refit."""
    analysis, study, features = analysis_and_inputs
    fit = analysis.condition_fit("fingerprint", "1N", "loso")
    rows, X, y = _regression_data(study, features, "fingerprint", "1N")
    specimens = rows["specimen"].to_numpy()
    held = specimens == "C4"
    Xr, yr, sr = X[~held], y[~held], specimens[~held]
    max_k = min(8, len(yr) - 6 - 1)
    inner_sse = np.zeros(max_k + 1)
    for other in np.unique(sr):
        test = sr == other
        for k in range(1, max_k + 1):
            model = PLSRegression(n_components=k, scale=False).fit(Xr[~test], yr[~test])
            inner_sse[k] += np.sum((model.predict(Xr[test]).ravel() - yr[test]) ** 2)
    k_expected = 1 + int(np.argmin(inner_sse[1:]))
    assert fit.per_specimen["C4"] == k_expected
    model = PLSRegression(n_components=k_expected, scale=False).fit(Xr, yr)
    expected = model.predict(X[held]).ravel()
    got = fit.predictions[fit.predictions.specimen == "C4"].sort_values("repetition")["prediction"].to_numpy()
    np.testing.assert_allclose(got, expected[np.argsort(rows.loc[held, "repetition"].to_numpy())], rtol=1e-6)
    assert set(fit.per_specimen) == set(np.unique(specimens))


def test_per_specimen_rmse_and_ovl_follow_their_definitions(analysis_and_inputs):
    analysis, study, _ = analysis_and_inputs
    fit = analysis.condition_fit("smooth", "combined", "loo")
    perceived = analysis.perceived.set_index("specimen")
    for specimen in ("R2", "C5"):
        preds = fit.predictions.loc[fit.predictions.specimen == specimen, "prediction"].to_numpy()
        row = fit.table.set_index("specimen").loc[specimen]
        g, s = perceived.loc[specimen, "gmean"], perceived.loc[specimen, "sd"]
        assert row["rmse"] == pytest.approx(np.sqrt(np.mean((preds - g) ** 2)), rel=1e-9)
        assert row["pred_mean"] == pytest.approx(preds.mean(), rel=1e-9)
        assert row["pred_sd"] == pytest.approx(preds.std(ddof=0), rel=1e-9)  # population SD, as the paper's tables
        m2, s2 = preds.mean(), preds.std(ddof=0)
        numeric, _ = integrate.quad(lambda x: min(stats.norm.pdf(x, g, s), stats.norm.pdf(x, m2, s2)), -10, 10,
                                    points=[g, m2], limit=200)
        assert row["ovl"] == pytest.approx(numeric, abs=1e-6)
    assert np.isnan(fit.table.set_index("specimen").loc["R3", "ovl"])


def test_combined_uses_all_three_forces_of_a_trial(analysis_and_inputs):
    analysis, _, _ = analysis_and_inputs
    fit = analysis.condition_fit("smooth", "combined", "loo")
    assert len(fit.predictions) == 14 * 6
    curves = analysis.cv_table().query("condition == 'combined' and cv == 'loo' and pad == 'smooth'")
    assert (curves["model"] == "pls").sum() == 9  # 0..8 components
    assert (curves["model"] == "peak-law").sum() == 2  # the training mean, then the law


def test_signed_rank_tests_match_scipy(analysis_and_inputs):
    analysis, _, _ = analysis_and_inputs
    results = analysis.results("loo")
    results = results[results.model == "pls"]  # tests.csv holds the paper's comparisons, of its PLS
    tests = analysis.tests.set_index(["cv", "comparison"])
    for pad in ("smooth", "fingerprint"):
        comb = results[(results.pad == pad) & (results.condition == "combined")].set_index("specimen")["rmse"]
        one = results[(results.pad == pad) & (results.condition == "1N")].set_index("specimen")["rmse"].reindex(comb.index)
        row = tests.loc[("loo", f"{pad}: combined vs 1N")]
        diff = comb.to_numpy() - one.to_numpy()
        expected = stats.wilcoxon(diff, method="exact" if np.count_nonzero(diff) <= 15 else "approx")
        ranks = stats.rankdata(np.abs(diff[diff != 0]))
        assert row["statistic"] == pytest.approx(ranks[diff[diff != 0] > 0].sum())
        assert row["p"] == pytest.approx(expected.pvalue, rel=1e-6)
        assert row["p_adjusted"] == pytest.approx(min(1.0, 3 * expected.pvalue), rel=1e-6)
    assert ("loo", "combined: smooth vs fingerprint") in tests.index


def test_results_follow_the_paper_schema(analysis_and_inputs):
    analysis, _, _ = analysis_and_inputs
    paper = published.paper_results()
    for cv in ("loo", "loso"):
        results = analysis.results(cv)
        # The paper's columns first, unchanged; ours are only ever added after them.
        assert list(results.columns[: len(paper.columns)]) == list(paper.columns)
        assert list(results.columns[len(paper.columns):]) == ["predictive_sd", "ovl_predictive", "model"]
        for model in ("pls", "peak-law"):
            rows = results[results["model"] == model]
            assert set(map(tuple, rows[["pad", "specimen", "condition"]].to_numpy())) == set(
                map(tuple, paper[["pad", "specimen", "condition"]].to_numpy())
            )


def test_summary_rows_are_mean_and_sample_sd(analysis_and_inputs):
    analysis, study, _ = analysis_and_inputs
    results = analysis.results("loo")
    for model in ("pls", "peak-law"):
        summary = analysis.summary("loo", "rmse", model).set_index(["pad", "condition", "group"])
        rect = results[(results.model == model) & (results.pad == "smooth") & (results.condition == "1N")
                       & results.specimen.str.startswith("R")]
        row = summary.loc[("smooth", "1N", "rectangular")]
        assert row["mean"] == pytest.approx(rect["rmse"].mean())
        assert row["sd"] == pytest.approx(rect["rmse"].std(ddof=1))


def test_too_few_repetitions_is_a_clear_error():
    study, features = synthetic_study(repetitions=3)
    features = features[~((features.specimen == "C3") & (features.repetition > 1))]
    with pytest.raises(InputError, match="too few repetitions.*C3"):
        analyse_study(study, features=features, max_components=4)


def test_missing_ratings_is_a_clear_error():
    study, features = synthetic_study(repetitions=2)
    study.ratings = None
    with pytest.raises(InputError, match="ratings"):
        analyse_study(study, features=features, max_components=2)


def _without_model(frame: pd.DataFrame, model: str = "pls") -> pd.DataFrame:
    return frame[frame["model"] == model].drop(columns="model").reset_index(drop=True)


def test_pls_numbers_do_not_change_beside_the_peak_law(analysis_and_inputs):
    """Every PLS number is the same, bit for bit, as in a run that fits PLS alone; the law's rows come after them."""
    analysis, study, features = analysis_and_inputs
    alone = analyse_study(study, features=features, max_components=8, n_permutations=9, models=("pls",))
    for frame in ("cv_table", "chosen_components", "predictions"):
        both, single = getattr(analysis, frame)(), getattr(alone, frame)()
        assert list(both.columns)[-1] == "model" and set(both["model"]) == set(family_names())
        pd.testing.assert_frame_equal(_without_model(both), _without_model(single), check_exact=True)
        assert list(both["model"]) == sorted(both["model"], key=family_names().index)  # PLS's rows first
    for cv in ("loo", "loso"):
        pd.testing.assert_frame_equal(_without_model(analysis.results(cv)), _without_model(alone.results(cv)),
                                      check_exact=True)
    pd.testing.assert_frame_equal(_without_model(analysis.controls), _without_model(alone.controls), check_exact=True)
    assert len(analysis.controls) == len(family_names()) * len(alone.controls) and list(analysis.controls.columns)[-1] == "model"
    pd.testing.assert_frame_equal(analysis.tests, alone.tests, check_exact=True)


def _combined_rows(features: pd.DataFrame, pad: str):
    """One row per trial, its 1 N, 2 N and 3 N spectra side by side (built without roughsense.analysis.dataset)."""
    at_pad = features[features.pad == pad]
    blocks = [at_pad[at_pad.condition == c].set_index(["specimen", "repetition"])[FREQ_COLUMNS] for c in ("1N", "2N", "3N")]
    joined = pd.concat(blocks, axis=1)
    return joined.index.to_frame(index=False), joined.to_numpy()


def test_peak_law_loso_predictions_are_refits_on_the_other_specimens(analysis_and_inputs):
    """PeakPowerLaw refitted without each specimen (3 force spectra per row, the pad's ridges left out) predicts it."""
    from roughsense.model.peak_law.law import PeakPowerLaw

    analysis, study, features = analysis_and_inputs
    keys, X = _combined_rows(features, "fingerprint")
    gmean = _gmean_of_medians(study.ratings)
    gmean["R3"] = 1.0
    y = keys["specimen"].map(gmean).to_numpy()
    expected = np.empty(len(y))
    for specimen in keys["specimen"].unique():
        held = (keys["specimen"] == specimen).to_numpy()
        surfaces = keys["specimen"].to_numpy()  # a specimen's presses share where its peak is
        law = PeakPowerLaw(freq_per_mm=FREQS, n_blocks=3, pad_ridge_period_mm=1.0).fit(X[~held], y[~held],
                                                                                        surfaces=surfaces[~held])
        expected[held] = law.predict(X[held], surfaces=surfaces[held])
    fit = analysis.condition_fit("fingerprint", "combined", "loso", "peak-law")
    got = fit.predictions.merge(keys.assign(expected=expected), on=["specimen", "repetition"])
    assert len(got) == len(y)
    np.testing.assert_allclose(got["prediction"], got["expected"], rtol=1e-9, atol=1e-12)
    assert fit.curve[1] == pytest.approx(np.sqrt(np.mean((expected - y) ** 2)), rel=1e-9)
    # Index 0 is the training mean under the same folds: PLS's 0-component LOSO, the same number.
    assert fit.curve[0] == analysis.condition_fit("fingerprint", "combined", "loso").curve[0]
    assert (fit.best, fit.one_se, fit.per_specimen) == (1, 1, {})


def test_peak_law_loo_predictions_are_refits_without_each_trial(analysis_and_inputs):
    """Each trial is predicted by the law refitted without it; where its specimen's peak is comes from the spectra of
    all that specimen's presses (spectra, never ratings: the held-out rating is used nowhere)."""
    from roughsense.model.peak_search import peak_features
    from tests.analysis.test_controls import _refit_on_features

    analysis, study, features = analysis_and_inputs
    rows, X, y = _regression_data(study, features, "smooth", "2N")
    surfaces = rows["specimen"].to_numpy()
    read = peak_features(X, FREQS, surfaces=surfaces)
    expected = np.array([_refit_on_features(read, y, np.arange(len(y)) != i, np.arange(len(y)) == i,
                                            surfaces=surfaces)[0] for i in range(len(y))])
    fit = analysis.condition_fit("smooth", "2N", "loo", "peak-law")
    got = fit.predictions.merge(rows[["specimen", "repetition"]].assign(expected=expected), on=["specimen", "repetition"])
    np.testing.assert_allclose(got["prediction"], got["expected"], rtol=1e-9, atol=1e-12)


def test_unseen_summary_follows_its_definitions(analysis_and_inputs):
    analysis, _, _ = analysis_and_inputs
    unseen = analysis.unseen.set_index(["model", "pad", "condition"])
    assert len(unseen) == len(family_names()) * 2 * 4
    loso = analysis.results("loso")
    controls = analysis.controls[analysis.controls.cv == "loso"].set_index(["model", "pad", "condition"])
    perceived = analysis.perceived.set_index("specimen")["gmean"]
    for model in ("pls", "peak-law"):
        row = unseen.loc[(model, "smooth", "combined")]
        table = loso[(loso.model == model) & (loso.pad == "smooth") & (loso.condition == "combined")]
        assert row["rmse"] == pytest.approx(table["rmse"].mean(), rel=1e-12)
        rated = table[table.specimen != "R3"]
        rho, p = stats.spearmanr(rated["pred_mean"], perceived.reindex(rated["specimen"]))
        assert (row["spearman_rho"], row["spearman_p"], row["n_rated"]) == (pytest.approx(rho), pytest.approx(p), 13)
        control = controls.loc[(model, "smooth", "combined")]
        assert row["permutation_p"] == control["permutation_p"] and row["passes"] == control["passes"]
        # The training mean, per specimen: the mean target of the other specimens' trials.
        trials = analysis.condition_fit("smooth", "combined", "loso", model).predictions
        target = trials["specimen"].map(perceived)
        null = [abs(target[trials.specimen != s].mean() - perceived[s]) for s in pd.unique(trials.specimen)]
        assert row["null_rmse"] == pytest.approx(np.mean(null), rel=1e-12)
        # Pooled over trials it is the controls' null (PLS's 0-component CV RMSE), the same folds.
        pooled = np.sqrt(np.mean([(target[trials.specimen != s].mean() - t) ** 2
                                  for s, t in zip(trials.specimen, target)]))
        assert control["null_rmse"] == pytest.approx(pooled, rel=1e-12) == row["null_cv_rmse"]


def test_models_are_checked_by_name():
    from roughsense.errors import ConfigError

    study, features = synthetic_study(repetitions=2, pads=("smooth",))
    with pytest.raises(ConfigError, match="models must be one of pls, peak-law"):
        analyse_study(study, features=features, max_components=1, conditions=("1N",), models=("ridge",))
    only = analyse_study(study, features=features, max_components=1, conditions=("1N",), n_permutations=0,
                         models=("Peak-Law",))
    assert only.models == ("peak-law",) and {f.model for f in only.fits} == {"peak-law"}
    assert only.claims["cv"].eq("none").all()  # no PLS: no claim about the paper's model is judged
