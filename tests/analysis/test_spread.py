"""SpreadModel and the predictive OVL, against hand computation, a direct mixture and numerical integration."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, stats
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from roughsense import SpreadModel, paper
from roughsense.analysis.spread import paper_predictive, predictive_ovl
from roughsense.errors import ConfigError, InputError


def test_weber_fit_is_the_pooled_coefficient_of_variation():
    model = SpreadModel().fit([1.0, 2.0, 4.0, 1.0], [0.2, 0.5, 0.8, np.nan])  # the NaN (a reference) is ignored
    # By hand: (0.2/1)^2 = 0.04, (0.5/2)^2 = 0.0625, (0.8/4)^2 = 0.04; mean 0.0475; k = sqrt(0.0475).
    assert model.slope_ == pytest.approx(0.2179449471770337, rel=1e-12)
    assert model.intercept_ == 0.0 and model.n_specimens_ == 3
    assert model.predict_sd(3.0) == pytest.approx(3 * 0.2179449471770337)
    np.testing.assert_allclose(model.predict_sd([0.0, -1.0, 2.0]), [0.0, 0.0, 2 * 0.2179449471770337])


def test_constant_fit_is_the_pooled_sd():
    model = SpreadModel(kind="constant").fit([1.0, 2.0], [0.3, 0.4])
    assert model.predict_sd(5.0) == pytest.approx(np.sqrt((0.09 + 0.16) / 2))


def test_predictive_sd_is_the_sd_of_the_mixture_over_repetitions():
    """var = mean of s(x_i)^2 + population variance of the x_i, computed directly from the repetitions."""
    model = SpreadModel().fit([1.0, 2.0], [0.25, 0.5])
    x = np.array([0.8, 1.1, 1.3, 0.9, 1.4])
    direct = np.sqrt(np.mean(model.predict_sd(x) ** 2) + x.var())
    assert model.predictive_sd(x.mean(), x.std()) == pytest.approx(direct, rel=1e-12)
    # And by sampling the mixture itself.
    rng = np.random.default_rng(0)
    draws = rng.normal(np.repeat(x, 40_000), np.repeat(model.predict_sd(x), 40_000))
    assert draws.std() == pytest.approx(direct, rel=5e-3)


def test_scikit_learn_conventions():
    model = SpreadModel(kind="constant")
    assert clone(model).get_params() == {"kind": "constant"}
    with pytest.raises(NotFittedError):
        SpreadModel().predict_sd(1.0)
    with pytest.raises(ConfigError):
        SpreadModel(kind="quadratic").fit([1.0], [0.1])
    with pytest.raises(InputError):
        SpreadModel().fit([1.0, 2.0], [0.1])


def test_predictive_ovl_is_leave_one_specimen_out_and_integrates_correctly():
    perceived = pd.DataFrame({"specimen": ["a", "b", "c", "d"], "gmean": [0.5, 1.0, 1.5, 2.0],
                              "sd": [0.2, 0.25, 0.4, 0.5]})
    table = perceived.assign(pred_mean=[0.6, 1.1, 1.4, 1.8], pred_sd=[0.1, 0.05, 0.2, 0.15])
    out = predictive_ovl(table, perceived)
    # Specimen c: k from a, b, d only.
    k = np.sqrt(np.mean([(0.2 / 0.5) ** 2, (0.25 / 1.0) ** 2, (0.5 / 2.0) ** 2]))
    width = np.sqrt((k * 1.4) ** 2 + (k * k + 1) * 0.2**2)
    assert out.loc[2, "predictive_sd"] == pytest.approx(width, rel=1e-12)
    numeric, _ = integrate.quad(lambda v: min(stats.norm.pdf(v, 1.5, 0.4), stats.norm.pdf(v, 1.4, width)),
                                -5, 8, points=[1.4, 1.5], limit=200)
    assert out.loc[2, "ovl_predictive"] == pytest.approx(numeric, abs=1e-7)
    # Its own ratings never enter: changing c's SD changes nothing about c's predictive SD.
    changed = perceived.copy()
    changed.loc[2, "sd"] = 5.0
    assert predictive_ovl(table, changed).loc[2, "predictive_sd"] == pytest.approx(width, rel=1e-12)


def test_a_precise_sensor_scores_near_zero_on_the_papers_ovl_but_not_on_the_predictive_one():
    perceived = paper.perceived_roughness().rename(columns={"perceived_gmean": "gmean", "perceived_sd": "sd"})
    perfect = perceived.assign(pred_mean=perceived["gmean"], pred_sd=1e-6).dropna(subset=["sd"])
    from roughsense.analysis.metrics import overlap

    assert np.nanmax(overlap(perfect["gmean"], perfect["sd"], perfect["pred_mean"], perfect["pred_sd"])) < 0.01
    assert predictive_ovl(perfect, perceived)["ovl_predictive"].mean() > 0.85


def test_paper_predictions_reach_the_goal_with_a_weber_spread():
    table = paper_predictive()
    published = paper.paper_results()
    assert len(table) == len(published)
    means = table.groupby(["pad", "condition"])[["ovl", "ovl_predictive"]].mean()
    for pad in ("fingerprint", "smooth"):
        paper_ovl = published[(published.pad == pad) & (published.condition == "combined")]["ovl"].mean()
        assert means.loc[(pad, "combined"), "ovl"] == pytest.approx(paper_ovl)
        assert means.loc[(pad, "combined"), "ovl_predictive"] >= 0.75  # issue 11's goal (the paper's: 0.56)
    assert table.loc[table.specimen == "R3", "ovl_predictive"].isna().all()
