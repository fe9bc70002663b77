"""The paper's claims: statistics recomputed with scipy from the per-specimen results, verdicts by their rules."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from roughsense.analysis.claims import CLAIM_COLUMNS, VERDICTS
from roughsense.analysis.study_analysis import analyse_study

from .test_study_analysis import synthetic_study


@pytest.fixture(scope="module")
def analysis():
    study, features = synthetic_study(repetitions=3, seed=1)
    return analyse_study(study, features=features, max_components=4, n_permutations=3)


def _claim(analysis, key, pad, cv):
    rows = analysis.claims[(analysis.claims.key == key) & (analysis.claims.pad == pad) & (analysis.claims.cv == cv)]
    assert len(rows) == 1, (key, pad, cv)
    return rows.iloc[0]


def _pls(frame):
    """The paper's model's rows: the claims are about it alone."""
    return frame[frame["model"] == "pls"]


def _rmse(analysis, cv, pad, condition, column="rmse"):
    r = _pls(analysis.results(cv))
    return r[(r.pad == pad) & (r.condition == condition)].set_index("specimen")[column]


def test_claims_are_the_papers_pls_alone(analysis):
    """Fitting a second family beside PLS changes no claim: the same table as a PLS-only run."""
    study, features = synthetic_study(repetitions=3, seed=1)
    alone = analyse_study(study, features=features, max_components=4, n_permutations=3, models=("pls",))
    assert analysis.models == ("pls", "peak-law") and alone.models == ("pls",)
    pd.testing.assert_frame_equal(analysis.claims, alone.claims, check_exact=True)
    pd.testing.assert_frame_equal(analysis.tests, alone.tests, check_exact=True)


def test_every_claim_has_a_verdict_under_loo_and_loso(analysis):
    claims = analysis.claims
    assert list(claims.columns) == CLAIM_COLUMNS
    assert set(claims["verdict"]) <= set(VERDICTS)
    per_scheme = claims[claims.cv != "none"].groupby("cv")["key"].apply(set)
    assert per_scheme["loo"] == per_scheme["loso"] and len(per_scheme["loo"]) >= 10
    assert set(claims.loc[claims.cv == "none", "key"]) == {"ratings_rise", "circular_rougher", "human_sd_grows"}
    assert (claims["basis"] == "finding").all()  # the synthetic study has no [simulation] table


@pytest.mark.parametrize("cv", ["loo", "loso"])
def test_combined_beats_singles_uses_scipy_wilcoxon_with_bonferroni(analysis, cv):
    row = _claim(analysis, "combined_beats_singles", "fingerprint", cv)
    combined = _rmse(analysis, cv, "fingerprint", "combined")
    adjusted = []
    for single in ("1N", "2N", "3N"):
        diff = combined.to_numpy() - _rmse(analysis, cv, "fingerprint", single).reindex(combined.index).to_numpy()
        adjusted.append(min(1.0, 3 * stats.wilcoxon(diff, method="exact").pvalue))
    assert row["p"] == pytest.approx(max(adjusted), rel=1e-9)
    lower = all(combined.mean() < _rmse(analysis, cv, "fingerprint", s).mean() for s in ("1N", "2N", "3N"))
    expected = "reproduced" if lower and max(adjusted) < 0.05 else "not reproduced"
    assert row["verdict"] == expected


def test_smooth_vs_fingerprint_and_rmse_below_sd_match_scipy(analysis):
    row = _claim(analysis, "smooth_beats_fingerprint", "both", "loo")
    a, b = _rmse(analysis, "loo", "smooth", "combined"), _rmse(analysis, "loo", "fingerprint", "combined")
    diff = a.to_numpy() - b.reindex(a.index).to_numpy()
    assert row["p"] == pytest.approx(stats.wilcoxon(diff, method="exact").pvalue, rel=1e-9)
    ranks = stats.rankdata(np.abs(diff))
    assert row["statistic"] == pytest.approx(ranks[diff > 0].sum())
    below = _claim(analysis, "rmse_below_sd", "smooth", "loso")
    people = analysis.perceived.set_index("specimen")["sd"].dropna()
    rmse = _rmse(analysis, "loso", "smooth", "combined").reindex(people.index)
    k = int((rmse < people).sum())
    assert below["statistic"] == pytest.approx(k / len(people))
    assert below["p"] == pytest.approx(stats.binomtest(k, len(people), 0.5, alternative="greater").pvalue)
    assert below["verdict"] == ("reproduced" if k > len(people) / 2 else "not reproduced")


def test_ovl_and_alignment_claims_match_scipy(analysis):
    row = _claim(analysis, "ovl_same_across_forces", "smooth", "loo")
    ovl = [_rmse(analysis, "loo", "smooth", c, "ovl").dropna() for c in ("1N", "2N", "3N", "combined")]
    expected = stats.friedmanchisquare(*[o.reindex(ovl[0].index).to_numpy() for o in ovl])
    assert row["statistic"] == pytest.approx(expected.statistic) and row["p"] == pytest.approx(expected.pvalue)
    aligns = _claim(analysis, "aligns", "fingerprint", "loso")
    r = _pls(analysis.results("loso"))
    r = r[(r.pad == "fingerprint") & (r.condition == "combined")]
    truth = analysis.perceived.set_index("specimen")["gmean"].reindex(r["specimen"])
    rho, p = stats.spearmanr(truth.to_numpy(), r["pred_mean"].to_numpy())
    assert aligns["statistic"] == pytest.approx(rho) and aligns["p"] == pytest.approx(p)
    control = _pls(analysis.controls).set_index(["pad", "condition", "cv"]).loc[("fingerprint", "combined", "loso")]
    beats = _claim(analysis, "beats_controls", "fingerprint", "loso")
    assert beats["p"] == control["permutation_p"]
    assert beats["verdict"] == ("reproduced" if control["passes"] else "not reproduced")


def test_rating_claims_match_scipy(analysis):
    people = analysis.perceived.set_index("specimen")
    circular = [f"C{w:g}" for w in (2, 2.5, 3, 3.5, 4, 4.5, 5)]
    rectangular = [f"R{w:g}" for w in (2, 2.5, 3, 3.5, 4, 4.5, 5)]
    row = _claim(analysis, "circular_rougher", "", "none")
    diff = people.loc[circular, "gmean"].to_numpy() - people.loc[rectangular, "gmean"].to_numpy()
    assert row["p"] == pytest.approx(stats.wilcoxon(diff, method="exact").pvalue)
    rise = _claim(analysis, "ratings_rise", "", "none")
    ps = [stats.spearmanr([2, 2.5, 3, 3.5, 4, 4.5, 5], people.loc[names, "gmean"]).pvalue
          for names in (circular, rectangular)]
    assert rise["p"] == pytest.approx(max(ps))


def test_a_single_pad_study_cannot_test_the_pad_comparisons():
    study, features = synthetic_study(repetitions=2, seed=2, pads=("smooth",))
    single = analyse_study(study, features=features, max_components=2, n_permutations=0, cv_schemes=("loo",))
    rows = single.claims[single.claims.key.isin(["smooth_beats_fingerprint", "ovl_pads_comparable"])]
    assert len(rows) == 2 and (rows["verdict"] == "not testable").all()
    assert (single.claims.loc[single.claims.key == "beats_controls", "verdict"] == "not testable").all()


def test_on_a_simulated_study_rating_claims_are_labelled_properties_of_the_simulator():
    study, features = synthetic_study(repetitions=2, seed=2, pads=("smooth",))
    study.extra = {"simulation": {"seed": 4, "simulator": "roughsense.sim"}}
    simulated = analyse_study(study, features=features, max_components=2, n_permutations=0, cv_schemes=("loo",))
    assert simulated.simulated and simulated.simulation["seed"] == 4
    basis = simulated.claims.set_index(["key", "cv"])["basis"]
    assert basis[("ratings_rise", "none")].startswith("property of the simulator")
    assert "tuned" in basis[("rmse_below_sd", "loo")]
    assert basis[("aligns", "loo")] == "finding on simulated data"


def test_a_tiny_study_still_gets_a_verdict_for_every_claim():
    """Three specimens, one pad, LOO only: most claims cannot be tested, and the analysis says so instead of failing."""
    study, features = synthetic_study(repetitions=2, seed=3, pads=("smooth",))
    keep = ["R2", "R3", "C5"]
    study.specimens = study.specimens[study.specimens.specimen.isin(keep)].reset_index(drop=True)
    study.ratings = study.ratings[study.ratings.specimen.isin(keep)]
    tiny = analyse_study(study, features=features[features.specimen.isin(keep)], max_components=1,
                         cv_schemes=("loo",), n_permutations=5)
    assert set(tiny.claims["verdict"]) <= {"reproduced", "not reproduced", "not testable"}
    verdicts = tiny.claims.set_index("key")["verdict"]
    for key in ("smooth_beats_fingerprint", "low_ovl_specimens", "circular_rougher", "aligns", "human_sd_grows"):
        assert verdicts[key] == "not testable", key
    # R2 and C5 are rated: each learns its spread from the other one alone.
    assert tiny.results("loo").query("specimen != 'R3'")["ovl_predictive"].notna().all()


def test_the_descriptive_and_remaining_claims_follow_their_definitions(analysis):
    cv = "loso"
    means = {c: _rmse(analysis, cv, "smooth", c).mean() for c in ("1N", "2N", "3N", "combined")}
    lowest = _claim(analysis, "combined_lowest_mean", "smooth", cv)
    margin = means["combined"] - min(means["1N"], means["2N"], means["3N"])
    assert lowest["statistic"] == pytest.approx(margin) and np.isnan(lowest["p"])
    assert lowest["verdict"] == ("reproduced" if margin < 0 else "not reproduced")

    comparable = _claim(analysis, "ovl_pads_comparable", "both", cv)
    diffs, ps = [], []
    for c in ("1N", "2N", "3N", "combined"):
        a = _rmse(analysis, cv, "smooth", c, "ovl").dropna()
        b = _rmse(analysis, cv, "fingerprint", c, "ovl").reindex(a.index)
        diffs.append(abs(a.mean() - b.mean()))
        ps.append(min(1.0, 4 * stats.wilcoxon(a.to_numpy() - b.to_numpy(), method="exact").pvalue))
    assert comparable["statistic"] == pytest.approx(max(diffs)) and comparable["p"] == pytest.approx(min(ps))

    low = _claim(analysis, "low_ovl_specimens", "fingerprint", cv)
    r = _pls(analysis.results(cv))
    cells = r[(r.pad == "fingerprint") & r.specimen.isin(["R2", "R2.5", "C5"])]["ovl"]
    assert len(cells) == 12 and low["statistic"] == pytest.approx((cells < 0.5).mean())

    flat = _claim(analysis, "sd_flat", "smooth", cv)
    rows = r[(r.pad == "smooth") & (r.condition == "combined") & (r.specimen != "R3")]
    gmean = analysis.perceived.set_index("specimen")["gmean"].reindex(rows["specimen"]).to_numpy()
    rho, p = stats.spearmanr(gmean, rows["pred_sd"].to_numpy())
    assert flat["statistic"] == pytest.approx(rho) and flat["p"] == pytest.approx(p)
    assert flat["verdict"] == ("not reproduced" if rho > 0 and p < 0.05 else "reproduced")

    grows = _claim(analysis, "human_sd_grows", "", "none")
    rated = analysis.perceived.dropna(subset=["sd"])
    rho, p = stats.spearmanr(rated["gmean"], rated["sd"])
    assert grows["statistic"] == pytest.approx(rho) and grows["p"] == pytest.approx(p)


def test_ratings_from_the_simulated_finger_are_labelled_as_the_finger_model():
    study, features = synthetic_study(repetitions=2, seed=2, pads=("smooth",))
    study.extra = {"simulation": {"seed": 4, "ratings_from": "physics"}}
    simulated = analyse_study(study, features=features, max_components=2, n_permutations=0, cv_schemes=("loo",))
    basis = simulated.claims.set_index(["key", "cv"])["basis"]
    assert "simulated finger" in basis[("human_sd_grows", "none")] and "Table 1" not in basis[("human_sd_grows", "none")]
