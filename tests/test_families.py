"""Families as objects: the registry and its engines agree, and a third family is one module and one registry line.

The third family here is the null model itself (each held-out trial predicted by its training fold's mean), written
from scratch in this file and registered by monkeypatching the registry. Run through the whole study analysis beside
PLS and the peak law, its cross-validated RMSE must equal PLS's 0-component CV RMSE under the same folds (an
independent computation of the same model), it must never beat the null model, and in a balanced design no
shuffling of the specimens' targets changes its RMSE, so its permutation p is exactly 1.
"""
from __future__ import annotations

import subprocess
import sys
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

from roughsense.analysis.study_analysis import analyse_study
from roughsense.errors import ConfigError
from roughsense.model import engines as model_engines
from roughsense.model import families
from roughsense.model.family import FamilyEngine, FoldResult

from .test_study_analysis import synthetic_study

TOY = "training-mean"


def _fold_means(y: np.ndarray, folds: np.ndarray) -> np.ndarray:
    """Each row's prediction: the mean of y over every row of another fold (a plain loop, no shared code)."""
    out = np.empty(len(y))
    for label in np.unique(folds):
        held = folds == label
        out[held] = y[~held].mean()
    return out


def _folds(y, specimens, cv: str) -> np.ndarray:
    return np.arange(len(y)) if cv == "loo" else np.asarray(specimens)


class TrainingMeanFamily(FamilyEngine):
    """The toy third family: it reads no spectrum and predicts the training fold's mean."""

    name: ClassVar[str] = TOY

    def cross_validate(self, X, y, specimens, cv, settings, max_components) -> FoldResult:
        out_of_fold = _fold_means(np.asarray(y, float), _folds(y, specimens, cv))
        rmse = float(np.sqrt(np.mean((out_of_fold - y) ** 2)))
        return FoldResult(out_of_fold, np.array([rmse, rmse]))

    def permuted_rmse(self, X, Y, specimens, cv, settings, max_components) -> np.ndarray:
        folds = _folds(Y[:, 0], specimens, cv)
        return np.array([np.sqrt(np.mean((_fold_means(column, folds) - column) ** 2)) for column in Y.T])

    def held_out_flags(self, X, y, specimens, settings, fold) -> np.ndarray:
        return np.zeros(len(y), dtype=bool)  # no domain: it never claims to read a spectrum


def _add_third_family(monkeypatch) -> families.Family:
    """The registry and its engines with the toy family appended (one Family line, one engine)."""
    toy = families.Family(TOY, "training mean", "^", "#777777", paper=False, chooses_components=False, kind=TOY)
    engines = model_engines.engines
    monkeypatch.setattr(families, "_FAMILIES", (*families.registry(), toy))
    monkeypatch.setattr(model_engines, "engines", lambda: (*engines(), TrainingMeanFamily()))
    return toy


@pytest.fixture
def third_family(monkeypatch):
    """The toy family beside the others for one test."""
    return _add_third_family(monkeypatch)


def test_the_registry_and_its_engines_list_the_same_families_in_the_same_order():
    assert tuple(f.name for f in families.registry()) == tuple(e.name for e in model_engines.engines())
    assert families.MODEL_FAMILIES == families.names() == ("pls", "peak-law")
    assert [f.name for f in families.registry() if f.paper] == [families.paper_family().name] == ["pls"]
    assert families.default_family().name == families.DEFAULT_MODEL
    assert all(model_engines.engine(name).name == name for name in families.names())
    assert families.check_model_name(" Peak-Law ") == "peak-law"
    with pytest.raises(ConfigError, match="--model must be one of pls, peak-law, got 'ridge'"):
        families.check_model_name("ridge")


def test_check_model_name_follows_the_registry(third_family):
    assert families.names() == ("pls", "peak-law", TOY)
    assert families.check_model_name("Training-Mean") == TOY and families.family(TOY) is third_family
    assert isinstance(model_engines.engine(TOY), TrainingMeanFamily)
    with pytest.raises(ConfigError, match=f"one of pls, peak-law, {TOY}"):
        families.check_model_name("ridge")


def test_the_registry_is_light_and_the_fingerprint_follows_the_engines():
    """The names load no NumPy (``--help`` reads them); the engines sit above them, so no import runs in a loop."""
    code = "import sys, roughsense.model.families; print('numpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split() == [
        "False"]
    from roughsense._util.fingerprint import module_closure

    closure = set(module_closure("roughsense.analysis.family_fits"))
    assert {"roughsense.model.engines", "roughsense.model.pls.family", "roughsense.model.peak_law.family"} <= closure
    assert "roughsense.model.engines" not in set(module_closure("roughsense.model.families"))


@pytest.fixture(scope="module")
def toy_analysis():
    """The study analysed with the toy family beside the others, once for the module (frozen: tests only read it);
    the registry is patched while it is analysed, and again in each test that reads it (``with_toy``)."""
    with pytest.MonkeyPatch.context() as monkeypatch:
        _add_third_family(monkeypatch)
        study, features = synthetic_study(repetitions=2, pads=("smooth",))
        return analyse_study(study, features=features, max_components=2, conditions=("1N", "combined"),
                             n_permutations=9, models=("pls", "peak-law", TOY))


@pytest.fixture
def with_toy(third_family, toy_analysis):
    return toy_analysis


def test_a_third_family_runs_through_the_study_beside_the_others(with_toy):
    analysis = with_toy
    assert analysis.models == ("pls", "peak-law", TOY)
    for table in (analysis.results("loo"), analysis.results("loso"), analysis.predictions(), analysis.cv_table(),
                  analysis.controls):
        assert list(dict.fromkeys(table["model"])) == ["pls", "peak-law", TOY]  # the registry's order
    pls_null = analysis.cv_table().query("model == 'pls' and n_components == 0").set_index(["condition", "cv"])
    controls = analysis.controls.set_index(["condition", "cv", "model"])
    for condition in ("1N", "combined"):
        for cv in ("loo", "loso"):
            toy = controls.loc[(condition, cv, TOY)]
            # The toy's pooled CV RMSE is the null model's, computed by PLS's CV engine at 0 components.
            assert toy["rmse"] == pytest.approx(pls_null.loc[(condition, cv), "rmse"], rel=1e-12)
            assert toy["null_rmse"] == pytest.approx(controls.loc[(condition, cv, "pls"), "null_rmse"], rel=1e-12)
            assert not toy["beats_null"] and not toy["passes"]
            assert toy["permutation_p"] == 1.0  # balanced: no shuffling changes the training mean's RMSE


def test_a_third_familys_predictions_are_its_training_fold_means(with_toy):
    analysis = with_toy
    predictions = analysis.predictions()
    for (condition, cv), rows in predictions[predictions["model"] == TOY].groupby(["condition", "cv"]):
        pls = predictions[predictions["model"].eq("pls") & predictions["condition"].eq(condition)
                          & predictions["cv"].eq(cv)]
        assert list(rows["image"]) == list(pls["image"])  # the same trials, in the same order
        target = rows["specimen"].map(analysis.perceived.set_index("specimen")["gmean"]).to_numpy(float)
        expected = [target[np.arange(len(target)) != i].mean() if cv == "loo" else
                    target[rows["specimen"].to_numpy() != s].mean()
                    for i, s in enumerate(rows["specimen"].to_numpy())]
        np.testing.assert_allclose(rows["prediction"], expected, rtol=1e-12)
    loso = analysis.held_out.query(f"model == '{TOY}'")
    assert list(loso["scheme"]) == ["specimen"] * 2  # stricter schemes: the toy has none; the study's LOSO is shown
    assert (loso["flagged_share"] == 0).all()
    assert TOY not in set(analysis.presses.get("model", pd.Series(dtype=str)))  # it reads no surface


def test_claims_stay_the_paper_familys_with_a_third_family_beside_it(with_toy):
    study, features = synthetic_study(repetitions=2, pads=("smooth",))
    alone = analyse_study(study, features=features, max_components=2, conditions=("1N", "combined"),
                          n_permutations=9, models=("pls",))
    pd.testing.assert_frame_equal(with_toy.claims, alone.claims)


def test_fold_settings_pass_the_same_keywords_as_the_dict_they_replace():
    from roughsense.analysis.family_fits import law_settings
    from roughsense.model.family import FoldSettings

    X = np.ones((4, 6))
    law = law_settings(X, np.linspace(0.1, 1.0, 3), 1.0, ["a", "a", "b", "b"])
    assert list(law) == ["freq_per_mm", "n_blocks", "pad_ridge_period_mm", "surfaces"] and law["n_blocks"] == 2
    again = FoldSettings.of(law).law()
    assert list(again) == list(law) and all(again[k] is law[k] for k in law)  # the very arrays, in the same order
    partial = FoldSettings.of({"freq_per_mm": law["freq_per_mm"]})
    assert (partial.n_blocks, partial.pad_ridge_period_mm, partial.surfaces) == (1, None, None)  # the kernels' defaults
    assert FoldSettings.of(None) is None and FoldSettings.of(partial) is partial


def test_the_fit_record_is_frozen(with_toy):
    import dataclasses

    pls = with_toy.condition_fit("smooth", "combined", "loso", "pls")
    assert pls.best_n_components == pls.best == int(np.argmin(pls.curve))
    assert pls.nested_n_components is pls.per_specimen and len(pls.per_specimen) == 14
    assert pls.held_out_flags is not None and pls.interval_check is None  # PLS: flags, no leave-two-out check
    law = with_toy.condition_fit("smooth", "combined", "loso", "peak-law")
    assert (law.best, law.one_se, law.per_specimen, law.curve.size) == (1, 1, {}, 2)
    assert law.interval_check is not None and len(law.interval_check) == 14
    with pytest.raises(dataclasses.FrozenInstanceError):
        pls.best = 3
