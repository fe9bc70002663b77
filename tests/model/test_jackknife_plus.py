"""The jackknife+ over specimens (model/jackknife_plus.py) against MAPIE's jackknife+ on one row per specimen, its
ranks against Barber et al.'s definition, and the nested check against a direct leave-two-out refit."""
from __future__ import annotations

import numpy as np
import pytest
from sklearn.linear_model import LinearRegression
from sklearn.model_selection import LeaveOneOut

from roughsense.model.jackknife_plus import jackknife_plus, nested_check, ranks


def test_ranks_follow_the_definition():
    # floor(alpha (n + 1)) and ceil((1 - alpha)(n + 1)) at alpha = 0.1.
    assert ranks(14) == (1, 14)
    assert ranks(29) == (3, 27)
    assert ranks(8) == (0, 9)  # too few specimens: unbounded on both sides


@pytest.mark.parametrize("n", [14, 29])
def test_equals_mapie_jackknife_plus_on_one_row_per_specimen(n):
    mapie = pytest.importorskip("mapie.regression")
    rng = np.random.default_rng(n)
    X = rng.normal(size=(n, 2))
    y = X @ [0.7, -0.3] + 0.3 * rng.standard_t(3, size=n)
    X_new = rng.normal(size=(5, 2))
    fold_predictions, residuals = np.empty((5, n)), np.empty(n)
    for i in range(n):
        keep = np.arange(n) != i
        model = LinearRegression().fit(X[keep], y[keep])
        residuals[i] = abs(y[i] - model.predict(X[i:i + 1])[0])
        fold_predictions[:, i] = model.predict(X_new)
    low, high = jackknife_plus(fold_predictions, residuals, level=0.9)
    reference = mapie.CrossConformalRegressor(LinearRegression(), confidence_level=0.9, method="plus",
                                              cv=LeaveOneOut()).fit_conformalize(X, y)
    _, bounds = reference.predict_interval(X_new, allow_infinite_bounds=True)
    np.testing.assert_allclose(low, bounds[:, 0, 0], rtol=1e-10)
    np.testing.assert_allclose(high, bounds[:, 1, 0], rtol=1e-10)


def test_the_nested_check_uses_only_models_that_never_saw_the_specimen():
    """Specimen t's interval: centres from models without t and s, residuals of s from the same models, so changing
    any model that saw t changes nothing about t's interval."""
    rng = np.random.default_rng(1)
    n = 12
    log_targets = rng.normal(size=n)
    pairs = rng.normal(size=(n, n, n))
    pairs = (pairs + pairs.transpose(1, 0, 2)) / 2  # a model without {t, s} is the model without {s, t}
    table = nested_check(pairs, log_targets, [f"S{i}" for i in range(n)])
    t = 3
    others = [s for s in range(n) if s != t]
    residuals = np.abs(log_targets[others] - pairs[t, others, others])
    low, high = jackknife_plus(pairs[t, others, t][None], residuals)
    assert table.loc[t, "pi90_low"] == pytest.approx(np.exp(low[0]))
    assert table.loc[t, "pi90_high"] == pytest.approx(np.exp(high[0]))
    assert table.loc[t, "covered"] == bool(low[0] <= log_targets[t] <= high[0])
    changed = pairs.copy()
    changed[5, 5, :] += 10.0  # the model without specimen 5 alone saw specimen 3
    assert nested_check(changed, log_targets, [f"S{i}" for i in range(n)]).loc[t].equals(table.loc[t])


def test_leave_two_out_fits_equal_refits_of_the_law():
    """Every pair's batched fit predicts as PeakPowerLaw refitted without both specimens (its clipping included)."""
    import roughsense as rs
    from roughsense.model.peak_law.folds import law_pair_log_predictions

    rng = np.random.default_rng(2)
    f = rs.frequency_grid()
    periods = np.repeat([2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0], 3)
    specimens = np.repeat([f"S{i}" for i in range(7)], 3)
    X = np.exp(-((f - 1 / periods[:, None]) / (0.04 + 0.01 * rng.random((21, 1)))) ** 2) + 0.01
    y = np.repeat((np.arange(7) / 3.0 + 0.5) ** 0.9 * rng.lognormal(0, 0.1, 7), 3)
    pairs = law_pair_log_predictions(X, y, specimens, freq_per_mm=f, surfaces=specimens)
    for t, s in ((0, 3), (2, 6), (4, 4)):
        keep = (specimens != f"S{t}") & (specimens != f"S{s}")
        law = rs.PeakPowerLaw(freq_per_mm=f).fit(X[keep], y[keep], surfaces=specimens[keep])
        for u in (t, s, 1):
            mine = specimens == f"S{u}"
            expected = law.predict(X[mine], surfaces=specimens[mine]).mean()
            # both stop the IRLS at a 1e-8 relative change of the coefficients: they agree to ~1e-6 in logs
            assert pairs[t, s, u] == pytest.approx(np.log(expected), abs=1e-5), (t, s, u)
