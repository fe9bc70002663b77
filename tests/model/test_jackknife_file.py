"""The jackknife+ a model file carries (model/jackknife_file.py): equal to refitting every fold and applying
model/jackknife_plus.py, to MAPIE's jackknife+ where the two coincide (one press per specimen), the same after a
model-file round trip, refused in one line when edited, and wider for a surface read from fewer presses."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import roughsense as rs
from roughsense.errors import ModelFileError
from roughsense.model.jackknife_file import KEY, deployed_jackknife, press_counts
from roughsense.model.jackknife_plus import jackknife_plus
from roughsense.model.modelfile import _digest, load_model, save_model
from roughsense.model.peak_law.jackknife import law_jackknife
from roughsense.model.pls.jackknife import pls_jackknife


def gratings(n_specimens: int = 11, presses: int = 4, seed: int = 2):
    """Spectra peaking at 1/period with press-to-press noise, and a power law of the period with specimen noise."""
    rng = np.random.default_rng(seed)
    f = rs.frequency_grid()
    periods = np.repeat(np.linspace(1.6, 5.5, n_specimens), presses)
    specimens = np.repeat([f"S{i}" for i in range(n_specimens)], presses)
    widths = 0.035 + 0.02 * rng.random((periods.size, 1))
    X = np.exp(-((f - 1 / periods[:, None]) / widths) ** 2) + 0.02 + 0.05 * rng.random((periods.size, f.size))
    y = np.repeat((np.linspace(1.6, 5.5, n_specimens) / 3) ** 0.9 * rng.lognormal(0, 0.15, n_specimens), presses)
    return f, X, y, specimens


def new_surface(f, period_mm: float, presses: int, seed: int = 9):
    rng = np.random.default_rng(seed)
    return np.exp(-((f - 1 / period_mm) / 0.045) ** 2) + 0.02 + 0.05 * rng.random((presses, f.size))


def test_press_counts_keep_the_studys_counts_below_the_fewest_presses_and_that_number():
    assert press_counts([10, 10, 12]) == (1, 3, 5, 10)
    assert press_counts([4, 6]) == (1, 3, 4)
    assert press_counts([1, 5]) == (1,)


def test_the_deployed_law_interval_equals_refitting_every_fold_and_the_jackknife_plus():
    """Every fold refitted by PeakPowerLaw without its specimen: residuals of each specimen's presses read together,
    centres the new surface's mean prediction; model/jackknife_plus.py on them gives the deployed bounds."""
    f, X, y, specimens = gratings()
    jackknife = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=0)
    assert jackknife.counts == (1, 3, 4)
    surface = new_surface(f, 3.3, 4)
    low, high, method = jackknife.intervals(surface, ["new"] * 4)
    centres, residuals = [], []
    for name in dict.fromkeys(specimens):
        keep = specimens != name
        law = rs.PeakPowerLaw(freq_per_mm=f).fit(X[keep], y[keep], surfaces=specimens[keep])
        residuals.append(np.log(y[~keep][0]) - np.log(law.predict(X[~keep], surfaces=specimens[~keep]).mean()))
        centres.append(np.log(law.predict(surface, surfaces=["new"] * 4).mean()))
    # the batched IRLS and a refit both stop at a 1e-8 relative change: they agree to ~1e-6 in logs
    np.testing.assert_allclose(jackknife.log_residuals[-1], residuals, atol=1e-5)
    expected_low, expected_high = jackknife_plus(np.array(centres)[None], np.array(residuals))
    np.testing.assert_allclose(np.log(low), expected_low[0], atol=1e-5)
    np.testing.assert_allclose(np.log(high), expected_high[0], atol=1e-5)
    assert set(method) == {"jackknife+ over specimens (11), residuals of 4-press surfaces"}


def test_with_one_press_per_specimen_the_deployed_interval_is_mapies_jackknife_plus():
    """One press per specimen: leave-one-group-out is leave-one-out and MAPIE's row quantiles are specimen
    quantiles, so MAPIE's CV+ (method "plus") with group folds, on log targets, is our interval exactly."""
    mapie = pytest.importorskip("mapie.regression")
    from sklearn.base import BaseEstimator, RegressorMixin
    from sklearn.model_selection import LeaveOneGroupOut

    f, X, y, specimens = gratings(n_specimens=19, presses=1, seed=5)

    class LogLaw(RegressorMixin, BaseEstimator):
        """The law on log targets; each training row its own surface (as ours, one press per specimen)."""

        def fit(self, X, log_y):
            self.law_ = rs.PeakPowerLaw(freq_per_mm=f).fit(X, np.exp(log_y), surfaces=np.arange(len(log_y)))
            return self

        def predict(self, X):
            return np.log(self.law_.predict(X))

    jackknife = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=0)
    surfaces = new_surface(f, 2.7, 5)
    low, high, _ = jackknife.intervals(surfaces)  # each press a surface of one
    reference = mapie.CrossConformalRegressor(LogLaw(), confidence_level=0.9, method="plus", cv=LeaveOneGroupOut())
    reference.fit_conformalize(X, np.log(y), groups=specimens)
    _, bounds = reference.predict_interval(surfaces)
    np.testing.assert_allclose(np.log(low), bounds[:, 0, 0], atol=1e-5)
    np.testing.assert_allclose(np.log(high), bounds[:, 1, 0], atol=1e-5)


def test_the_deployed_pls_interval_equals_refitting_every_fold_with_its_nested_count():
    f, X, y, specimens = gratings(seed=3)
    names = list(dict.fromkeys(specimens))
    counts = {name: 1 + i % 3 for i, name in enumerate(names)}
    counts[names[4]] = 0  # a fold whose nested CV chose no component: the training mean
    jackknife = pls_jackknife(X, y, specimens, counts, seed=0)
    surface = new_surface(f, 4.1, 4)  # as many presses as each specimen: every specimen's residual of all its presses
    low, high, _ = jackknife.intervals(surface, ["new"] * 4)
    centres, residuals = [], []
    for name in names:
        keep = specimens != name
        floor = 0.5 * y[keep].min()
        if counts[name]:
            model = rs.SIMPLS(n_components=counts[name]).fit(X[keep], y[keep])
            predict = model.predict
        else:
            def predict(rows, mean=y[keep].mean()):
                return np.full(len(rows), mean)
        residuals.append(np.log(y[~keep][0]) - np.log(np.maximum(predict(X[~keep]), floor).mean()))
        centres.append(np.log(np.maximum(predict(surface), floor).mean()))
    np.testing.assert_allclose(jackknife.log_residuals[-1], residuals, rtol=1e-9, atol=1e-12)
    expected_low, expected_high = jackknife_plus(np.array(centres)[None], np.array(residuals))
    np.testing.assert_allclose(np.log([low[0], high[0]]), [expected_low[0], expected_high[0]], rtol=1e-9)


def _law_file(tmp_path, seed: int = 0):
    f, X, y, specimens = gratings()
    law = rs.PeakPowerLaw(freq_per_mm=f).fit(X, y, surfaces=specimens)
    jackknife = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=seed)
    features = {"spectrum": rs.SpatialSpectrum().feature_definition(), "conditions": ["2N"]}
    path = save_model(tmp_path / "law.json", law, feature_definition=features,
                      training={"study": "gratings", KEY: jackknife.to_dict()})
    return path, jackknife, f


def test_a_model_file_round_trip_gives_the_same_intervals(tmp_path):
    path, jackknife, f = _law_file(tmp_path)
    loaded = deployed_jackknife(load_model(path))
    assert loaded.counts == jackknife.counts and loaded.specimens == jackknife.specimens
    np.testing.assert_array_equal(loaded.log_residuals, jackknife.log_residuals)
    surfaces = new_surface(f, 2.2, 6)
    labels = ["a"] * 2 + ["b"] * 4
    for before, after in zip(jackknife.intervals(surfaces, labels), loaded.intervals(surfaces, labels)):
        np.testing.assert_array_equal(before, after)
    assert path.stat().st_size < 40_000  # a few kB: the folds are 10 numbers each


@pytest.mark.parametrize(("edit", "message"), [
    (lambda entry: entry.update(level=0.8), r"training.jackknife_plus.level: expected 0.9 \(the level predict labels "
                                            r"pi90\), got 0.8"),
    (lambda entry: entry["log_residuals"][0].pop(), r"training.jackknife_plus.log_residuals has shape"),
    (lambda entry: entry["log_residuals"][1].__setitem__(0, 60.0),
     r"training.jackknife_plus.log_residuals\[1\]\[0\]: expected a number from -50 to 50, got 60"),
    (lambda entry: entry.update(presses=[3, 1, 4]), "training.jackknife_plus.presses must be increasing"),
    (lambda entry: entry["folds"].update(kind="pls1-simpls"), "folds must be an object of kind 'peak-power-law'"),
    (lambda entry: entry["folds"]["coefficients"][2].__setitem__(0, 900.0), r"fold 3 \(S2\): .*log roughness"),
    (lambda entry: entry["folds"]["feature_min"][0].__setitem__(0, 5.0), "feature_min exceeds feature_max"),
])
def test_an_edited_entry_is_refused_in_one_line_naming_the_field(tmp_path, edit, message):
    path, _, _ = _law_file(tmp_path)
    document = json.loads(path.read_text())
    edit(document["training"][KEY])
    document["sha256"] = _digest(document)  # re-signed: the field checks, not the checksum, must refuse it
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=message) as raised:  # on loading, not first when predict reads it
        load_model(path)
    assert "\n" not in str(raised.value) and str(raised.value).startswith(f"{path}: training.{KEY}")


def test_a_surface_read_from_fewer_presses_gets_the_residuals_of_that_many():
    """The width follows the presses given: the residuals of the largest kept count at most that many."""
    f, X, y, specimens = gratings(presses=6)
    jackknife = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=1)
    assert jackknife.counts == (1, 3, 5, 6)
    assert [jackknife.count_for(m) for m in (1, 2, 3, 4, 5, 6, 30)] == [1, 1, 3, 3, 5, 6, 6]
    surface = new_surface(f, 3.0, 6)
    _, _, methods = jackknife.intervals(surface[:2], ["s"] * 2)
    assert methods == ["jackknife+ over specimens (11), residuals of 1-press surfaces"] * 2
    # the same draw gives the same residuals (seeded); another seed another draw of the presses
    again = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=1)
    np.testing.assert_array_equal(again.log_residuals, jackknife.log_residuals)
    other = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=2)
    assert not np.array_equal(other.log_residuals[0], jackknife.log_residuals[0])
    np.testing.assert_array_equal(other.log_residuals[-1], jackknife.log_residuals[-1])  # all presses: no draw


@pytest.fixture(scope="module")
def fingerprint_1n(shared_build):
    """A small simulated study: the fingerprint pad at 1 N (where one press reads a surface worst), the paper's 14
    gratings, 10 presses each, its ratings (seed 11, 1920 x 170 frames)."""
    from roughsense.paper import PAPER_SPECIMENS
    from roughsense.sim.config import SimulationConfig, with_image_size
    from roughsense.sim.simulate import simulate_study

    config = SimulationConfig(pads=("fingerprint",), specimens=PAPER_SPECIMENS, forces_n=(1.0,), repetitions=10,
                              seed=11, participants=3, sessions=2)
    return shared_build("fingerprint-1n-seed11",
                        lambda folder: simulate_study(folder, with_image_size(config, 1920, 170), jobs=1))


def test_one_press_gets_a_wider_interval_than_ten_and_held_out_readings_are_covered_near_nominal(fingerprint_1n):
    """Issue 35: the interval widens when a surface is read from fewer presses, and held out (each specimen's
    interval from models that never saw it, leave-two-out) it covers about 90 % at 1 and at 10 presses."""
    from roughsense.analysis import dataset
    from roughsense.analysis.family_fits import law_settings
    from roughsense.io.study import read_study
    from roughsense.model.peak_law.folds import law_nested_press_check, law_pair_models

    study = read_study(fingerprint_1n)
    X, meta = dataset.condition_matrix(dataset.study_features(study), "fingerprint", "1N")
    y = dataset.targets(meta, dataset.perceived_roughness(study))
    specimens = meta["specimen"].astype(str).to_numpy()
    law = law_settings(X, np.asarray(dataset.spectrum_for(study).freq_per_mm_), 1.0, specimens)
    models = law_pair_models(X, y, specimens, **law)
    coverage, width = {}, {}
    for count in (1, 10):
        checks = [law_nested_press_check(X, y, specimens, count, seed, models=models, **law) for seed in range(5)]
        coverage[count] = np.mean([np.average(c["covered"], weights=c["readings"]) for c in checks])
        width[count] = np.median([c["log_halfwidth"].median() for c in checks])
    assert width[1] > width[10]
    assert 0.85 <= coverage[1] <= 0.95 and 0.85 <= coverage[10] <= 0.95
    jackknife = law_jackknife(X, y, specimens, law, seed=0)  # deployed: a trained surface read both ways
    alone, together = [], []
    for name in jackknife.specimens:
        mine = X[specimens == name]
        low, high, _ = jackknife.intervals(mine)
        alone.append(np.median(np.log(high / low)))
        low, high, _ = jackknife.intervals(mine, [name] * len(mine))
        together.append(np.log(high[0] / low[0]))
    assert np.median(alone) > np.median(together)


def test_the_nested_press_check_equals_leave_two_out_refits():
    """Issue 35 item 3: a held-out specimen's per-press interval (a press read alone, as predict gives it) is built
    from models fitted without it and each other specimen in turn; equal to refitting PeakPowerLaw on each pair."""
    from roughsense.model.peak_law.folds import law_nested_press_check, press_groups, specimen_codes

    f, X, y, specimens = gratings(n_specimens=10, presses=3, seed=4)
    check = law_nested_press_check(X, y, specimens, 1, 5, freq_per_mm=f, surfaces=specimens)
    codes, names = specimen_codes(specimens)
    rows, reading, owner = press_groups(codes, 1, 5)
    first_press = {s: rows[np.flatnonzero(owner == s)[0]] for s in range(names.size)}
    t = 6
    centres, residuals = [], []
    for s in (s for s in range(names.size) if s != t):
        keep = (codes != t) & (codes != s)
        law = rs.PeakPowerLaw(freq_per_mm=f).fit(X[keep], y[keep], surfaces=specimens[keep])
        press = first_press[s]
        residuals.append(np.log(y[press]) - np.log(law.predict(X[press:press + 1])[0]))
        centres.append(np.log(law.predict(X[codes == t])))  # each press of t read alone
    low, high = jackknife_plus(np.array(centres).T, np.array(residuals))
    target = np.log(y[codes == t][0])
    assert check.loc[t, "readings"] == 3
    assert check.loc[t, "covered"] == pytest.approx(np.mean((low <= target) & (target <= high)))
    assert check.loc[t, "log_halfwidth"] == pytest.approx(np.median(0.5 * (high - low)), abs=1e-5)


def test_fit_stores_and_predict_applies_the_jackknife_plus_end_to_end(run_cli, fingerprint_1n, tmp_path):
    """roughsense fit on 14 specimens keeps the fold models; predict's surface interval (10 presses) and a press read
    alone (1 press) are the stored jackknife+ applied to the spectra, and the CSV names which presses' residuals."""
    import pandas as pd

    from roughsense.analysis import dataset
    from roughsense.io.study import read_study

    model = tmp_path / "law.json"
    code, stdout, err = run_cli("fit", "--study", fingerprint_1n, "--pad", "fingerprint", "--condition", "1N",
                                "--out", model)
    assert code == 0, err
    assert "per surface and per press read alone the jackknife+ over specimens (14), from surfaces read from 1, 3, " \
           "5, 10 presses" in " ".join(stdout.split())
    jackknife = deployed_jackknife(load_model(model))
    assert jackknife.counts == (1, 3, 5, 10) and len(jackknife.specimens) == 14
    code, _, err = run_cli("predict", model, "--study", fingerprint_1n, "--specimen", "R3", "--specimen", "C4",
                           "--out", tmp_path / "surfaces.csv")
    assert code == 0, err
    table = pd.read_csv(tmp_path / "surfaces.csv")
    study = read_study(fingerprint_1n)
    X, meta = dataset.condition_matrix(dataset.study_features(study), "fingerprint", "1N")
    for name in ("R3", "C4"):
        rows = table[table["specimen"] == name]
        mine = X[(meta["specimen"] == name).to_numpy()]
        low, high, method = jackknife.intervals(mine, [name] * len(mine))
        np.testing.assert_allclose(rows["surface_pi90_low"], low, rtol=5e-3)  # 3 significant digits
        np.testing.assert_allclose(rows["surface_pi90_high"], high, rtol=5e-3)
        assert set(rows["surface_pi90_method"]) == {"jackknife+ over specimens (14), residuals of 10-press surfaces"}
        # a press read with its surface's others: the plain jackknife, named so, never pi90 beside the jackknife+
    assert "pi90_low" not in table and "pi90_method" not in table and (table["jackknife90_low"] > 0).all()
    image = fingerprint_1n / meta["image"].iloc[0]
    code, _, err = run_cli("predict", model, image, "--out", tmp_path / "alone.csv")
    assert code == 0, err
    alone = pd.read_csv(tmp_path / "alone.csv")
    low, high, _ = jackknife.intervals(X[:1])
    np.testing.assert_allclose([alone["pi90_low"][0], alone["pi90_high"][0]], [low[0], high[0]], rtol=5e-3)
    assert alone["pi90_method"][0] == "jackknife+ over specimens (14), residuals of 1-press surfaces"
    assert "keeps no leave-one-specimen-out" not in err


def test_a_pls_model_file_round_trip_gives_the_same_intervals(tmp_path):
    f, X, y, specimens = gratings(seed=6)
    pls = rs.SIMPLS(n_components=2).fit(X, y)
    jackknife = pls_jackknife(X, y, specimens, dict.fromkeys(specimens, 2), seed=0)
    features = {"spectrum": rs.SpatialSpectrum().feature_definition(), "conditions": ["2N"]}
    path = save_model(tmp_path / "pls.json", pls, feature_definition=features,
                      training={"study": "gratings", "target_range": [float(y.min()), float(y.max())],
                                KEY: jackknife.to_dict()})
    loaded = deployed_jackknife(load_model(path))
    surfaces = new_surface(f, 3.7, 5)
    for before, after in zip(jackknife.intervals(surfaces, ["a"] * 5), loaded.intervals(surfaces, ["a"] * 5)):
        np.testing.assert_array_equal(before, after)
    document = json.loads(path.read_text())
    document["training"][KEY]["folds"]["floors"][3] = 0.0  # a floor of 0 would let a fold predict log(0)
    document["sha256"] = _digest(document)
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=r"training.jackknife_plus.folds.floors must be positive"):
        deployed_jackknife(load_model(path))


@settings(max_examples=8, deadline=None)
@given(factor=st.floats(0.2, 5.0), order_seed=st.integers(0, 2**16))
def test_the_interval_scales_with_the_ratings_and_ignores_the_row_order(factor, order_seed):
    """Ratings are ratios to a reference: rescaling every rating rescales the law's predictions and the interval by
    the same factor (the law is fitted in logs, its residuals unchanged); the order of the training presses (and so
    the order of first appearance of the specimens) changes nothing (all presses read together: no draw)."""
    f, X, y, specimens = gratings(n_specimens=10, presses=3, seed=8)
    surface = new_surface(f, 3.4, 3)
    base = law_jackknife(X, y, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=0)
    low, high, _ = base.intervals(surface, ["s"] * 3)
    scaled = law_jackknife(X, y * factor, specimens, {"freq_per_mm": f, "surfaces": specimens}, seed=0)
    low_scaled, high_scaled, _ = scaled.intervals(surface, ["s"] * 3)
    np.testing.assert_allclose([low_scaled[0], high_scaled[0]], [factor * low[0], factor * high[0]], rtol=1e-5)
    order = np.random.default_rng(order_seed).permutation(len(y))
    shuffled = law_jackknife(X[order], y[order], specimens[order],
                             {"freq_per_mm": f, "surfaces": specimens[order]}, seed=0)
    low_shuffled, high_shuffled, _ = shuffled.intervals(surface, ["s"] * 3)
    np.testing.assert_allclose([low_shuffled[0], high_shuffled[0]], [low[0], high[0]], rtol=1e-5)
